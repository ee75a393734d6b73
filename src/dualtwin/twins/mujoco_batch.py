"""Many MuJoCo twins' physics, one control period at a time, as one ``mujoco.batch.Batch`` call on C threads.

Once Webots' motor law runs inside ``mj_step`` (the native plugin, :mod:`dualtwin.twins.motor_plugin`), a
twin's control period is nothing but ``mj_step`` repeated from its integration state: commands live in
``plugin_state``, and what the twin does in Python (delayed commands, sensor history, the stability check)
happens before and after the period (``start_period`` / ``finish_period``). So a `TwinBatch` copies each twin's
integration state into its batch row, steps every row's substeps on the batch's threads (each simulation on its
twin's own model, ``Batch.set_models``, so per-twin knobs apply), and copies the rows back. Everything else
stays with the twins: each keeps its own RNG, history and Python state, and callers interleave their own
Python (commands, sampling) between periods exactly as they would around ``twin.step()``.

Bit-identical to ``twin.step()`` (``mujoco.batch`` is bit-identical to a loop of ``mj_step`` at any thread
count; tests/align/test_batched.py): after the copy back, the twin recomputes poses and position/velocity
sensors from the state (``refresh``) as after its own step, and sensor readings of the acceleration stage
(and anything a pos/vel sensor would read from an older stage) come from the batch's last substep, as
``mj_step`` leaves them. Hence :func:`batch_reason` refuses sensors whose value ``refresh`` cannot recompute
from kinematics alone (actuator or tendon lengths, for instance), and twins that need Python between physics
steps (the Python motor law, Webots' friction pyramid).

The batch also computes the position and velocity stages at the new state on its threads
(``stage=mjSTAGE_VEL``: what ``refresh`` computes, and acceleration-stage sensors keep the last substep's
values), so a binding's channels can be read for every simulation at once from the batch's arrays
(`ChannelColumns`) instead of one twin and one getter at a time: the same values, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import mujoco.batch
import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.robots.binding import Channel
from dualtwin.twins.io import AXES
from dualtwin.twins.mujoco import MuJoCoTwin

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION.value
_POSES = mujoco.mjtStage.mjSTAGE_VEL.value
_BAD_STATE = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                               mujoco.mjtWarning.mjWARN_BADQACC)]
_S = mujoco.mjtSensor
#: Position- and velocity-stage sensors that ``refresh`` (kinematics, com positions and velocities) recomputes
#: exactly; acceleration-stage sensors are copied from the batch whatever their type.
_REFRESHED = frozenset(int(t) for t in (
    _S.mjSENS_JOINTPOS, _S.mjSENS_JOINTVEL, _S.mjSENS_BALLQUAT, _S.mjSENS_BALLANGVEL, _S.mjSENS_FRAMEPOS,
    _S.mjSENS_FRAMEQUAT, _S.mjSENS_FRAMEXAXIS, _S.mjSENS_FRAMEYAXIS, _S.mjSENS_FRAMEZAXIS, _S.mjSENS_FRAMELINVEL,
    _S.mjSENS_FRAMEANGVEL, _S.mjSENS_GYRO, _S.mjSENS_VELOCIMETER, _S.mjSENS_MAGNETOMETER, _S.mjSENS_SUBTREECOM,
    _S.mjSENS_SUBTREELINVEL, _S.mjSENS_SUBTREEANGMOM, _S.mjSENS_CLOCK))


def batch_reason(twin: Any) -> str | None:
    """Why ``twin``'s physics cannot run in a `TwinBatch` (one line), or None when it can."""
    if not isinstance(twin, MuJoCoTwin):
        return f"the {getattr(twin, 'name', type(twin).__name__)} twin is not a MuJoCo twin"
    if not twin.native_law:
        return ("the Python motor law acts between physics steps, which a batch cannot call back (the native "
                "law is not built: see dualtwin.twins.motor_plugin)")
    if twin.contact_semantics is not None:
        return "Webots' friction pyramid (contact_semantics) acts between physics steps"
    model = twin.model
    for s in range(model.nsensor):
        if model.sensor_needstage[s] != mujoco.mjtStage.mjSTAGE_ACC and int(model.sensor_type[s]) not in _REFRESHED:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, s) or f"sensor {s}"
            return f"sensor {name!r} reads more than the kinematics the twin recomputes after a batched period"
    return None


