"""The Webots twin's state transfer: reading and writing a robot's mechanical state through the supervisor API.

:class:`StateStructure` resolves once which nodes hold the state (root Solids, hinge/slider joints, Hinge2 and
ball joints, the motors that hold joints) and then reads the state every control period in plain floats
(:meth:`StateStructure.read`) and writes a state as supervisor edits (:meth:`StateStructure.write`): field
teleports, held-motor targets, then every body's velocity from the written state's forward kinematics. The
conventions are those of :mod:`dualtwin.twins.base`; :class:`~dualtwin.twins.webots.WebotsTwin` owns the
timing (when to write, the settling basic steps, what ``get_state`` answers right after a write).

Kept apart from the twin's name resolution, commands and knobs because it is the one part that reasons about
kinematics: a reader looking for how a state becomes Webots fields finds it all here.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.geometry import (
    axis_angle_from_matrix,
    matrix_from_quat,
    quat_tuple,
    rotation_about,
    rotation_vector,
)
from dualtwin.twins.base import BALL_COMPONENTS, MechanicalState, StateLayout, SyncError

JOINT_TYPES = ("HingeJoint", "SliderJoint", "Hinge2Joint", "BallJoint")


def base_field(node: Any, name: str) -> Any:
    """A field of what ``node`` is in the simulation: for a PROTO instance its base node's field.

    Webots' ``getField`` on a PROTO instance sees only the PROTO's interface (a Pioneer3at has ``extensionSlot``,
    not ``children``); the twin walks the scene it simulates, so it reads the base node (``getProtoField``).
    """
    return node.getProtoField(name) if node.isProto() else node.getField(name)
MOTOR_TYPES = ("RotationalMotor", "LinearMotor")
#: set_state refuses a state to which a free body responds, within one basic step, with a velocity jump
#: above these (m/s, rad/s): ODE pushing a penetrating body out (softERP 0.2 moves 2 cm of overlap at
#: 0.5 m/s with an 8 ms step) or a violated joint. Driving and gravity stay far below them.
MAX_JUMP_LINEAR = 0.5
MAX_JUMP_ANGULAR = 10.0


def cross(a: Any, b: Any) -> np.ndarray:
    """Cross product of two 3-vectors (``np.cross`` costs tens of microseconds on tiny inputs)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def pose_of(node: Any) -> tuple[np.ndarray, np.ndarray]:
    """(rotation matrix, position) of a node in the world now."""
    return (np.array(node.getOrientation(), dtype=float).reshape(3, 3),
            np.array(node.getPosition(), dtype=float))


class JointAxis:
    """A joint parameters' ``axis`` as the joint uses it now, a unit vector in the closest upper Pose's frame.

    Read from the field on every use: a supervisor may edit it at run time, and Webots turns the joint about the
    new axis from the next step (reference webots-on-ode.md §4.1, §4.2-4.4; our runtime:
    ``webots/physics/axis_edits.py``). Reading a field is a dictionary look-up here and the state is read every
    control period, so the normalisation is redone only when the value read differs from the last. A zero axis is
    refused by Webots (a warning; the joint keeps its axis), so this keeps the last non-zero one.
    """

    __slots__ = ("_field", "_given", "unit")

    def __init__(self, params: Any) -> None:
        self._field = base_field(params, "axis")
        self._given: list[float] | None = None
        self.unit: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def now(self) -> tuple[float, float, float]:
        given = self._field.getSFVec3f()
        if given != self._given:
            self._given = given
            norm = math.sqrt(given[0] * given[0] + given[1] * given[1] + given[2] * given[2])
            if norm > 1e-12 and math.isfinite(norm):
                self.unit = (given[0] / norm, given[1] / norm, given[2] / norm)
        return self.unit


class Joint:
    """A joint node with the handles ground truth needs."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.kind = node.getTypeName()
        self.params = base_field(node, "jointParameters").getSFNode()
        if self.params is None:
            raise DualtwinError(f"joint {node.getDef()!r} has no jointParameters; give it one to use it by name")
        self.position = base_field(self.params, "position")
        self.joint_axis = JointAxis(self.params)
        self.child = base_field(node, "endPoint").getSFNode()
        self.parent = node.getParentNode()

    @property
    def axis(self) -> np.ndarray:
        """The unit axis now, in the closest upper Pose's frame (see :class:`JointAxis`)."""
        return np.array(self.joint_axis.now(), dtype=float)


