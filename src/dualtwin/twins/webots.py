"""The Webots twin, written against the Webots controller API only.

Everything here goes through ``Supervisor``, ``Motor``, ``PositionSensor``, ``Node`` and ``Field``, so the same
adapter drives our headless ODE runtime (:mod:`dualtwin.webots`) and a real Webots installation, where it runs
as an extern controller of a robot with ``supervisor TRUE`` (see the README).

Names: joints are found by the DEF of their joint node, bodies by the DEF of their Solid, motors and sensors
by their device ``name``, as in the binding.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins.base import (
    ControlMode,
    Knob,
    MechanicalState,
    StateLayout,
    SyncError,
    Twin,
    check_state_names,
    matrix_from_quat,
    quat_from_matrix,
    quat_tuple,
    rotation_vector,
    unknown_name,
)

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding
    from dualtwin.twins.camera import CameraSpec

JOINT_TYPES = ("HingeJoint", "SliderJoint", "Hinge2Joint", "BallJoint")
MOTOR_TYPES = ("RotationalMotor", "LinearMotor")
#: set_state refuses a state to which a free body responds, within one basic step, with a velocity jump
#: above these (m/s, rad/s): ODE pushing a penetrating body out (softERP 0.2 moves 2 cm of overlap at
#: 0.5 m/s with an 8 ms step) or a violated joint. Driving and gravity stay far below them.
MAX_JUMP_LINEAR = 0.5
MAX_JUMP_ANGULAR = 10.0


def _cross(a: Any, b: Any) -> np.ndarray:
    """Cross product of two 3-vectors (``np.cross`` costs tens of microseconds on tiny inputs)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _pose_of(node: Any) -> tuple[np.ndarray, np.ndarray]:
    return (np.array(node.getOrientation(), dtype=float).reshape(3, 3),
            np.array(node.getPosition(), dtype=float))


def _rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    c, s_, t = math.cos(angle), math.sin(angle), 1.0 - math.cos(angle)
    return np.array([[c + t * x * x, t * x * y - s_ * z, t * x * z + s_ * y],
                     [t * x * y + s_ * z, c + t * y * y, t * y * z - s_ * x],
                     [t * x * z - s_ * y, t * y * z + s_ * x, c + t * z * z]])


def _axis_angle(rotation: np.ndarray) -> list[float]:
    """A VRML ``rotation`` (axis, angle) for a rotation matrix."""
    q = quat_from_matrix(rotation)
    s_ = float(np.linalg.norm(q[1:]))
    if s_ < 1e-300:
        return [0.0, 0.0, 1.0, 0.0]
    return [*(q[1:] / s_), 2.0 * math.atan2(s_, float(q[0]))]