class TwinBatch:
    """The physics of ``twins`` (MuJoCo twins of one model structure) stepped on ``nthread`` threads (0: all CPUs).

    ``step(ids)`` stands for ``twins[i].step()`` for each ``i`` in ``ids``; the twins' models may change between
    calls (knobs, resets): each call runs every simulation on its twin's current model.
    """

    def __init__(self, twins: Sequence[MuJoCoTwin], nthread: int) -> None:
        if not twins:
            raise DualtwinError("a twin batch needs at least one twin")
        for twin in twins:
            reason = batch_reason(twin)
            if reason:
                raise DualtwinError(f"cannot batch this twin: {reason}")
        self.twins = list(twins)
        self.nsim = len(self.twins)
        model = self.twins[0].model
        self.batch = mujoco.batch.Batch(model, self.nsim, nthread=nthread)
        self._rows = [self.batch.state[i] for i in range(self.nsim)]
        self._options = [twin.model.opt for twin in self.twins]  # live views (each model.opt is a lookup)
        # Sensor readings at the new state (position and velocity stages) and the last substep's (acceleration
        # stage), as the twin's data holds them after mj_step and refresh (see the module docstring).
        self._sensordata = self.batch.bind("sensordata") if model.nsensor else None
        # Only acceleration-stage readings need the copy: refresh recomputes the others in the twin.
        self._copy_sensors = bool((model.sensor_needstage == mujoco.mjtStage.mjSTAGE_ACC).any())

    @property
    def nthread(self) -> int:
        return int(self.batch.nthread)

    def step(self, ids: Sequence[int]) -> list[SimulationUnstable | None]:
        """One control period of each twin ``ids`` names (ascending), as ``twin.step()``; per id, the
        `SimulationUnstable` its step raised, or None."""
        by_substeps: dict[int, list[int]] = {}
        for i in ids:
            twin = self.twins[i]
            twin.start_period()
            mujoco.mj_getState(twin.model, twin.data, self._rows[i], _INTEGRATION)
            # A physics.substeps knob changes the step, so the substeps of a period, per twin.
            substeps = int(round(twin.control_period / self._options[i].timestep))
            by_substeps.setdefault(substeps, []).append(i)
        # Knobs and resets edit the twins' models in place: the batch reads them again.
        self.batch.set_models([twin.model for twin in self.twins])
        warnings = self.batch.warning
        before = warnings[:, _BAD_STATE, 1].sum(axis=1)
        for substeps, group in by_substeps.items():
            self.batch.step(None if len(group) == self.nsim else np.asarray(group, dtype=np.int32), nstep=substeps,
                            stage=_POSES)
        bad: list[bool] = (warnings[:, _BAD_STATE, 1].sum(axis=1) != before).tolist()
        out: list[SimulationUnstable | None] = []
        sensordata = self._sensordata if self._copy_sensors else None
        for i in ids:
            twin = self.twins[i]
            mujoco.mj_setState(twin.model, twin.data, self._rows[i], _INTEGRATION)
            if sensordata is not None:
                twin.data.sensordata[:] = sensordata[i]
            try:
                twin.finish_period(bad[i])
            except SimulationUnstable as exc:
                out.append(exc)
            else:
                out.append(None)
        return out


Column = Callable[[np.ndarray], np.ndarray]