class Hinge2:
    """A Hinge2Joint: two state joints, ``<DEF>`` (axis 1, fixed in the parent) and ``<DEF>2`` (axis 2,
    turning with axis 1), as the Webots-to-MJCF converter names its two hinges."""

    def __init__(self, node: Any, second: str) -> None:
        self.node = node
        self.second = second
        params = [base_field(node, f).getSFNode() for f in ("jointParameters", "jointParameters2")]
        if params[0] is None or params[1] is None:
            raise DualtwinError(f"Hinge2Joint {node.getDef()!r} needs jointParameters and jointParameters2 "
                                "for its state to be read and written")
        self.params, self.params2 = params
        self.position, self.position2 = (base_field(p, "position") for p in params)
        self.joint_axes = (JointAxis(self.params), JointAxis(self.params2))
        self.child = base_field(node, "endPoint").getSFNode()
        self.parent = node.getParentNode()

    def world_axes(self, q1: float) -> tuple[np.ndarray, np.ndarray]:
        """World axes now: axis 2 is given for axis 1 at zero and turns with it (as ODE's hinge-2 axis 2)."""
        rotation = np.array(self.parent.getOrientation(), dtype=float).reshape(3, 3)
        axis, axis2 = (np.array(a.now(), dtype=float) for a in self.joint_axes)
        return rotation @ axis, rotation @ (rotation_about(axis, q1) @ axis2)


