"""A binding's channels read for every simulation of a ``mujoco.batch.Batch`` at once, as NumPy columns.

:class:`~dualtwin.twins.io.RobotIO` reads one twin, one channel at a time, through the twin's getters. After
a batched control period the same values sit in the batch's bound arrays (``qpos``, ``qvel``, ``xpos``,
``xmat``, ``sensordata``, computed at the new state when the batch steps with ``stage=mjSTAGE_VEL``), so a
column per channel is a slice and the channel's scale, in the getters' order of operations: the result is
bit-identical to RobotIO on each twin (tests/rl/test_vector_env.py).

Only what the twin's getters do without per-reading Python is covered: sensors read as they are (no noise,
bias, resolution or delay: :func:`plain_sensors` says whether an env's knobs add any) of types whose value
depends on joint positions and velocities only, joint positions and velocities, body positions and linear
velocities, and a body's up-axis tilt. :meth:`BatchChannels.reader` returns None for any other channel; the vector env then reads that
env through its twin.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from dualtwin.robots.binding import Channel, RobotBinding

AXES = {"x": 0, "y": 1, "z": 2}
#: Sensor types whose reading is the joint's qpos or qvel, so the batch's stage and the twin's refresh agree.
_JOINT_SENSORS = frozenset(int(t) for t in (mujoco.mjtSensor.mjSENS_JOINTPOS, mujoco.mjtSensor.mjSENS_JOINTVEL))
#: Knob names whose effect the twin applies per reading or per period in Python (sensor models, control delay).
_PER_READING_KNOBS = ("sensor.", "control.delay_periods")

Column = Callable[[], np.ndarray]


def plain_sensors(model: mujoco.MjModel, knob_values: dict[str, float]) -> bool:
    """True when the twin reads its sensors as MuJoCo computes them: no noise in the model, and no knob of
    this episode adds noise, bias, resolution or delay (or delays commands)."""
    if bool((model.sensor_noise > 0).any()):
        return False
    return not any(name.startswith(_PER_READING_KNOBS) for name in knob_values)


class BatchChannels:
    """Column readers over a batch's bound arrays for the channels of ``robot`` on a MuJoCo model."""

    def __init__(self, robot: RobotBinding, model: mujoco.MjModel, batch: Any) -> None:
        section = robot.spec.twins.get("mujoco")
        self._aliases = dict(section.aliases) if section else {}
        self.model = model
        self.batch = batch

    def _id(self, kind: mujoco.mjtObj, name: str) -> int:
        return int(mujoco.mj_name2id(self.model, kind, self._aliases.get(name, name)))

    def reader(self, channel: Channel) -> Column | None:
        """A function returning the channel's column (n,) after a batched step, or None if not covered."""
        scale, m, b = channel.scale, self.model, self.batch
        if channel.sensors:
            addresses = []
            for name in channel.sensors:
                s = self._id(mujoco.mjtObj.mjOBJ_SENSOR, name)
                if s < 0 or int(m.sensor_type[s]) not in _JOINT_SENSORS or m.sensor_dim[s] != 1:
                    return None
                addresses.append(int(m.sensor_adr[s]))
            data = b.bind("sensordata")
            if len(addresses) == 1:
                adr = addresses[0]
                # twin.sensor adds its bias (0.0 here) to the reading: x + 0.0, as it does
                return lambda: (data[:, adr] + 0.0) * scale
            count = len(addresses)

            def mean() -> np.ndarray:
                total = 0.0 + (data[:, addresses[0]] + 0.0)  # sum() starts from 0, left to right
                for adr in addresses[1:]:
                    total = total + (data[:, adr] + 0.0)
                return total / count * scale
            return mean
        if channel.joint is not None:
            j = self._id(mujoco.mjtObj.mjOBJ_JOINT, channel.joint)
            if j < 0:
                return None
            if channel.quantity == "position":
                qpos, adr = b.bind("qpos"), int(m.jnt_qposadr[j])
                return lambda: qpos[:, adr] * scale
            qvel, dof = b.bind("qvel"), int(m.jnt_dofadr[j])
            return lambda: qvel[:, dof] * scale
        body = self._id(mujoco.mjtObj.mjOBJ_BODY, channel.body or "")
        if body < 0 or channel.axis not in AXES:
            return None  # angles (yaw, pitch, roll): through the twin
        xpos, axis = b.bind("xpos"), AXES[channel.axis or "x"]
        if channel.quantity == "position":
            return lambda: xpos[:, body, axis] * scale
        return self._velocity(body, axis, scale)

    def _velocity(self, body: int, axis: int, scale: float) -> Column:
        """The body frame's world linear velocity along ``axis``: MuJoCo's own ``mj_objectVelocity`` per
        simulation (as ``MuJoCoTwin.body_velocity``) on the batch's com-frame velocities, a few µs each."""
        m, b = self.model, self.batch
        cvel, com, xpos = b.bind("cvel"), b.bind("subtree_com"), b.bind("xpos")
        root = int(m.body_rootid[body])
        scratch, out = mujoco.MjData(m), np.zeros(6)

        def velocity() -> np.ndarray:
            column = np.empty(len(cvel))
            for i in range(len(cvel)):
                scratch.cvel[body], scratch.subtree_com[root], scratch.xpos[body] = cvel[i, body], com[i, root], xpos[i, body]
                mujoco.mj_objectVelocity(m, scratch, mujoco.mjtObj.mjOBJ_XBODY, body, out, 0)
                column[i] = out[3 + axis]
            return column * scale
        return velocity

    def tilt(self, body_name: str) -> Column | None:
        """Angle between the body's up axis and the world's, per simulation (math.acos, as the task computes it)."""
        body = self._id(mujoco.mjtObj.mjOBJ_BODY, body_name)
        if body < 0:
            return None
        xmat = self.batch.bind("xmat")

        def tilt() -> np.ndarray:
            acos = math.acos  # per value: NumPy's arccos need not round as libm's does
            return np.array([acos(max(-1.0, min(1.0, up))) for up in xmat[:, body, 8].tolist()])
        return tilt


__all__ = ["BatchChannels", "Column", "plain_sensors"]