class _Joint:
    """A joint node with the handles ground truth needs."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.kind = node.getTypeName()
        self.params = node.getField("jointParameters").getSFNode()
        if self.params is None:
            raise DualtwinError(f"joint {node.getDef()!r} has no jointParameters; give it one to use it by name")
        self.position = self.params.getField("position")
        self.axis = np.array(self.params.getField("axis").getSFVec3f(), dtype=float)
        self.axis /= np.linalg.norm(self.axis)
        self.child = node.getField("endPoint").getSFNode()
        self.parent = node.getParentNode()


class WebotsTwin(Twin):
    """A Webots robot driven by a supervisor controller, in control periods of simulation time."""

    name = "webots"

    def __init__(self, supervisor: Any, control_period: float, aliases: dict[str, str] | None = None,
                 origin: str = "webots") -> None:
        self.sup = supervisor
        self._origin = origin
        self._aliases = aliases or {}
        self._basic_ms = float(supervisor.getBasicTimeStep())
        period_ms = control_period * 1000.0
        if abs(period_ms / self._basic_ms - round(period_ms / self._basic_ms)) > 1e-6:
            raise DualtwinError(f"{origin}: control period {period_ms:g} ms is not a multiple of "
                                f"basicTimeStep {self._basic_ms:g} ms")
        self._period_ms = period_ms
        self._control_period = control_period
        self._t0 = float(supervisor.getTime())
        self._joints: dict[str, _Joint] = {}
        self._bodies: dict[str, Any] = {}
        self._motors: dict[str, Any] = {}
        self._sensors: dict[str, Any] = {}
        self._gains: dict[str, float] = {}
        self._knob_values: dict[str, float] = {}
        # State transfer: motors commanded since reset (the others hold their position), the state written
        # and not yet stepped from (the supervisor shows it only after the next step), the resolved structure.
        self._commanded: set[str] = set()
        self._written: MechanicalState | None = None
        self._structure: _Structure | None = None
        # Enable every sensor now: a Webots sensor reads NaN until its first sample after enable().
        for name in self._device_names(None):
            self._sensor(name)
        self._fields = self._scan_knob_fields()
        self._nominal = {name: self._read_knob(name) for name in self._fields}
        self._knobs = self._build_knobs()

    # ---------------------------------------------------------------- name resolution
    def _resolve(self, name: str) -> str:
        return self._aliases.get(name, name)

    def _find(self, name: str, types: tuple[str, ...] | None) -> Any:
        """A node by DEF inside this robot first (DEFs may repeat across robots), then by its ``name``
        field inside the robot, then anywhere in the world (static bodies)."""
        name = self._resolve(name)
        nodes = list(self._walk())

        def ok(node: Any) -> bool:
            return types is None or node.getTypeName() in types

        for node in nodes:
            if node.getDef() == name and ok(node):
                return node
        for node in nodes:
            field = node.getField("name")
            is_solid = node.getField("children") is not None and node.getField("boundingObject") is not None
            if field is not None and is_solid and ok(node) and field.getSFString() == name:
                return node
        node = self.sup.getFromDef(name)
        return node if node is not None and ok(node) else None

    def _joint(self, name: str) -> _Joint:
        joint = self._joints.get(name)
        if joint is None:
            node = self._find(name, JOINT_TYPES)
            if node is None:
                raise unknown_name("joint", self._resolve(name), self._defs(JOINT_TYPES), self._origin)
            joint = self._joints[name] = _Joint(node)
        return joint

    def _body(self, name: str) -> Any:
        node = self._bodies.get(name)
        if node is None:
            node = self._find(name, None)
            if node is None:
                raise unknown_name("body", self._resolve(name), self._defs(None), self._origin)
            self._bodies[name] = node
        return node

    def _motor(self, name: str) -> Any:
        motor = self._motors.get(name)
        if motor is None:
            device = self.sup.getDevice(self._resolve(name))
            if device is None or not hasattr(device, "setVelocity"):
                raise unknown_name("motor", self._resolve(name), self._device_names(MOTOR_TYPES), self._origin)
            motor = self._motors[name] = device
        return motor

    def _sensor(self, name: str) -> Any:
        sensor = self._sensors.get(name)
        if sensor is None:
            device = self.sup.getDevice(self._resolve(name))
            if device is None or not hasattr(device, "enable"):
                raise unknown_name("sensor", self._resolve(name), self._device_names(None), self._origin)
            device.enable(int(self._basic_ms))
            sensor = self._sensors[name] = device
        return sensor

    def _walk(self) -> Iterator[Any]:
        """Every node of the robot's subtree (children, joint endPoints and devices, parameters)."""
        stack = [self.sup.getSelf()]
        while stack:
            node = stack.pop()
            yield node
            for field in ("children", "device"):
                handle = node.getField(field)
                if handle is not None and handle.getCount() > 0:
                    stack.extend(n for n in (handle.getMFNode(i) for i in range(handle.getCount())) if n)
            for field in ("endPoint", "jointParameters", "physics"):
                handle = node.getField(field)
                child = handle.getSFNode() if handle is not None else None
                if child is not None:
                    stack.append(child)

    def _defs(self, types: tuple[str, ...] | None) -> list[str]:
        return [n.getDef() for n in self._walk() if n.getDef() and (types is None or n.getTypeName() in types)]

    def _device_names(self, types: tuple[str, ...] | None) -> list[str]:
        out = []
        for node in self._walk():
            kind = node.getTypeName()
            name_field = node.getField("name")
            is_device = node.getField("device") is None and name_field is not None and kind != "Robot"
            wanted = kind.endswith("Sensor") if types is None else kind in types
            if is_device and wanted:
                out.append(name_field.getSFString())
        return out

    # ---------------------------------------------------------------- Twin API
    @property
    def control_period(self) -> float:
        return self._control_period

    @property
    def time(self) -> float:
        return round(float(self.sup.getTime()) - self._t0, 9)

    def reset(self, seed: int | None = None) -> None:
        # Webots reseeds its sensor noise from WorldInfo.randomSeed on reset; a controller cannot choose it.
        self.sup.simulationReset()
        self._advance(self._basic_ms)
        self._t0 = float(self.sup.getTime())
        self._commanded.clear()
        self._written = None
        # simulationReset restores every field, knobs included: re-apply them.
        self.set_knobs(dict(self._knob_values))

    def _advance(self, ms: float) -> None:
        result = self.sup.step(int(round(ms)))
        if result == -1:
            raise DualtwinError(f"{self._origin}: the simulation ended")

    def set_joint_state(self, joint: str, position: float | None = None, velocity: float | None = None) -> None:
        j = self._joint(joint)
        self._written = None
        if position is not None:
            # Webots teleports the endPoint at the next step and resets its physics
            # (docs/reference/webots-on-ode.md §4.1).
            j.position.setSFFloat(float(position))
        if velocity is not None:
            axis = self._world_axis(j)
            parent_w = self._angular(j.parent)
            if j.kind == "SliderJoint":
                linear = np.array(j.child.getVelocity()[:3]) + axis * velocity
                j.child.setVelocity([*linear, *parent_w])
            else:
                omega = parent_w + axis * velocity
                anchor = self._anchor_world(j)
                com = np.array(j.child.getCenterOfMass())
                linear = _cross(omega, com - anchor)
                j.child.setVelocity([*linear, *omega])

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        node = self._body(body)
        field = node.getField("translation")
        translation = list(field.getSFVec3f())
        parent = node.getParentNode()
        if parent is not None and parent.getTypeName() not in ("Group", ""):
            raise DualtwinError(f"{self._origin}: body {body!r} is not a top-level Solid; cannot teleport it")
        translation[axis] = float(value)
        field.setSFVec3f(translation)
        self._written = None

    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        motor = self._motor(actuator)
        self._commanded.add(self._resolve(actuator))
        value *= self._gains.get(actuator, 1.0)
        if mode == "velocity":
            motor.setPosition(math.inf)
            motor.setVelocity(float(max(-motor.getMaxVelocity(), min(motor.getMaxVelocity(), value))))
        elif mode == "position":
            motor.setVelocity(motor.getMaxVelocity())
            motor.setPosition(float(value))
        else:
            limit = motor.getMaxTorque() if hasattr(motor, "getMaxTorque") else motor.getMaxForce()
            clamped = float(max(-limit, min(limit, value)))
            (motor.setTorque if hasattr(motor, "setTorque") else motor.setForce)(clamped)

    def step(self) -> None:
        self._advance(self._period_ms)
        self._written = None

    def joint_position(self, joint: str) -> float:
        return float(self._joint(joint).position.getSFFloat())

    def _world_axis(self, j: _Joint) -> np.ndarray:
        rotation = np.array(j.parent.getOrientation(), dtype=float).reshape(3, 3)
        return rotation @ j.axis

    def _anchor_world(self, j: _Joint) -> np.ndarray:
        anchor_field = j.params.getField("anchor")
        local = np.array(anchor_field.getSFVec3f() if anchor_field is not None else [0.0, 0.0, 0.0])
        rotation = np.array(j.parent.getOrientation(), dtype=float).reshape(3, 3)
        return np.array(j.parent.getPosition(), dtype=float) + rotation @ local

    @staticmethod
    def _angular(node: Any) -> np.ndarray:
        return np.array(node.getVelocity()[3:], dtype=float) if node is not None else np.zeros(3)

    def joint_velocity(self, joint: str) -> float:
        j = self._joint(joint)
        axis = self._world_axis(j)
        if j.kind == "SliderJoint":
            relative = np.array(j.child.getVelocity()[:3]) - np.array(j.parent.getVelocity()[:3])
            return float(relative @ axis)
        return float((self._angular(j.child) - self._angular(j.parent)) @ axis)

    def body_position(self, body: str) -> np.ndarray:
        return np.array(self._body(body).getPosition(), dtype=float)

    def body_orientation(self, body: str) -> np.ndarray:
        return np.array(self._body(body).getOrientation(), dtype=float).reshape(3, 3)

    def body_velocity(self, body: str) -> np.ndarray:
        node = self._body(body)
        velocity = np.array(node.getVelocity(), dtype=float)
        # Webots reports the CoM's linear velocity; the contract is the frame origin's.
        offset = np.array(node.getPosition(), dtype=float) - np.array(node.getCenterOfMass(), dtype=float)
        velocity[:3] += _cross(velocity[3:], offset)
        return velocity

    def sensor(self, name: str) -> float:
        device = self._sensor(name)
        value = device.getValue() if hasattr(device, "getValue") else device.getValues()[0]
        return float(value)

    def render(self, camera: str | CameraSpec, width: int, height: int) -> np.ndarray:
        """An RGB frame (H, W, 3) uint8 of the current scene, rendered headless (``MUJOCO_GL=egl|osmesa``).

        Our runtime has no renderer: the world's Shapes become a visual-only MuJoCo scene whose mocap bodies
        follow the Solids' supervisor poses (:mod:`dualtwin.webots.visual_scene`). ``camera`` is a
        :class:`~dualtwin.twins.camera.CameraSpec`, the name of a Camera device, or ``"viewpoint"``.
        In real Webots use a Camera device and ``Camera.getImage()`` instead.
        """
        from dualtwin.twins.render import render_webots

        return render_webots(self, camera, width, height)

    # ---------------------------------------------------------------- state transfer (supervisor API)
    def _state_structure(self) -> _Structure:
        if self._structure is None:
            self._structure = _Structure(self)
        return self._structure

    def _read_state(self) -> tuple[StateLayout, list[float]]:
        """Root poses and velocities from ``Node.getPose/getVelocity`` (the CoM velocity moved to the frame
        origin), joint positions from their ``position`` fields, joint rates from the relative angular (or,
        for sliders, linear) velocity of the endPoint and the parent Solid along the joint axes, and ball
        joints from the endPoint's rotation relative to the parent Solid."""
        st = self._state_structure()
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
        commanded = self._commanded
        for name, motors in st.hold_motors:
            for motor, motor_name in motors:
                if motor_name not in commanded:
                    target = motor.getTargetPosition()
                    if math.isfinite(target):
                        holds.append(name)
                        out.append(float(target))
                        break
        return st.layout(tuple(holds)), out

    def state_vector(self) -> tuple[StateLayout, np.ndarray]:
        if self._written is not None:
            written = self._written
            return StateLayout(written.bodies, written.joint_positions, written.holds), written.vector()
        layout, values = self._read_state()
        return layout, np.array(values)

    def get_state(self) -> MechanicalState:
        """See :meth:`_read_state`. Right after :meth:`set_state` the supervisor still shows the pre-write
        state until the next step; the state written is returned then (it is exactly what the next step
        starts from)."""
        if self._written is not None:
            state = self._written.copy()
            state.time = self.time
            return state
        layout, values = self._read_state()
        return layout.state(values, self.time, self.name)

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        """Write ``state`` through the supervisor so that the next :meth:`step` evolves from it.

        The writes: each root's ``translation``/``rotation`` fields (a teleport that keeps velocities), each
        joint's ``position`` field (a teleport of its endPoint that resets the subtree's physics), the held
        motors' ``Motor.setPosition`` (see the module docstring of :mod:`dualtwin.twins.base`), then
        ``Node.setVelocity`` of every body, computed by forward kinematics from the written state. Webots
        executes these in order just before the next physics step.

        Webots steps once with the contact joints of the *old* pose after a teleport (spec §1.6). So the twin
        writes the state and runs one basic step (its contacts are then collided near the new pose), writes it
        again and runs a second basic step (with those contacts: a body written into the floor is now pushed
        out, which the check below sees), and writes it a third time. These basic steps are not counted on the
        control clock: ``time`` does not move, and the next :meth:`step` starts from ``state`` exactly, with
        contacts collided within one basic step of it.

        Raises:
            DualtwinError: A body or joint cannot be mapped, or a root is not a top-level Solid.
            SyncError: Non-finite values; the physics became unstable; a free body's velocity jumped by more
                than ``MAX_JUMP_LINEAR`` m/s or ``MAX_JUMP_ANGULAR`` rad/s within a basic step (penetration
                or a violated joint). The twin then needs a :meth:`reset`.
        """
        st = self._state_structure()
        check_state_names(state, list(st.bodies), st.names, self._origin, partial)
        # What get_state will answer until the next step: the current state overlaid with the written parts,
        # and the holds the held motors will have.
        expected = self.get_state()
        expected.bodies.update({n: b for n, b in state.copy().bodies.items()})
        expected.joint_positions.update(state.joint_positions)
        expected.joint_velocities.update(state.joint_velocities)
        for name in state.joint_positions:
            if any(m.getName() not in self._commanded for m in st.motors.get(name, [])):
                expected.holds[name] = state.holds.get(name, state.joint_positions[name])
        self._written = None
        dt = self._basic_ms / 1000.0
        for settle in (False, True):
            st.write(state)
            try:
                self._advance(self._basic_ms)
            except SimulationUnstable as exc:
                raise SyncError(f"{self._origin}: the physics became unstable in the state written ({exc}); "
                                "reset the twin", "unstable") from None
            self._t0 += dt
            if settle:
                self._check_jump(st, state, dt)
        st.write(state)
        self._written = expected

    def _check_jump(self, st: _Structure, state: MechanicalState, dt: float) -> None:
        for name, body in state.bodies.items():
            node = st.bodies[name]
            velocity = np.array(node.getVelocity(), dtype=float)
            com = np.array(node.getCenterOfMass(), dtype=float)
            linear = velocity[:3] + _cross(velocity[3:], np.array(node.getPosition(), dtype=float) - com)
            jump_v = float(np.linalg.norm(linear - body.linear_velocity))
            jump_w = float(np.linalg.norm(velocity[3:] - body.angular_velocity))
            if jump_v > MAX_JUMP_LINEAR or jump_w > MAX_JUMP_ANGULAR:
                raise SyncError(f"{self._origin}: body {name!r} was thrown by the state written (velocity jump "
                                f"{jump_v:.3g} m/s, {jump_w:.3g} rad/s in {dt * 1000:g} ms): penetration or a "
                                "violated joint; reset the twin", "jump")

    # ---------------------------------------------------------------- knobs, through Field edits
    def _scan_knob_fields(self) -> dict[str, tuple[Any, str, int | None]]:
        """Knob name -> (node, field, MF index). Only fields Webots applies live are offered."""
        fields: dict[str, tuple[Any, str, int | None]] = {}
        for node in self._walk():
            kind = node.getTypeName()
            if kind in JOINT_TYPES and node.getDef():
                params = node.getField("jointParameters").getSFNode()
                if params is not None:
                    fields[f"joint.{node.getDef()}.damping"] = (params, "dampingConstant", None)
                    fields[f"joint.{node.getDef()}.friction"] = (params, "staticFriction", None)
            elif kind in MOTOR_TYPES:
                name = node.getField("name").getSFString()
                torque = "maxTorque" if kind == "RotationalMotor" else "maxForce"
                fields[f"motor.{name}.max_torque"] = (node, torque, None)
                fields[f"motor.{name}.max_velocity"] = (node, "maxVelocity", None)
            elif kind == "Physics":
                continue
            physics = node.getField("physics")
            physics_node = physics.getSFNode() if physics is not None else None
            if node.getDef() and physics_node is not None and physics_node.getField("mass").getSFFloat() > 0:
                fields[f"body.{node.getDef()}.mass"] = (physics_node, "mass", None)
        root = self.sup.getRoot().getField("children")
        info = next((n for n in (root.getMFNode(i) for i in range(root.getCount())) if n
                     and n.getTypeName() == "WorldInfo"), None)
        if info is not None:
            fields["world.erp"] = (info, "ERP", None)
            fields["world.cfm"] = (info, "CFM", None)
            contacts = info.getField("contactProperties")
            for i in range(contacts.getCount()):
                cp = contacts.getMFNode(i)
                pair = f"{cp.getField('material1').getSFString()}:{cp.getField('material2').getSFString()}"
                fields[f"contact.{pair}.friction"] = (cp, "coulombFriction", 0)
                fields[f"contact.{pair}.bounce"] = (cp, "bounce", None)
                fields[f"contact.{pair}.soft_erp"] = (cp, "softERP", None)
                fields[f"contact.{pair}.soft_cfm"] = (cp, "softCFM", None)
        return fields

    def _read_knob(self, name: str) -> float:
        node, field, index = self._fields[name]
        handle = node.getField(field)
        return float(handle.getMFFloat(index) if index is not None else handle.getSFFloat())

    def _write_knob(self, name: str, value: float) -> None:
        node, field, index = self._fields[name]
        handle = node.getField(field)
        if index is not None:
            handle.setMFFloat(index, float(value))
        else:
            handle.setSFFloat(float(value))

    def _build_knobs(self) -> dict[str, Knob]:
        knobs: dict[str, Knob] = {}
        units = {"damping": "N*m*s/rad", "friction": "N*m", "max_torque": "N*m", "max_velocity": "rad/s",
                 "mass": "kg"}
        for name, nominal in self._nominal.items():
            prop = name.rsplit(".", 1)[-1]
            if prop in ("soft_erp", "erp"):
                lower, upper = 0.01, 1.0
            elif prop in ("soft_cfm", "cfm"):
                lower, upper = 1e-9, max(nominal * 100, 1e-2)
            elif prop == "bounce":
                lower, upper = 0.0, 1.0
            elif prop == "mass":
                lower, upper = 0.1 * nominal, 10 * nominal
            elif prop == "friction" and name.startswith("contact."):
                lower, upper = 0.0, 5 * max(nominal, 0.1)
            else:
                lower, upper = 0.0, max(10 * nominal, 1.0 if prop == "damping" else 0.5)
            knobs[name] = Knob(name, nominal, min(lower, nominal), max(upper, nominal), units.get(prop, ""))
        for motor in self._device_names(MOTOR_TYPES):
            knobs[f"motor.{motor}.gain"] = Knob(f"motor.{motor}.gain", 1.0, -2.0, 2.0, "",
                                                 "command gain (sign included)")
        return knobs

    def knobs(self) -> dict[str, Knob]:
        return dict(self._knobs)

    def set_knobs(self, values: dict[str, float]) -> None:
        unknown = sorted(set(values) - set(self._knobs))
        if unknown:
            raise DualtwinError(f"{self._origin}: unknown knobs: {', '.join(unknown)}")
        for name, nominal in self._nominal.items():
            target = values.get(name, nominal)
            if self._read_knob(name) != target:
                self._write_knob(name, target)
        self._gains = {k.split(".")[1]: v for k, v in values.items() if k.endswith(".gain")}
        self._knob_values = dict(values)


