"""The Webots twin, written against the Webots controller API only.

Everything here goes through ``Supervisor``, ``Motor``, ``PositionSensor``, ``Node`` and ``Field``, so the same
adapter drives our headless ODE runtime (:mod:`dualtwin.webots`) and a real Webots installation, where it runs
as an extern controller of a robot with ``supervisor TRUE`` (see the README).

Names: joints are found by the DEF of their joint node, bodies by the DEF of their Solid, motors and sensors
by their device ``name``, as in the binding.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins.base import (
    ControlMode,
    Knob,
    MechanicalState,
    NameKind,
    StateLayout,
    SyncError,
    Twin,
    check_state_names,
    control_substeps,
    unknown_name,
)
from dualtwin.twins.webots_knobs import WEBOTS_KNOBS
from dualtwin.twins.webots_state import (
    JOINT_TYPES,
    MOTOR_TYPES,
    Joint,
    StateStructure,
    base_field,
    cross,
)
from dualtwin.webots.motor_api import coupled_groups

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding
    from dualtwin.twins.camera import CameraSpec

#: Devices besides the ``*Sensor`` nodes whose reading ``sensor()`` takes (the first component of a vector): each is
#: enabled when the twin is made, as a MuJoCo sensor reads from the first step.
SCALAR_READ_TYPES = ("GPS", "Gyro", "Accelerometer", "Compass", "Altimeter")


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
        control_substeps(control_period, self._basic_ms / 1000.0, origin, "WorldInfo.basicTimeStep")
        self._period_ms = period_ms
        self._control_period = control_period
        self._t0 = float(supervisor.getTime())
        self._joints: dict[str, Joint] = {}
        self._bodies: dict[str, Any] = {}
        self._motors: dict[str, Any] = {}
        self._sensors: dict[str, Any] = {}
        self._gains: dict[str, float] = {}
        self._coupled: dict[str, list[Any]] = {}  # motor name as commanded -> it and its coupled siblings
        self._knob_values: dict[str, float] = {}
        # State transfer: motors commanded since reset (the others hold their position), the state written
        # and not yet stepped from (the supervisor shows it only after the next step), the resolved structure.
        self._commanded: set[str] = set()
        self._written: MechanicalState | None = None
        self._structure: StateStructure | None = None
        # Enable every sensor now: a Webots sensor reads NaN until its first sample after enable().
        for name in self._device_names(None):
            self._sensor(name)
        # The knobs and their nominal values, read once from the world as loaded (see twins.webots_knobs).
        self._knobs = WEBOTS_KNOBS.build(self)

    # ---------------------------------------------------------------- name resolution
    def _resolve(self, name: str) -> str:
        return self._aliases.get(name, name)

    def _find(self, name: str, types: tuple[str, ...] | None) -> Any:
        """A node by DEF inside this robot first (DEFs may repeat across robots), then by its ``name``
        field inside the robot, then anywhere in the world (static bodies)."""
        name = self._resolve(name)
        if not name:  # no node has an empty DEF: "" would match the first node without one (the robot itself)
            return None
        nodes = list(self._walk())

        def ok(node: Any) -> bool:
            return types is None or node.getTypeName() in types

        for node in nodes:
            if node.getDef() == name and ok(node):
                return node
        for node in nodes:
            field = base_field(node, "name")
            is_solid = base_field(node, "children") is not None and base_field(node, "boundingObject") is not None
            if field is not None and is_solid and ok(node) and field.getSFString() == name:
                return node
        node = self.sup.getFromDef(name)
        return node if node is not None and ok(node) else None

    def _joint(self, name: str) -> Joint:
        joint = self._joints.get(name)
        if joint is None:
            node = self._find(name, JOINT_TYPES)
            if node is None:
                raise unknown_name("joint", self._resolve(name), self._defs(JOINT_TYPES), self._origin)
            joint = self._joints[name] = Joint(node)
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

    def _position_velocity(self, name: str, motor: Any) -> float:
        """The velocity a position command gives first, so that a former velocity command does not slow the
        move: the motor's maxVelocity, lowered to the largest value that neither its multiplier nor a coupled
        sibling's takes past that motor's own maxVelocity. Webots clips ``setVelocity(v)``'s ``v·multiplier`` to
        ±maxVelocity with a warning, for each motor the command is relayed to (webots-devices.md §9,
        webots-on-ode.md §5.2), while a position command is ``setPosition`` alone there, which warns about no
        velocity: given maxVelocity itself, a motor with |multiplier| > 1 warned here where Webots does not. Each
        motor's target velocity is what the clipping gave before, to the last bit at most (the velocity is
        stepped down until every product is within its limit)."""
        group = self._coupled.get(name)
        if group is None:
            group = self._coupled[name] = self._coupled_with(motor)
        velocity = float(motor.getMaxVelocity())
        for member in group:
            factor = abs(float(member.getMultiplier())) if hasattr(member, "getMultiplier") else 1.0
            limit = float(member.getMaxVelocity())
            if velocity * factor > limit:
                velocity = limit / factor
                while velocity * factor > limit:
                    velocity = math.nextafter(velocity, 0.0)
        return velocity

    def _coupled_with(self, motor: Any) -> list[Any]:
        """``motor`` and the motors coupled with it (the robot's motors named ``prefix::suffix`` with its prefix,
        exactly two parts: webots-devices.md §9), to which Webots relays its commands."""
        name = motor.getName()
        group = coupled_groups(self._device_names(MOTOR_TYPES)).get(name.split("::")[0], []) if "::" in name else []
        siblings = [self.sup.getDevice(n) for n in group if n != name]
        return [motor, *(s for s in siblings if s is not None)]

    def _sensor(self, name: str) -> Any:
        sensor = self._sensors.get(name)
        if sensor is None:
            device = self.sup.getDevice(self._resolve(name))
            if device is None or not (hasattr(device, "getValue") or hasattr(device, "getValues")):
                # a Camera, Lidar or InertialUnit has no value a scalar read could take the first component of
                raise unknown_name("sensor", self._resolve(name), self._device_names(None), self._origin)
            # Webots' enable() takes whole milliseconds (0 disables) and samples once a period has elapsed: the
            # basic step rounded down samples every step, 1 ms as often as it can below a 1 ms step.
            device.enable(max(1, int(self._basic_ms)))
            sensor = self._sensors[name] = device
        return sensor

    def check_name(self, kind: NameKind, name: str) -> None:
        if kind == "joint":
            self._joint(name)
        elif kind == "body":
            self._body(name)
        elif kind == "free body":
            self._translation(name)
        else:
            # Through the device list, not getDevice(): that prints Webots' "not found" warning, a second line.
            resolved = self._resolve(name)
            devices = (self.sup.getDeviceByIndex(i) for i in range(self.sup.getNumberOfDevices()))
            device = next((d for d in devices if d is not None and d.getName() == resolved), None)
            if device is None or not hasattr(device, "setVelocity" if kind == "motor" else "enable"):
                known = self._device_names(MOTOR_TYPES if kind == "motor" else None)
                raise unknown_name(kind, resolved, known, self._origin)

    def _walk(self) -> Iterator[Any]:
        """Every node of the robot's subtree (children, joint endPoints and devices of every axis, parameters)."""
        stack = [self.sup.getSelf()]
        while stack:
            node = stack.pop()
            yield node
            for field in ("children", "device", "device2", "device3"):  # a Hinge2Joint's, a BallJoint's other axes
                handle = base_field(node, field)
                if handle is not None and handle.getCount() > 0:
                    stack.extend(n for n in (handle.getMFNode(i) for i in range(handle.getCount())) if n)
            for field in ("endPoint", "jointParameters", "physics"):
                handle = base_field(node, field)
                child = handle.getSFNode() if handle is not None else None
                if child is not None:
                    stack.append(child)

    def _defs(self, types: tuple[str, ...] | None) -> list[str]:
        return [n.getDef() for n in self._walk() if n.getDef() and (types is None or n.getTypeName() in types)]

    def _device_names(self, types: tuple[str, ...] | None) -> list[str]:
        out = []
        for node in self._walk():
            kind = node.getTypeName()
            name_field = base_field(node, "name")
            is_device = base_field(node, "device") is None and name_field is not None and kind != "Robot"
            wanted = (kind.endswith("Sensor") or kind in SCALAR_READ_TYPES) if types is None else kind in types
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
                linear = cross(omega, com - anchor)
                j.child.setVelocity([*linear, *omega])

    def _translation(self, body: str) -> Any:
        """The translation field that teleports ``body``: a top-level Solid's (a node found by DEF may be a
        joint, which has none)."""
        node = self._body(body)
        field = base_field(node, "translation")
        parent = node.getParentNode()
        if field is None or (parent is not None and parent.getTypeName() not in ("Group", "")):
            raise DualtwinError(f"{self._origin}: body {body!r} is not a top-level Solid; cannot teleport it")
        return field

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        field = self._translation(body)
        translation = list(field.getSFVec3f())
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
            motor.setVelocity(self._position_velocity(actuator, motor))
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

    def _world_axis(self, j: Joint) -> np.ndarray:
        rotation = np.array(j.parent.getOrientation(), dtype=float).reshape(3, 3)
        return rotation @ j.axis

    def _anchor_world(self, j: Joint) -> np.ndarray:
        anchor_field = base_field(j.params, "anchor")
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
        velocity[:3] += cross(velocity[3:], offset)
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
    def _state_structure(self) -> StateStructure:
        if self._structure is None:
            self._structure = StateStructure(self.sup, self._walk(), self._aliases, self._origin, self._commanded)
        return self._structure

    def state_vector(self) -> tuple[StateLayout, np.ndarray]:
        if self._written is not None:
            written = self._written
            return StateLayout(written.bodies, written.joint_positions, written.holds), written.vector()
        layout, values = self._state_structure().read()
        return layout, np.array(values)

    def get_state(self) -> MechanicalState:
        """See :meth:`StateStructure.read <dualtwin.twins.webots_state.StateStructure.read>`. Right after :meth:`set_state` the supervisor still shows the pre-write
        state until the next step; the state written is returned then (it is exactly what the next step
        starts from)."""
        if self._written is not None:
            state = self._written.copy()
            state.time = self.time
            return state
        layout, values = self._state_structure().read()
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
                than ``webots_state.MAX_JUMP_LINEAR`` m/s or ``MAX_JUMP_ANGULAR`` rad/s within a basic step (penetration
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
                st.check_jump(state, dt)
        st.write(state)
        self._written = expected

    # ---------------------------------------------------------------- knobs (one table: twins.webots_knobs)
    def knobs(self) -> dict[str, Knob]:
        return {name: bound.knob for name, bound in self._knobs.items()}

    def set_knobs(self, values: dict[str, float]) -> None:
        unknown = sorted(set(values) - set(self._knobs))
        if unknown:
            raise DualtwinError(f"{self._origin}: unknown knobs: {', '.join(unknown)}")
        # Every knob through its table entry: the value given, else the nominal (fields unchanged are not
        # written, so Webots does not re-apply them).
        for name, bound in self._knobs.items():
            bound.kind.apply(self, bound.handle, values.get(name, bound.knob.nominal))
        self._knob_values = dict(values)


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
