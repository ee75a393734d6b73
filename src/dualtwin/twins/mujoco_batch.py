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
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import mujoco.batch
import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins.mujoco import MuJoCoTwin

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION.value
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
        # The last substep's sensor readings, as mj_step leaves them in the twin's data (see the module docstring).
        self._sensordata = self.batch.bind("sensordata") if model.nsensor else None

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
            substeps = int(round(twin.control_period / twin.model.opt.timestep))
            by_substeps.setdefault(substeps, []).append(i)
        # Knobs and resets edit the twins' models in place: the batch reads them again.
        self.batch.set_models([twin.model for twin in self.twins])
        warnings = self.batch.warning
        before = warnings[:, _BAD_STATE, 1].sum(axis=1)
        for substeps, group in by_substeps.items():
            self.batch.step(None if len(group) == self.nsim else np.asarray(group, dtype=np.int32), nstep=substeps)
        bad = warnings[:, _BAD_STATE, 1].sum(axis=1) != before
        out: list[SimulationUnstable | None] = []
        for i in ids:
            twin = self.twins[i]
            mujoco.mj_setState(twin.model, twin.data, self._rows[i], _INTEGRATION)
            if self._sensordata is not None:
                twin.data.sensordata[:] = self._sensordata[i]
            try:
                twin.finish_period(bool(bad[i]))
            except SimulationUnstable as exc:
                out.append(exc)
            else:
                out.append(None)
        return out


__all__ = ["TwinBatch", "batch_reason"]
