"""The MuJoCo twin's state layout: where each state entry lives in ``qpos``/``qvel``, and the state read from them.

Conventions are those of :mod:`dualtwin.twins.base`: free bodies by name (frame pose, world velocities),
hinge/slide joints, then ball joints as rotation vectors. Writing a state stays in
:meth:`MuJoCoTwin.set_state <dualtwin.twins.mujoco.MuJoCoTwin.set_state>`, next to the contact checks it needs.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from dualtwin.twins.base import BALL_COMPONENTS, StateLayout


class StatePlan:
    """Where each state entry lives in qpos/qvel: free bodies, hinge/slide joints, then ball joints."""

    def __init__(self, m: mujoco.MjModel, inverse: dict[str, str]) -> None:
        self.body_names: list[str] = []
        self.bodies: list[tuple[int, int]] = []
        scalars: list[tuple[str, int, int]] = []
        balls: list[tuple[str, int, int]] = []
        kinds = mujoco.mjtJoint
        for j in range(m.njnt):
            kind = int(m.jnt_type[j])
            qa, da = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
            if kind == kinds.mjJNT_FREE:
                name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j]))
                if name:  # unnamed bodies and joints are scenery, not robot state
                    self.body_names.append(inverse.get(name, name))
                    self.bodies.append((qa, da))
                continue
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if name:
                (balls if kind == kinds.mjJNT_BALL else scalars).append((inverse.get(name, name), qa, da))
        self.scalar = len(scalars)
        self.joint_names = [n for n, _, _ in scalars] + [f"{n}/{c}" for n, _, _ in balls for c in BALL_COMPONENTS]
        self.scalar_qpos = [qa for _, qa, _ in scalars]
        self.scalar_dof = [da for _, _, da in scalars]
        self.ball_qpos = [qa for _, qa, _ in balls]
        self.ball_dof = [da for _, _, da in balls]
        self.by_qpos = {qa: n for n, qa, _ in scalars}
        self._layouts: dict[tuple[str, ...], StateLayout] = {}

    def layout(self, holds: tuple[str, ...]) -> StateLayout:
        layout = self._layouts.get(holds)
        if layout is None:
            layout = self._layouts[holds] = StateLayout(self.body_names, self.joint_names, holds)
        return layout

    def read(self, qpos: list[float], qvel: list[float], held: list[tuple[str, float]]) -> list[float]:
        """The state vector (see :meth:`layout`) from ``qpos``/``qvel`` as plain floats (a few dozen numbers,
        read every control period in lockstep) and the held motors' (joint, target)."""
        out: list[float] = []
        for qa, da in self.bodies:
            w, x, y, z = qpos[qa + 3:qa + 7]
            norm = (-1.0 if w < 0 else 1.0) / math.sqrt(w * w + x * x + y * y + z * z)
            w, x, y, z = w * norm, x * norm, y * norm, z * norm
            a, b, c = qvel[da + 3:da + 6]
            # v + 2w(q×v) + 2q×(q×v): the body-frame angular velocity in world coordinates.
            tx, ty, tz = 2 * (y * c - z * b), 2 * (z * a - x * c), 2 * (x * b - y * a)
            out += [*qpos[qa:qa + 3], w, x, y, z, *qvel[da:da + 3],
                    a + w * tx + y * tz - z * ty, b + w * ty + z * tx - x * tz, c + w * tz + x * ty - y * tx]
        positions = [qpos[qa] for qa in self.scalar_qpos]
        velocities = [qvel[da] for da in self.scalar_dof]
        for qa, da in zip(self.ball_qpos, self.ball_dof, strict=True):
            rotvec = np.zeros(3)
            quat = np.array(qpos[qa:qa + 4])
            mujoco.mju_quat2Vel(rotvec, quat / np.linalg.norm(quat), 1.0)
            positions += rotvec.tolist()
            velocities += qvel[da:da + 3]
        out += positions
        out += velocities
        out += [target for _, target in held]
        return out