class _Hinge2:
    """A Hinge2Joint: two state joints, ``<DEF>`` (axis 1, fixed in the parent) and ``<DEF>2`` (axis 2,
    turning with axis 1), as the Webots-to-MJCF converter names its two hinges."""

    def __init__(self, node: Any, second: str) -> None:
        self.node = node
        self.second = second
        params = [node.getField(f).getSFNode() for f in ("jointParameters", "jointParameters2")]
        if params[0] is None or params[1] is None:
            raise DualtwinError(f"Hinge2Joint {node.getDef()!r} needs jointParameters and jointParameters2 "
                                "for its state to be read and written")
        self.params, self.params2 = params
        self.position, self.position2 = (p.getField("position") for p in params)
        self.axis, self.axis2 = (np.array(p.getField("axis").getSFVec3f(), dtype=float) for p in params)
        self.axis /= np.linalg.norm(self.axis)
        self.axis2 /= np.linalg.norm(self.axis2)
        self.child = node.getField("endPoint").getSFNode()
        self.parent = node.getParentNode()

    def world_axes(self, q1: float) -> tuple[np.ndarray, np.ndarray]:
        """World axes now: axis 2 is given for axis 1 at zero and turns with it (as ODE's hinge-2 axis 2)."""
        rotation = np.array(self.parent.getOrientation(), dtype=float).reshape(3, 3)
        return rotation @ self.axis, rotation @ (_rotation_about(self.axis, q1) @ self.axis2)