class StateStructure:
    """The robot's roots, joints and held-motor map for state transfer, resolved once through the API."""

    def __init__(self, sup: Any, nodes: Iterable[Any], aliases: dict[str, str], origin: str,
                 commanded: set[str]) -> None:
        """``nodes``: the robot's subtree (``WebotsTwin._walk``); ``commanded``: the twin's set of motors
        commanded since reset (shared, not copied: held motors are the others)."""
        self.origin = origin
        self.commanded = commanded
        inverse = {v: k for k, v in aliases.items()}
        self.bodies: dict[str, Any] = {}
        me = sup.getSelf()
        candidates = [me]
        root = base_field(sup.getRoot(), "children")
        for i in range(root.getCount()):
            node = root.getMFNode(i)
            if node is not None and node != me and node.getDef() and self._has_body(node):
                candidates.append(node)
        for node in candidates:
            if self._has_body(node):
                name = node.getDef() or base_field(node, "name").getSFString()
                self.bodies[inverse.get(name, name)] = node
        self.joints: dict[str, Joint] = {}
        self.hinge2: dict[str, Hinge2] = {}
        self.balls: dict[str, Any] = {}  # name -> (joint node, endPoint)
        self.motors: dict[str, list[Any]] = {}  # state joint name -> its motor devices

        def motors(node: Any, field: str) -> list[Any]:
            devices = base_field(node, field)
            names = [base_field(devices.getMFNode(i), "name").getSFString() for i in range(devices.getCount())
                     if devices.getMFNode(i) is not None and devices.getMFNode(i).getTypeName() in MOTOR_TYPES]
            return [d for d in (sup.getDevice(n) for n in names) if d is not None]

        for node in nodes:
            kind = node.getTypeName()
            if kind not in JOINT_TYPES or not node.getDef():
                continue
            end = base_field(node, "endPoint")
            if end is None or end.getSFNode() is None:
                continue
            name = inverse.get(node.getDef(), node.getDef())
            if kind == "BallJoint":
                self.balls[name] = (node, end.getSFNode())
            elif kind == "Hinge2Joint":
                second = inverse.get(node.getDef() + "2", node.getDef() + "2")
                self.hinge2[name] = Hinge2(node, second)
                self.motors[name], self.motors[second] = motors(node, "device"), motors(node, "device2")
            elif base_field(node, "jointParameters").getSFNode() is not None:
                self.joints[name] = Joint(node)
                self.motors[name] = motors(node, "device")
        self.names = [*self.joints, *(n for name, h in self.hinge2.items() for n in (name, h.second)),
                      *(f"{b}/{c}" for b in self.balls for c in BALL_COMPONENTS)]
        # Read every control period in lockstep: node ids and motor names resolved once.
        self.roots = [(node.getId(), node) for node in self.bodies.values()]
        self.hold_motors = [(name, [(m, m.getName()) for m in motors]) for name, motors in self.motors.items()]
        self._layouts: dict[tuple[str, ...], StateLayout] = {}
        self._parents: dict[int, Any] = {}
        self._joint_of: dict[int, Joint] = {j.child.getId(): j for j in self.joints.values()}
        self._hinge2_of: dict[int, tuple[str, Hinge2]] = {h.child.getId(): (n, h) for n, h in self.hinge2.items()}
        self._ball_of: dict[int, str] = {end.getId(): n for n, (_, end) in self.balls.items()}
        self._slider = any(j.kind == "SliderJoint" for j in self.joints.values())
        self._plan: tuple[list[tuple[int, Any]], list[tuple[int, Any]],
                          list[tuple[int, int, int, JointAxis, bool]]] | None = None
        for name in self.joints:
            self.parent_solid(self.joints[name].node)

    def layout(self, holds: tuple[str, ...]) -> StateLayout:
        layout = self._layouts.get(holds)
        if layout is None:
            layout = self._layouts[holds] = StateLayout(self.bodies, self.names, holds)
        return layout

    def read(self) -> tuple[StateLayout, list[float]]:
        """Root poses and velocities from ``Node.getPose/getVelocity`` (the CoM velocity moved to the frame
        origin), joint positions from their ``position`` fields, joint rates from the relative angular (or,
        for sliders, linear) velocity of the endPoint and the parent Solid along the joint axes, and ball
        joints from the endPoint's rotation relative to the parent Solid."""
        st = self
        out: list[float] = []
        rotations: dict[int, Sequence[float]] = {}
        velocities: dict[int, Sequence[float]] = {}
        for key, node in st.roots:
            pose = node.getPose()
            px, py, pz = pose[3], pose[7], pose[11]
            rotations[key] = r = (pose[0], pose[1], pose[2], pose[4], pose[5], pose[6], pose[8], pose[9], pose[10])
            velocities[key] = v = node.getVelocity()
            com = node.getCenterOfMass()
            # Velocity of the frame origin: v_com + w x (origin - com).
            dx, dy, dz = px - com[0], py - com[1], pz - com[2]
            out += [px, py, pz, *quat_tuple(r), v[0] + v[4] * dz - v[5] * dy, v[1] + v[5] * dx - v[3] * dz,
                    v[2] + v[3] * dy - v[4] * dx, v[3], v[4], v[5]]
        positions, rates = st.joint_states(rotations, velocities)
        out += positions
        out += rates
        holds: list[str] = []
        commanded = self.commanded
        for name, motors in st.hold_motors:
            for motor, motor_name in motors:
                if motor_name not in commanded:
                    target = motor.getTargetPosition()
                    if math.isfinite(target):
                        holds.append(name)
                        out.append(float(target))
                        break
        return st.layout(tuple(holds)), out

    def check_jump(self, state: MechanicalState, dt: float) -> None:
        """Raise :class:`SyncError` when a written free body was thrown within the basic step ``dt`` just run."""
        st = self
        for name, body in state.bodies.items():
            node = st.bodies[name]
            velocity = np.array(node.getVelocity(), dtype=float)
            com = np.array(node.getCenterOfMass(), dtype=float)
            linear = velocity[:3] + cross(velocity[3:], np.array(node.getPosition(), dtype=float) - com)
            jump_v = float(np.linalg.norm(linear - body.linear_velocity))
            jump_w = float(np.linalg.norm(velocity[3:] - body.angular_velocity))
            if jump_v > MAX_JUMP_LINEAR or jump_w > MAX_JUMP_ANGULAR:
                raise SyncError(f"{self.origin}: body {name!r} was thrown by the state written (velocity jump "
                                f"{jump_v:.3g} m/s, {jump_w:.3g} rad/s in {dt * 1000:g} ms): penetration or a "
                                "violated joint; reset the twin", "jump")

    def joint_states(self, known: dict[int, Sequence[float]] | None = None,
                     known_velocities: dict[int, Sequence[float]] | None = None) -> tuple[list[float], list[float]]:
        """Positions and rates of every state joint, in :attr:`names` order (``known``, ``known_velocities``:
        see :meth:`_rates`)."""
        velocities = self._rates(known or {}, known_velocities or {})
        positions = [float(j.position.getSFFloat()) for j in self.joints.values()]
        for h in self.hinge2.values():
            q1, q2 = float(h.position.getSFFloat()), float(h.position2.getSFFloat())
            a1, a2 = h.world_axes(q1)
            # The relative angular velocity is q1' a1 + q2' a2: solve the 2x2 normal equations.
            rel = self._angular(h.child) - self._angular(self.parent_solid(h.node))
            g11, g12, g22 = float(a1 @ a1), float(a1 @ a2), float(a2 @ a2)
            b1, b2 = float(a1 @ rel), float(a2 @ rel)
            det = g11 * g22 - g12 * g12
            positions += [q1, q2]
            velocities += [(g22 * b1 - g12 * b2) / det, (g11 * b2 - g12 * b1) / det]
        for joint, end in self.balls.values():
            rotation, relative = self._relative_rotation(joint, end)
            positions += rotation_vector(relative).tolist()
            w_child = self._angular(end)
            w_rel = w_child - self._angular(self.parent_solid(joint))
            velocities += (np.array(end.getOrientation(), dtype=float).reshape(3, 3).T @ w_rel).tolist()
        return positions, velocities

    def _relative_rotation(self, joint: Any, end: Any) -> tuple[np.ndarray, np.ndarray]:
        """(parent Solid's world rotation, the endPoint's rotation relative to it)."""
        parent = self.parent_solid(joint)
        rp = np.array(parent.getOrientation(), dtype=float).reshape(3, 3) if parent is not None else np.eye(3)
        return rp, rp.T @ np.array(end.getOrientation(), dtype=float).reshape(3, 3)

    @staticmethod
    def _angular(node: Any) -> np.ndarray:
        return np.array(node.getVelocity()[3:], dtype=float) if node is not None else np.zeros(3)

    @staticmethod
    def _has_body(node: Any) -> bool:
        physics = base_field(node, "physics")
        return physics is not None and physics.getSFNode() is not None

    @staticmethod
    def _is_solid(node: Any) -> bool:
        return base_field(node, "physics") is not None

    def parent_solid(self, node: Any) -> Any:
        """The closest Solid above ``node`` (None for a top-level node)."""
        key = node.getId()
        if key not in self._parents:
            parent = node.getParentNode()
            while parent is not None and not self._is_solid(parent):
                parent = parent.getParentNode()
            self._parents[key] = parent
        return self._parents[key]

    def _frame(self, joint: Joint) -> tuple[np.ndarray, np.ndarray]:
        """World axis and anchor of a joint now (axis and anchor live in the closest upper Pose, spec §4.1)."""
        rotation, _ = pose_of(joint.parent)
        return rotation @ joint.axis, self._anchor(joint.parent, joint.params)

    @staticmethod
    def _anchor(frame: Any, params: Any) -> np.ndarray:
        """World anchor of a joint now, from its parameters' ``anchor`` in the closest upper Pose ``frame``."""
        rotation, position = pose_of(frame)
        field = base_field(params, "anchor") if params is not None else None
        anchor = np.array(field.getSFVec3f() if field is not None else [0.0, 0.0, 0.0], dtype=float)
        return position + rotation @ anchor

    @staticmethod
    def _twist(node: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(linear velocity of the CoM, angular velocity, CoM) of the body holding ``node``."""
        velocity = np.array(node.getVelocity(), dtype=float)
        return velocity[:3], velocity[3:], np.array(node.getCenterOfMass(), dtype=float)

    def joint_rate(self, joint: Joint) -> float:
        name = next(n for n, j in self.joints.items() if j is joint)
        return self.joint_rates([name])[name]

    def joint_rates(self, names: list[str] | None = None,
                    known: dict[int, Sequence[float]] | None = None) -> dict[str, float]:
        """Joint rates: the relative velocity of endPoint and parent Solid along the world joint axis (``known``:
        see :meth:`_rates`)."""
        rates = zip(self.joints, self._rates(known or {}, {}), strict=True)
        return {n: r for n, r in rates if names is None or n in names}

    def _rates(self, known: dict[int, Sequence[float]], known_velocities: dict[int, Sequence[float]]) -> list[float]:
        """:meth:`joint_rates` of every hinge/slider, in :attr:`joints` order.

        Each node's orientation and velocity is read once per call, from a plan resolved once: the state is
        read every control period, so this stays in plain floats. ``known``/``known_velocities``: row-major
        orientations and ``getVelocity`` values already read, by node id (a root body is often the joints'
        frame and a parent Solid).
        """
        if self._plan is None:
            self._plan = self._rate_plan()
        frames, solids, rows = self._plan
        rotations = [known.get(key) or node.getOrientation() for key, node in frames]
        velocities = [known_velocities.get(key) or node.getVelocity() for key, node in solids]
        coms = [node.getCenterOfMass() for _, node in solids] if self._slider else []
        out = []
        for frame, child, parent, joint_axis, slider in rows:
            ax, ay, az = joint_axis.now()
            r = rotations[frame]
            axis = (r[0] * ax + r[1] * ay + r[2] * az, r[3] * ax + r[4] * ay + r[5] * az,
                    r[6] * ax + r[7] * ay + r[8] * az)
            vc = velocities[child]
            vp = velocities[parent] if parent >= 0 else (0.0,) * 6
            if slider:
                cc = coms[child]
                cp = coms[parent] if parent >= 0 else cc
                d = (cc[0] - cp[0], cc[1] - cp[1], cc[2] - cp[2])
                rel = (vc[0] - vp[0] - (vp[4] * d[2] - vp[5] * d[1]), vc[1] - vp[1] - (vp[5] * d[0] - vp[3] * d[2]),
                       vc[2] - vp[2] - (vp[3] * d[1] - vp[4] * d[0]))
            else:
                rel = (vc[3] - vp[3], vc[4] - vp[4], vc[5] - vp[5])
            out.append(float(rel[0] * axis[0] + rel[1] * axis[1] + rel[2] * axis[2]))
        return out

    def _rate_plan(self) -> tuple[list[tuple[int, Any]], list[tuple[int, Any]],
                                  list[tuple[int, int, int, JointAxis, bool]]]:
        frames: list[tuple[int, Any]] = []
        solids: list[tuple[int, Any]] = []

        def index(nodes: list[tuple[int, Any]], node: Any) -> int:
            key = node.getId()
            for i, (k, _) in enumerate(nodes):
                if k == key:
                    return i
            nodes.append((key, node))
            return len(nodes) - 1

        rows = []
        for joint in self.joints.values():
            parent = self.parent_solid(joint.node)
            rows.append((index(frames, joint.parent), index(solids, joint.child),
                         index(solids, parent) if parent is not None else -1,
                         joint.joint_axis, joint.kind == "SliderJoint"))
        return frames, solids, rows

    @staticmethod
    def _local_fields(node: Any) -> tuple[np.ndarray, np.ndarray]:
        """(rotation matrix, translation) of a Solid's ``rotation`` and ``translation`` fields now."""
        rotation = base_field(node, "rotation").getSFRotation()
        axis = np.array(rotation[:3], dtype=float)
        return rotation_about(axis / np.linalg.norm(axis), float(rotation[3])), \
            np.array(base_field(node, "translation").getSFVec3f(), dtype=float)

    def _turn_free(self, key: int, state: MechanicalState, free: tuple[np.ndarray, ...], q_now: dict[str, float],
                   qd_now: dict[str, float], rp_now: np.ndarray, pp_now: np.ndarray, rel_r: np.ndarray,
                   rel_p: np.ndarray, rp: np.ndarray, pp: np.ndarray, wp: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A Hinge2/ball endPoint's pose relative to its parent Solid, angular velocity and world anchor in the
        written state (``rel_r``/``rel_p``: its relative pose now; ``rp``/``pp``/``wp``: the parent written)."""
        a1_w, a2_w, anchor_now = free[0], free[1], free[2]
        anchor_p = rp_now.T @ (anchor_now - pp_now)
        if key in self._hinge2_of:
            name, h = self._hinge2_of[key]
            a1, a2 = rp_now.T @ a1_w, rp_now.T @ a2_w
            first = rotation_about(a1, state.joint_positions.get(name, q_now[name]) - q_now[name])
            turn = first @ rotation_about(a2, state.joint_positions.get(h.second, q_now[h.second]) - q_now[h.second])
            rates = (state.joint_velocities.get(name, qd_now[name]), state.joint_velocities.get(h.second, qd_now[h.second]))
            new_r = turn @ rel_r
            w = wp + rp @ (a1 * rates[0] + (first @ a2) * rates[1])
        else:
            entries = [f"{self._ball_of[key]}/{c}" for c in BALL_COMPONENTS]
            rotvec = np.array([state.joint_positions.get(e, q_now[e]) for e in entries], dtype=float)
            angle = float(np.linalg.norm(rotvec))
            new_r = rotation_about(rotvec / angle, angle) if angle > 0 else np.eye(3)
            turn = new_r @ rel_r.T
            w = wp + rp @ new_r @ np.array([state.joint_velocities.get(e, qd_now[e]) for e in entries], dtype=float)
        return new_r, turn @ (rel_p - anchor_p) + anchor_p, w, rp @ anchor_p + pp

    def write(self, state: MechanicalState) -> None:
        """Queue the supervisor writes that put the robot into ``state`` (see ``WebotsTwin.set_state``)."""
        # Read everything first: once a write is queued, real Webots may answer some getters with it.
        now: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        nodes: dict[int, Any] = {}

        def remember(node: Any) -> None:
            key = node.getId()
            if key not in now:
                now[key] = pose_of(node)
                nodes[key] = node

        frames: dict[str, tuple[np.ndarray, np.ndarray, float, float]] = {}
        rates = self.joint_rates()
        for name, joint in self.joints.items():
            remember(joint.child)
            parent = self.parent_solid(joint.node)
            if parent is not None:
                remember(parent)
            axis, anchor = self._frame(joint)
            frames[name] = (axis, anchor, float(joint.position.getSFFloat()), rates[name])
        for node in self.bodies.values():
            remember(node)
        # Hinge2 and ball endPoints are written as poses relative to the parent Solid (their translation and
        # rotation fields), so their axes, anchors and current fields are read here too.
        names = self.names
        positions, velocities = self.joint_states()
        joint_q, joint_qd = dict(zip(names, positions, strict=True)), dict(zip(names, velocities, strict=True))
        free: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        for name, h in self.hinge2.items():
            a1, a2 = h.world_axes(joint_q[name])
            free[h.child.getId()] = (a1, a2, self._anchor(h.parent, h.params), *self._local_fields(h.child))
        for joint, end in self.balls.values():
            params = base_field(joint, "jointParameters").getSFNode()
            free[end.getId()] = (np.zeros(3), np.zeros(3), self._anchor(joint.getParentNode(), params),
                                 *self._local_fields(end))
        for key in free:
            child = self.hinge2[self._hinge2_of[key][0]].child if key in self._hinge2_of else \
                self.balls[self._ball_of[key]][1]
            remember(child)
            parent = self.parent_solid(child)
            if parent is not None:
                remember(parent)
        relatives: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        coms = {key: np.array(node.getCenterOfMass(), dtype=float) for key, node in nodes.items()
                if self._has_body(node)}
        current = {name: self._twist(node) for name, node in self.bodies.items() if name not in state.bodies}

        # Forward kinematics of the written state: each Solid's new pose and frame-origin twist.
        new: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        roots = {node.getId(): name for name, node in self.bodies.items()}

        def solve(node: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            key = node.getId()
            if key in new:
                return new[key]
            remember(node)
            rotation_now, position_now = now[key]
            name = roots.get(key)
            parent = None if name is not None else self.parent_solid(node)
            if name is not None and name in state.bodies:
                body = state.bodies[name]
                result = (matrix_from_quat(body.quaternion), np.asarray(body.position, dtype=float),
                          np.asarray(body.linear_velocity, dtype=float), np.asarray(body.angular_velocity, dtype=float))
            elif parent is None:
                if name is not None:  # a root the state leaves alone (partial): as it is now
                    v_com, w, com = current[name]
                    result = (rotation_now, position_now, v_com + cross(w, position_now - com), w)
                else:
                    result = (rotation_now, position_now, np.zeros(3), np.zeros(3))
            else:
                rp, pp, vp, wp = solve(parent)
                rp_now, pp_now = now[parent.getId()]
                rel_r, rel_p = rp_now.T @ rotation_now, rp_now.T @ (position_now - pp_now)
                joint = self._joint_of.get(key)
                w, extra_v, anchor_w = wp, np.zeros(3), pp
                turned = key in free
                if turned:
                    before = (rel_r, rel_p)
                    rel_r, rel_p, w, anchor_w = self._turn_free(key, state, free[key], joint_q, joint_qd, rp_now,
                                                                pp_now, rel_r, rel_p, rp, pp, wp)
                    relatives[key] = (*before, rel_r, rel_p)
                if joint is not None:
                    jname = next(n for n, j in self.joints.items() if j is joint)
                    axis_w_now, anchor_w_now, q_now, qd_now = frames[jname]
                    q = state.joint_positions.get(jname, q_now)
                    qd = state.joint_velocities.get(jname, qd_now)
                    axis_p = rp_now.T @ axis_w_now
                    anchor_p = rp_now.T @ (anchor_w_now - pp_now)
                    if joint.kind == "SliderJoint":
                        rel_p = rel_p + axis_p * (q - q_now)
                        extra_v = (rp @ axis_p) * qd
                    else:
                        turn = rotation_about(axis_p, q - q_now)
                        rel_r, rel_p = turn @ rel_r, turn @ (rel_p - anchor_p) + anchor_p
                        w = wp + (rp @ axis_p) * qd
                        anchor_w = rp @ anchor_p + pp
                rotation, position = rp @ rel_r, rp @ rel_p + pp
                velocity = vp + cross(wp, position - pp) + extra_v
                if turned or (joint is not None and joint.kind != "SliderJoint"):
                    velocity = velocity + cross(w - wp, position - anchor_w)
                result = (rotation, position, velocity, w)
            new[key] = result
            return result

        targets = [self.bodies[n] for n in state.bodies] + [self.joints[n].child for n in state.joint_positions
                                                             if n in self.joints]
        targets += [h.child for n, h in self.hinge2.items() if n in state.joint_positions or h.second in
                    state.joint_positions]
        targets += [end for n, (_, end) in self.balls.items() if f"{n}/{BALL_COMPONENTS[0]}" in state.joint_positions]
        for node in targets:
            solve(node)
        # Teleports first (parents before children), then held motors, then every body's velocity.
        for name in state.bodies:
            node = self.bodies[name]
            parent = node.getParentNode()
            if parent is not None and parent.getTypeName() not in ("Group", ""):
                raise DualtwinError(f"{self.origin}: body {name!r} is not a top-level Solid; cannot write its pose")
            rotation, position, _, _ = new[node.getId()]
            base_field(node, "translation").setSFVec3f([float(v) for v in position])
            base_field(node, "rotation").setSFRotation(axis_angle_from_matrix(rotation))
        for name, joint in self.joints.items():
            if name in state.joint_positions:
                joint.position.setSFFloat(float(state.joint_positions[name]))
        for name, h in self.hinge2.items():
            for field, entry in ((h.position, name), (h.position2, h.second)):
                if entry in state.joint_positions:
                    field.setSFFloat(float(state.joint_positions[entry]))
        for key, (rel_r_now, rel_p_now, rel_r, rel_p) in relatives.items():
            # The fields are relative to the parent Solid through fixed Poses: turn them by the relative motion.
            _, _, _, local_r, local_t = free[key]
            node = nodes[key]
            base_field(node, "translation").setSFVec3f([float(v) for v in local_r @ (rel_r_now.T @ (rel_p - rel_p_now))
                                                     + local_t])
            base_field(node, "rotation").setSFRotation(axis_angle_from_matrix(local_r @ rel_r_now.T @ rel_r))
        for name, motors in self.motors.items():
            if name not in state.joint_positions:
                continue
            for motor in motors:
                if motor.getName() not in self.commanded:
                    multiplier = motor.getMultiplier() if hasattr(motor, "getMultiplier") else 1.0
                    hold = state.holds.get(name, state.joint_positions[name])
                    motor.setPosition(float(hold) / (multiplier or 1.0))
        for key, (rotation, position, velocity, w) in new.items():
            if key not in coms:
                continue  # no body of its own: merged into its parent's
            rotation_now, position_now = now[key]
            com = rotation @ (rotation_now.T @ (coms[key] - position_now)) + position
            v_com = velocity + cross(w, com - position)
            nodes[key].setVelocity([*map(float, v_com), *map(float, w)])
