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
    """Where each state entry lives in qpos/qvel: free bodies, hinge/slide joints, then ball joints (those
    below the :data:`ROBOT_TEXT` body when the model names one)."""

    def __init__(self, m: mujoco.MjModel, inverse: dict[str, str]) -> None:
        self.body_names: list[str] = []
        self.bodies: list[tuple[int, int]] = []
        scalars: list[tuple[str, int, int]] = []
        balls: list[tuple[str, int, int]] = []
        kinds = mujoco.mjtJoint
        robot = robot_body(m)
        scenery = set(model_text(m, SCENERY_TEXT).split())
        for j in range(m.njnt):
            kind = int(m.jnt_type[j])
            qa, da = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
            if kind == kinds.mjJNT_FREE:
                name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j]))
                if name and name not in scenery:  # unnamed bodies and joints are scenery, not robot state
                    self.body_names.append(inverse.get(name, name))
                    self.bodies.append((qa, da))
                continue
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if name and (robot < 0 or _below(m, int(m.jnt_bodyid[j]), robot)):
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


def scale_contact_depths(m: mujoco.MjModel, d: mujoco.MjData, ratio: float) -> None:
    """Move the free bodies so that every overlapping contact is ``ratio`` times as deep as written.

    Why: a resting contact's depth is set by the engine's contact compliance under the load, not by the
    motion. ODE's ERP/CFM spring and MuJoCo's solref/solimp give different depths for the same weight (on
    the bundled CartPole MuJoCo rests about 1.9 times as deep as the Webots twin), so a state written at
    the other engine's depth is not at rest here: the contacts push the body out and it bounces within
    the period. Scaling the depths (``ratio``: this twin's resting depth over the other's, measured by
    lockstep at rest) carries the contact *load* across instead of the geometry. One linear least-squares
    step on the free joints' degrees of freedom (the contact normals' Jacobian) is exact for planar
    contacts; joints and velocities are not touched.
    """
    free = [int(m.jnt_dofadr[j]) + k for j in range(m.njnt)
            if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for k in range(6)]
    rows: list[np.ndarray] = []
    wanted: list[float] = []
    jacp = np.zeros((3, m.nv))
    for i in range(d.ncon):
        contact = d.contact[i]
        if contact.dist >= 0 or not free:
            continue
        normal = np.array(contact.frame[:3])  # from geom 1 to geom 2: moving geom 2 along it separates them
        row = np.zeros(m.nv)
        for geom, sign in ((contact.geom[0], -1.0), (contact.geom[1], 1.0)):
            mujoco.mj_jac(m, d, jacp, None, contact.pos, int(m.geom_bodyid[geom]))
            row += sign * (normal @ jacp)
        rows.append(row[free])
        wanted.append((ratio - 1.0) * float(contact.dist))
    if not rows:
        return
    delta = np.linalg.lstsq(np.array(rows), np.array(wanted), rcond=None)[0]
    step = np.zeros(m.nv)
    step[free] = delta
    mujoco.mj_integratePos(m, d.qpos, step, 1.0)
    mujoco.mj_forward(m, d)


#: The custom text naming the converted robot's root body, written when its world has other robots
#: (:mod:`dualtwin.convert.world_robots`): only the joints below that body are state, as the Webots twin's
#: state holds its robot's joints only (the other robots' joints, and their motors' holds, stay out of it).
ROBOT_TEXT = "webots_robot"


#: The custom text listing, space-separated, the free bodies of a converted world that are not state: the Webots
#: twin's state holds its robot and the world's top-level Solids with a DEF and a body only
#: (:class:`dualtwin.twins.webots_state.StateStructure`), so a loose Solid without a DEF, or one inside a top-level
#: Group or Pose, is scenery in both twins (written only when there is one: :mod:`dualtwin.convert.world_robots`).
SCENERY_TEXT = "webots_scenery"


def model_text(m: mujoco.MjModel, name: str) -> str:
    """The data of the model's custom text ``name`` ("" without one)."""
    index = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXT, name)
    if index < 0:
        return ""
    adr, size = int(m.text_adr[index]), int(m.text_size[index])
    return bytes(m.text_data[adr:adr + size]).rstrip(b"\0").decode()


def robot_body(m: mujoco.MjModel) -> int:
    """The id of the body the model's :data:`ROBOT_TEXT` names; -1 without one (every named joint is state)."""
    name = model_text(m, ROBOT_TEXT)
    return int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)) if name else -1


def in_converted_robot(m: mujoco.MjModel, body: int) -> bool:
    """Whether ``body`` belongs to the converted robot: below the :data:`ROBOT_TEXT` body, or any body when the model
    names none (a world without other robots)."""
    robot = robot_body(m)
    return robot < 0 or _below(m, body, robot)


def robot_actuator(m: mujoco.MjModel, actuator: int) -> bool:
    """Whether the joint actuator ``actuator`` drives a joint of the converted robot (:func:`in_converted_robot`):
    another robot's motors hold their initial position and are no device of the robot, in either twin."""
    return in_converted_robot(m, int(m.jnt_bodyid[m.actuator_trnid[actuator, 0]]))


def _below(m: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether ``body`` is ``root`` or in its subtree."""
    while body > 0 and body != root:
        body = int(m.body_parentid[body])
    return body == root


#: The keyframe a converted model starts from (Webots' initial velocities, dualtwin.convert.initial_state): the
#: twin resets to it when the model has one.
INITIAL_KEYFRAME = "webots_initial"
#: Per-sensor numerics a converted model carries (``webots_sensor.<sensor>`` = [resolution]).
SENSOR_NUMERIC = "webots_sensor."


def initial_keyframe(m: mujoco.MjModel) -> int:
    """The id of the model's :data:`INITIAL_KEYFRAME` (-1 without one)."""
    return int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, INITIAL_KEYFRAME))


def reset_data(m: mujoco.MjModel, d: mujoco.MjData, keyframe: int) -> None:
    """``mj_resetData``, or ``mj_resetDataKeyframe`` to ``keyframe`` when it is one (:func:`initial_keyframe`)."""
    if keyframe >= 0:
        mujoco.mj_resetDataKeyframe(m, d, keyframe)
    else:
        mujoco.mj_resetData(m, d)


def sensor_numerics(m: mujoco.MjModel, prefix: str) -> dict[int, list[float]]:
    """Sensor id -> the data of its ``<prefix><sensor name>`` numeric, for each named sensor that has one (the
    per-sensor Webots value models a converted model carries)."""
    out: dict[int, list[float]] = {}
    for s in range(m.nsensor):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, s)
        numeric = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, prefix + name) if name else -1
        if numeric >= 0:
            adr, size = int(m.numeric_adr[numeric]), int(m.numeric_size[numeric])
            out[s] = [float(v) for v in m.numeric_data[adr:adr + size]]
    return out


def sensor_resolutions(m: mujoco.MjModel) -> np.ndarray:
    """Each sensor's Webots ``resolution`` from its ``webots_sensor.<name>`` numeric (0 = none)."""
    out = np.zeros(m.nsensor)
    for s, data in sensor_numerics(m, SENSOR_NUMERIC).items():
        if data:
            out[s] = max(data[0], 0.0)
    return out