#: State joints of a BallJoint ``B``: ``B/rx``, ``B/ry``, ``B/rz`` (see :mod:`dualtwin.twins.base`).
BALL_COMPONENTS = ("rx", "ry", "rz")


class _Structure:
    """The robot's roots, joints and held-motor map for state transfer, resolved once through the API."""

    def __init__(self, twin: WebotsTwin) -> None:
        self.twin = twin
        inverse = {v: k for k, v in twin._aliases.items()}
        sup = twin.sup
        self.bodies: dict[str, Any] = {}
        me = sup.getSelf()
        candidates = [me]
        root = sup.getRoot().getField("children")
        for i in range(root.getCount()):
            node = root.getMFNode(i)
            if node is not None and node != me and node.getDef() and self._has_body(node):
                candidates.append(node)
        for node in candidates:
            if self._has_body(node):
                name = node.getDef() or node.getField("name").getSFString()
                self.bodies[inverse.get(name, name)] = node
        self.joints: dict[str, _Joint] = {}
        self.hinge2: dict[str, _Hinge2] = {}
        self.balls: dict[str, Any] = {}  # name -> (joint node, endPoint)
        self.motors: dict[str, list[Any]] = {}  # state joint name -> its motor devices

        def motors(node: Any, field: str) -> list[Any]:
            devices = node.getField(field)
            names = [devices.getMFNode(i).getField("name").getSFString() for i in range(devices.getCount())
                     if devices.getMFNode(i) is not None and devices.getMFNode(i).getTypeName() in MOTOR_TYPES]
            return [d for d in (sup.getDevice(n) for n in names) if d is not None]

        for node in twin._walk():
            kind = node.getTypeName()
            if kind not in JOINT_TYPES or not node.getDef():
                continue
            end = node.getField("endPoint")
            if end is None or end.getSFNode() is None:
                continue
            name = inverse.get(node.getDef(), node.getDef())
            if kind == "BallJoint":
                self.balls[name] = (node, end.getSFNode())
            elif kind == "Hinge2Joint":
                second = inverse.get(node.getDef() + "2", node.getDef() + "2")
                self.hinge2[name] = _Hinge2(node, second)
                self.motors[name], self.motors[second] = motors(node, "device"), motors(node, "device2")
            elif node.getField("jointParameters").getSFNode() is not None:
                self.joints[name] = _Joint(node)
                self.motors[name] = motors(node, "device")
        self.names = [*self.joints, *(n for name, h in self.hinge2.items() for n in (name, h.second)),
                      *(f"{b}/{c}" for b in self.balls for c in BALL_COMPONENTS)]
        # Read every control period in lockstep: node ids and motor names resolved once.
        self.roots = [(node.getId(), node) for node in self.bodies.values()]
        self.hold_motors = [(name, [(m, m.getName()) for m in motors]) for name, motors in self.motors.items()]
        self._layouts: dict[tuple[str, ...], StateLayout] = {}
        self._parents: dict[int, Any] = {}
        self._joint_of: dict[int, _Joint] = {j.child.getId(): j for j in self.joints.values()}
        self._hinge2_of: dict[int, tuple[str, _Hinge2]] = {h.child.getId(): (n, h) for n, h in self.hinge2.items()}
        self._ball_of: dict[int, str] = {end.getId(): n for n, (_, end) in self.balls.items()}
        self._slider = any(j.kind == "SliderJoint" for j in self.joints.values())
        self._plan: tuple[list[tuple[int, Any]], list[tuple[int, Any]],
                          list[tuple[int, int, int, tuple[float, ...], bool]]] | None = None
        for name in self.joints:
            self.parent_solid(self.joints[name].node)

    def layout(self, holds: tuple[str, ...]) -> StateLayout:
        layout = self._layouts.get(holds)
        if layout is None:
            layout = self._layouts[holds] = StateLayout(self.bodies, self.names, holds)
        return layout

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
        physics = node.getField("physics")
        return physics is not None and physics.getSFNode() is not None

    @staticmethod
    def _is_solid(node: Any) -> bool:
        return node.getField("physics") is not None

    def parent_solid(self, node: Any) -> Any:
        """The closest Solid above ``node`` (None for a top-level node)."""
        key = node.getId()
        if key not in self._parents:
            parent = node.getParentNode()
            while parent is not None and not self._is_solid(parent):
                parent = parent.getParentNode()
            self._parents[key] = parent
        return self._parents[key]

    def _frame(self, joint: _Joint) -> tuple[np.ndarray, np.ndarray]:
        """World axis and anchor of a joint now (axis and anchor live in the closest upper Pose, spec §4.1)."""
        rotation, _ = _pose_of(joint.parent)
        return rotation @ joint.axis, self._anchor(joint.parent, joint.params)

    @staticmethod
    def _anchor(frame: Any, params: Any) -> np.ndarray:
        """World anchor of a joint now, from its parameters' ``anchor`` in the closest upper Pose ``frame``."""
        rotation, position = _pose_of(frame)
        field = params.getField("anchor") if params is not None else None
        anchor = np.array(field.getSFVec3f() if field is not None else [0.0, 0.0, 0.0], dtype=float)
        return position + rotation @ anchor

    @staticmethod
    def _twist(node: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(linear velocity of the CoM, angular velocity, CoM) of the body holding ``node``."""
        velocity = np.array(node.getVelocity(), dtype=float)
        return velocity[:3], velocity[3:], np.array(node.getCenterOfMass(), dtype=float)

    def joint_rate(self, joint: _Joint) -> float:
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
        for frame, child, parent, (ax, ay, az), slider in rows:
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
                                  list[tuple[int, int, int, tuple[float, ...], bool]]]:
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
                         tuple(float(v) for v in joint.axis), joint.kind == "SliderJoint"))
        return frames, solids, rows

    @staticmethod
    def _local_fields(node: Any) -> tuple[np.ndarray, np.ndarray]:
        """(rotation matrix, translation) of a Solid's ``rotation`` and ``translation`` fields now."""
        rotation = node.getField("rotation").getSFRotation()
        axis = np.array(rotation[:3], dtype=float)
        return _rotation_about(axis / np.linalg.norm(axis), float(rotation[3])), \
            np.array(node.getField("translation").getSFVec3f(), dtype=float)

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
            first = _rotation_about(a1, state.joint_positions.get(name, q_now[name]) - q_now[name])
            turn = first @ _rotation_about(a2, state.joint_positions.get(h.second, q_now[h.second]) - q_now[h.second])
            rates = (state.joint_velocities.get(name, qd_now[name]), state.joint_velocities.get(h.second, qd_now[h.second]))
            new_r = turn @ rel_r
            w = wp + rp @ (a1 * rates[0] + (first @ a2) * rates[1])
        else:
            entries = [f"{self._ball_of[key]}/{c}" for c in BALL_COMPONENTS]
            rotvec = np.array([state.joint_positions.get(e, q_now[e]) for e in entries], dtype=float)
            angle = float(np.linalg.norm(rotvec))
            new_r = _rotation_about(rotvec / angle, angle) if angle > 0 else np.eye(3)
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
                now[key] = _pose_of(node)
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
            params = joint.getField("jointParameters").getSFNode()
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
                    result = (rotation_now, position_now, v_com + _cross(w, position_now - com), w)
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
                        turn = _rotation_about(axis_p, q - q_now)
                        rel_r, rel_p = turn @ rel_r, turn @ (rel_p - anchor_p) + anchor_p
                        w = wp + (rp @ axis_p) * qd
                        anchor_w = rp @ anchor_p + pp
                rotation, position = rp @ rel_r, rp @ rel_p + pp
                velocity = vp + _cross(wp, position - pp) + extra_v
                if turned or (joint is not None and joint.kind != "SliderJoint"):
                    velocity = velocity + _cross(w - wp, position - anchor_w)
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
                raise DualtwinError(f"{self.twin._origin}: body {name!r} is not a top-level Solid; cannot write its pose")
            rotation, position, _, _ = new[node.getId()]
            node.getField("translation").setSFVec3f([float(v) for v in position])
            node.getField("rotation").setSFRotation(_axis_angle(rotation))
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
            node.getField("translation").setSFVec3f([float(v) for v in local_r @ (rel_r_now.T @ (rel_p - rel_p_now))
                                                     + local_t])
            node.getField("rotation").setSFRotation(_axis_angle(local_r @ rel_r_now.T @ rel_r))
        for name, motors in self.motors.items():
            if name not in state.joint_positions:
                continue
            for motor in motors:
                if motor.getName() not in self.twin._commanded:
                    multiplier = motor.getMultiplier() if hasattr(motor, "getMultiplier") else 1.0
                    hold = state.holds.get(name, state.joint_positions[name])
                    motor.setPosition(float(hold) / (multiplier or 1.0))
        for key, (rotation, position, velocity, w) in new.items():
            if key not in coms:
                continue  # no body of its own: merged into its parent's
            rotation_now, position_now = now[key]
            com = rotation @ (rotation_now.T @ (coms[key] - position_now)) + position
            v_com = velocity + _cross(w, com - position)
            nodes[key].setVelocity([*map(float, v_com), *map(float, w)])


def from_binding(robot: RobotBinding, control_period: float) -> WebotsTwin:
    """The Webots twin on our headless ODE runtime."""
    from dualtwin.webots import load_world
    from dualtwin.webots.controller import Supervisor
    from dualtwin.webots.physics import Simulation

    section = robot.spec.twins.get("webots")
    world_path: Path = robot.model_path("webots")
    world = load_world(world_path)
    robot_def = section.robot if section else None
    simulation = Simulation(world)
    robot_node = None
    if robot_def:
        robot_node = next((r.node for r in simulation.robots if r.node.def_name == robot_def), None) or next(
            (r.node for r in simulation.robots if r.name == robot_def), None)
        if robot_node is None:
            robots = ", ".join(f"{r.node.def_name or '-'} ({r.name})" for r in simulation.robots) or "none"
            raise DualtwinError(f"{world_path}: no robot with DEF or name {robot_def!r} (robots: {robots})")
    kwargs: dict[str, Any] = {"simulation": simulation}
    if robot_node is not None:
        kwargs["robot_node"] = robot_node
    elif simulation.robots:
        kwargs["robot_node"] = simulation.robots[0].node
    supervisor = Supervisor(**kwargs)
    supervisor.step(int(round(supervisor.getBasicTimeStep())))  # Webots' first step after load: time 0 → dt
    twin = WebotsTwin(supervisor, control_period, dict(section.aliases) if section else None, str(world_path))
    twin.reset()
    return twin