class ChannelColumns:
    """A binding's channels read for many simulations of a `TwinBatch` at once, after its last step.

    ``read(ids)`` gives one row per simulation in ``ids``, one column per channel, with the value the twin's
    getter (`dualtwin.twins.io.RobotIO`) returns for that simulation, bit for bit: the same arrays (the batch
    computes poses and sensors at the new state, see the module docstring), and each getter's arithmetic in
    its order, on columns. Valid for a twin that reads sensors as they are (``MuJoCoTwin.plain_sensor_reads``:
    no noise, bias, resolution or delay, which apply per reading in Python).

    :meth:`build` returns None for a binding with a channel it cannot read so (an unknown name).
    """

    def __init__(self, batch: TwinBatch, aliases: dict[str, str], channels: list[Channel]) -> None:
        self._batch = batch.batch
        self._model = batch.twins[0].model
        self._aliases = aliases
        self.width = len(channels)
        # Per kind of getter, the output columns and where each reads: one fancy index per kind and period.
        self._plain: dict[str, tuple[list[int], list[int], list[float]]] = {}
        self._bodies: tuple[list[int], list[int], list[int], list[float]] = ([], [], [], [])
        self._each: list[tuple[int, Column]] = []  # channels read by a function of their own
        for column, channel in enumerate(channels):
            self._add(column, channel)
        self._gathers = [(self._batch.bind(kind), np.asarray(columns), np.asarray(addresses), np.asarray(scales),
                          kind == "sensordata") for kind, (columns, addresses, scales) in self._plain.items()]
        self._xpos = self._batch.bind("xpos") if self._bodies[0] else None
        self._body_scales = np.asarray(self._bodies[3])

    @classmethod
    def build(cls, batch: TwinBatch, aliases: dict[str, str], channels: list[Channel]) -> ChannelColumns | None:
        try:
            return cls(batch, aliases, channels)
        except KeyError:
            return None

    def _id(self, kind: mujoco.mjtObj, name: str) -> int:
        index = int(mujoco.mj_name2id(self._model, kind, self._aliases.get(name, name)))
        if index < 0:
            raise KeyError(name)
        return index

    def _put(self, kind: str, column: int, address: int, scale: float) -> None:
        columns, addresses, scales = self._plain.setdefault(kind, ([], [], []))
        columns.append(column)
        addresses.append(address)
        scales.append(scale)

    def _add(self, column: int, channel: Channel) -> None:
        m, scale = self._model, channel.scale
        if channel.sensors:
            adrs = [int(m.sensor_adr[self._id(mujoco.mjtObj.mjOBJ_SENSOR, n)]) for n in channel.sensors]
            if len(adrs) == 1:  # twin.sensor(name) * scale, the reading + 0.0 (a zero bias)
                self._put("sensordata", column, adrs[0], scale)
            else:
                self._each.append((column, self._sensor_mean(adrs, scale)))
        elif channel.joint is not None:
            j = self._id(mujoco.mjtObj.mjOBJ_JOINT, channel.joint)
            if channel.quantity == "position":
                self._put("qpos", column, int(m.jnt_qposadr[j]), scale)
            else:
                self._put("qvel", column, int(m.jnt_dofadr[j]), scale)
        else:
            body = self._id(mujoco.mjtObj.mjOBJ_BODY, channel.body or "")
            if channel.axis in ("yaw", "pitch", "roll"):
                self._each.append((column, self._angle(body, channel.axis, scale)))
            elif channel.quantity == "position":
                columns, bodies, axes, scales = self._bodies
                columns.append(column)
                bodies.append(body)
                axes.append(AXES[channel.axis or "x"])
                scales.append(scale)
            else:
                self._each.append((column, self._velocity(body, AXES[channel.axis or "x"], scale)))

    def _sensor_mean(self, adrs: list[int], scale: float) -> Column:
        data = self._batch.bind("sensordata")
        count = len(adrs)

        def mean(ids: np.ndarray) -> np.ndarray:
            rows = data[ids]
            total = 0.0 + (rows[:, adrs[0]] + 0.0)  # sum() from 0, left to right, of readings + 0.0
            for adr in adrs[1:]:
                total = total + (rows[:, adr] + 0.0)
            return total / count * scale
        return mean

    def _angle(self, body: int, axis: str, scale: float) -> Column:
        """`dualtwin.geometry.rpy_from_matrix` of the body's rotation, per value (libm's atan2 and hypot)."""
        xmat = self._batch.bind("xmat")
        # Row-major 3x3: R[i, j] is entry 3 i + j.
        atan2, hypot = math.atan2, math.hypot

        def angle(ids: np.ndarray) -> np.ndarray:
            rows = xmat[ids, body].tolist()
            if axis == "yaw":
                values = [atan2(r[3], r[0]) for r in rows]
            elif axis == "pitch":
                values = [atan2(-r[6], hypot(r[7], r[8])) for r in rows]
            else:
                values = [atan2(r[7], r[8]) for r in rows]
            return np.array(values) * scale
        return angle

    def _velocity(self, body: int, axis: int, scale: float) -> Column:
        """``MuJoCoTwin.body_velocity``'s linear part: ``mj_objectVelocity`` per simulation on its fields."""
        m, b = self._model, self._batch
        cvel, com, xpos, xmat = b.bind("cvel"), b.bind("subtree_com"), b.bind("xpos"), b.bind("xmat")
        root = int(m.body_rootid[body])
        scratch, out = mujoco.MjData(m), np.zeros(6)

        def velocity(ids: np.ndarray) -> np.ndarray:
            column = np.empty(len(ids))
            for k, i in enumerate(ids.tolist()):
                scratch.cvel[body], scratch.subtree_com[root] = cvel[i, body], com[i, root]
                scratch.xpos[body], scratch.xmat[body] = xpos[i, body], xmat[i, body]
                mujoco.mj_objectVelocity(m, scratch, mujoco.mjtObj.mjOBJ_XBODY, body, out, 0)
                column[k] = out[3 + axis]
            return column * scale
        return velocity

    def read(self, ids: np.ndarray) -> np.ndarray:
        """The channels of simulations ``ids`` (int array): shape (len(ids), channels)."""
        out = np.empty((len(ids), self.width))
        for array, targets, addresses, scales, sensors in self._gathers:
            values = array[ids][:, addresses]
            if sensors:
                values = values + 0.0  # twin.sensor adds its bias, 0.0: -0.0 reads 0.0
            out[:, targets] = values * scales
        if self._xpos is not None:
            columns, bodies, axes, _ = self._bodies
            out[:, columns] = self._xpos[ids][:, bodies, axes] * self._body_scales
        for column, read in self._each:
            out[:, column] = read(ids)
        return out


__all__ = ["ChannelColumns", "TwinBatch", "batch_reason"]
