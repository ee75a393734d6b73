"""Track: a belt that moves through ODE contact surface velocity, with its LinearMotor and PositionSensor.

Webots (``WbTrack``) keeps the belt geometry fixed to the Track Solid and makes it *act* as moving: every contact
involving a Track geom gets a surface velocity (``dContactMotion1``). Per step, before physics:

* position or velocity control: the belt speed ``v`` comes from the motor's usual law (PID on the belt position,
  velocity and acceleration limits, the same as for joint motors), so ``v`` follows the commanded speed;
* force control (``setForce``): ``v = (F − c·v_prev)·dt / m`` with ``m`` the mass of the Track's body and ``c``
  the damping constant of the Brake in its ``device`` field (Webots' formula, which does not integrate);
* no motor, or no body (a Track without Physics): the belt does not move;
* the belt position (what the PositionSensor reads) integrates ``v``.

A supervisor's edit of the motor's maxVelocity, maxForce, acceleration, controlPID, minPosition/maxPosition or
multiplier acts from the next step, as a joint motor's (``physics/motor_edits.py``).

In the collision pass, for each contact point (normal ``n`` negated when the Track is the pair's second geom):
``c = n·ẑ_track``; the surface speed is ``v·s·|acos(c) − π/2|/(π/2)`` with the sign ``s`` chosen from the raw
normal's component along the dominant gravity axis (z in ENU, y in NUE/EUN) and the sign of ``c`` as Webots
does, so contacts on the belt's top and bottom faces move in opposite directions and side contacts not at all.
When the Track geom has a body, the friction direction is the Track's x axis (negated under the belt). Without a
motor the belt does not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.api_args import as_float, finite, warn
from dualtwin.webots.device_base import Device
from dualtwin.webots.joint_devices import Brake, PositionSensor
from dualtwin.webots.kinematic_motor import KinematicMotor
from dualtwin.webots.motor_api import (
    check_maxima,
    clamp_force,
    read_motor_fields,
    refuse_nan,
)
from dualtwin.webots.motor_law import motor_velocity
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import Simulation, SolidRec
from dualtwin.webots.physics.edit_stamps import stamps_of, written_since
from dualtwin.webots.step_hints import buffered

__all__ = ["TrackBrake", "TrackMotor", "TrackPositionSensor", "TrackRec", "gravity_axis", "install"]


@dataclass(eq=False)
class TrackRec:
    """A Track Solid, its belt state and its motor's controller state."""

    solid: SolidRec
    motor: Node | None
    sensor: Node | None
    brake: Node | None = None
    damping: float = 0.0  # the Brake's damping constant (N·s/m), set by Brake.setDampingConstant
    max_velocity: float = 10.0
    max_force: float = 10.0
    acceleration: float = -1.0
    load_acceleration: float = -1.0  # the motor's acceleration field as loaded (a reset restores it)
    kp: float = 10.0
    ki: float = 0.0
    kd: float = 0.0
    multiplier: float = 1.0
    min_position: float = 0.0
    max_position: float = 0.0
    target_position: float = 0.0
    target_velocity: float = 0.0
    available: float = 0.0
    force_mode: bool = False
    force: float = 0.0
    integral: float = 0.0
    prev_error: float = 0.0
    current_velocity: float = 0.0
    position: float = 0.0  # belt travel (m)
    velocity: float = 0.0  # belt speed (m/s)
    devices: dict[str, Any] = field(default_factory=dict)
    #: the motor's write stamps when its fields were last read (physics/edit_stamps.py): the node's and each field's
    stamps: dict[Any, int] = field(default_factory=dict)

    def control(self, dt: float) -> None:
        body = self.solid.body
        if self.motor is None or body is None:  # §7.2: no motor or no body: the belt does not move
            self.velocity = 0.0
            return
        if self.force_mode:
            # §7.2: v = (F − brakeDamping·v_prev)·dt / m (Webots' formula: it does not integrate)
            self.velocity = (self.force - self.damping * self.velocity) * dt / body.mass if body.mass > 0 else 0.0
        else:
            u, self.integral, self.prev_error = motor_velocity(
                target_position=self.target_position, target_velocity=self.target_velocity,
                available=self.available, position=self.position, integral=self.integral,
                previous_error=self.prev_error, current_velocity=self.current_velocity, kp=self.kp, ki=self.ki,
                kd=self.kd, acceleration=self.acceleration, dt=dt,
            )  # fmt: skip
            self.current_velocity = u
            self.velocity = u
        self.position += self.velocity * dt


def _make(solid: SolidRec, sim: Simulation) -> TrackRec:
    found: dict[str, Node] = {}
    for dev in solid.node.fields.get("device", []) or []:
        if isinstance(dev, Node) and dev.type_name in ("LinearMotor", "PositionSensor", "Brake"):
            found.setdefault(dev.type_name, dev)
    motor = found.get("LinearMotor")
    rec = TrackRec(solid=solid, motor=motor, sensor=found.get("PositionSensor"), brake=found.get("Brake"))
    if motor is not None:
        check_maxima(motor, sim.warn)
        _read_motor(rec, sim, _MOTOR_FIELDS)
        rec.load_acceleration = rec.acceleration
        rec.target_velocity = rec.max_velocity  # Webots' initial hold: the current position at full speed
    return rec


#: the LinearMotor fields a Track reads, at load and again after a supervisor's edit (as a joint's motor does,
#: physics/motor_edits.py: from the next step, the getters too)
_MOTOR_FIELDS = ("maxVelocity", "maxForce", "acceleration", "controlPID", "minPosition", "maxPosition", "multiplier")


def _read_motor(rec: TrackRec, sim: Simulation, names: Any) -> None:
    """Read the motor fields ``names`` into ``rec``, as a joint motor does (:func:`.motor_api.read_motor_fields`)."""
    assert rec.motor is not None
    read_motor_fields(rec, rec.motor, names, str(rec.motor.fields.get("name", "linear motor")), sim.warn)


class _Tracks:
    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.recs = [_make(s, sim) for s in sim.solids if s.node.type_name == "Track"]
        self.stamps = stamps_of(sim)
        for rec in self.recs:
            robot = rec.solid.robot
            if robot is not None:
                for node, default, api in ((rec.motor, "linear motor", TrackMotor),
                                           (rec.sensor, "position sensor", TrackPositionSensor),
                                           (rec.brake, "brake", TrackBrake)):
                    if node is not None:
                        name = str(node.fields.get("name", default))
                        handle = _Handle(rec, name, api, node)
                        if robot.devices.setdefault(name, handle) is handle:  # a name taken stays the first's
                            rec.devices[node.type_name] = handle
            sim.set_contact_modifier(rec.solid, self._modifier(rec))
        sim.pre_step_hooks.append(self.control)
        sim.reset_hooks.append(self.reset)

    def reset(self) -> None:
        """simulationReset: the belt back at 0, the motor holding it there (Webots resets Track positions)."""
        for rec in self.recs:
            if rec.motor is not None:  # the load values the reset restored in the fields a supervisor edited
                edited = {name for name in _MOTOR_FIELDS if self.stamps.get((id(rec.motor), name), 0)}
                _read_motor(rec, self.sim, edited)
            rec.position = rec.velocity = rec.current_velocity = rec.integral = rec.prev_error = 0.0
            rec.target_position = 0.0
            rec.target_velocity = rec.max_velocity
            rec.available = rec.max_force
            rec.force_mode = False
            rec.force = 0.0
            # setAcceleration replaced the motor's acceleration field, which a reset restores (webots-on-ode.md
            # §5.2; the motors' acceleration is among what webots-devices.md §11.3 lists as reset), as for joints
            rec.acceleration = rec.load_acceleration

    def control(self, dt: float) -> None:
        for rec in self.recs:
            self.follow(rec)
            rec.control(dt)

    def follow(self, rec: TrackRec) -> None:
        """Read the motor fields a supervisor wrote since they were last read (or a reset restored)."""
        changed = written_since(self.stamps, rec.motor, _MOTOR_FIELDS, rec.stamps)
        if rec.motor is None or not changed:
            return
        check_maxima(rec.motor, self.sim.warn)  # a negative maximum, as at load
        _read_motor(rec, self.sim, changed)

    def _modifier(self, rec: TrackRec) -> Any:
        sim = self.sim
        own = {g.ptr for g in rec.solid.geoms}

        def modify(contacts: Any, indices: list[int], o1: int) -> None:
            v = rec.velocity
            if v == 0.0:
                return
            # the gravity of this step: a supervisor may have written WorldInfo's (physics/world_edits.py)
            up, g_up = gravity_axis(sim.gravity)
            track_first = o1 in own
            pose = sim.solid_world_pose(rec.solid)
            z_axis = pose.rotate((0.0, 0.0, 1.0))
            x_axis = pose.rotate((1.0, 0.0, 0.0))
            has_body = rec.solid.body is not None
            for i in indices:
                c = contacts[i]
                raw = (c.geom.normal[0], c.geom.normal[1], c.geom.normal[2])
                n = raw if track_first else m3.scale(raw, -1.0)
                cos = max(-1.0, min(1.0, m3.dot(n, z_axis)))
                inv = cos < 0
                sign = -g_up if (raw[up] < 0) == inv else g_up
                sign *= abs(math.acos(cos) - math.pi / 2) / (math.pi / 2)
                c.surface.mode |= ode.dContactMotion1
                c.surface.motion1 = v * sign
                if has_body:
                    c.surface.mode |= ode.dContactFDir1
                    d = m3.scale(x_axis, -1.0) if inv else x_axis
                    c.fdir1[0], c.fdir1[1], c.fdir1[2] = d

        return modify


def gravity_axis(gravity: m3.Vec3) -> tuple[int, float]:
    """The world axis along which gravity mostly points and the unit gravity vector's component on it: the
    axis whose normal component and gravity sign Webots' belt rule reads (§7.2, "the dominant gravity axis is
    used"), so a NUE or EUN world (gravity along −y) moves its belts as an ENU one does. Without gravity: z
    pointing down, as in an ENU world (the reference does not say; a belt still moves what lies on it)."""
    g_norm = m3.norm(gravity)
    if g_norm == 0.0:
        return 2, -1.0
    axis = max(range(3), key=lambda i: abs(gravity[i]))
    return axis, gravity[axis] / g_norm


class _Handle:
    """A Track device as listed among its robot's devices."""

    def __init__(self, track: TrackRec, name: str, api: type[Device], node: Node) -> None:
        self.track = track
        self.name = name
        self.api_class = api
        self.node = node


def _sibling(device: Device, type_name: str) -> Any:
    """The handle of another device of the same Track (its motor, position sensor or brake), or None."""
    handle = device._record.track.devices.get(type_name)
    return device._robot._device_for(handle) if handle is not None else None


def install(sim: Simulation) -> list[TrackRec]:
    """Make the simulation's Tracks move their belts (idempotent); their motor and sensor become devices."""
    hook = sim.extensions.get("tracks")
    if hook is None:
        hook = sim.extensions["tracks"] = _Tracks(sim)
    return hook.recs


class TrackMotor(KinematicMotor):
    """The LinearMotor of a Track: Webots' Motor API driving the belt."""

    _record: _Handle

    def _state(self) -> TrackRec:
        rec = self._record.track
        # an edit of the motor's fields acts on the commands and getters from now on, as on a joint's motor
        self._robot._sim.extensions["tracks"].follow(rec)
        return rec

    def _position_set(self) -> None:
        self._state().force_mode = False

    def _sibling(self, kind: str) -> Any:
        return _sibling(self, kind)

    @buffered()
    def setForce(self, force: Any) -> None:
        f = as_float(force, "Motor.setForce")
        if not refuse_nan("setForce()/setTorque", self._name, f):
            t = self._state()
            t.force = clamp_force(self._name, f * t.multiplier, t.available)
            t.force_mode = True

    @buffered()
    def setTorque(self, torque: Any) -> None:
        self.setForce(torque)

    def getType(self) -> int:
        return self.LINEAR


class TrackPositionSensor(PositionSensor):
    """The PositionSensor of a Track: the belt travel (m), with its noise and resolution (§7.2)."""

    _record: _Handle  # type: ignore[assignment]
    _webots_class = PositionSensor

    def _read(self) -> None:
        node = self._record.node
        noise = float(node.fields.get("noise", 0.0))
        resolution = float(node.fields.get("resolution", -1.0))
        self._value = self._robot._sim.sensor_noise(self._record.track.position, noise, resolution)

    def getType(self) -> int:
        return self.LINEAR

    def getMotor(self) -> Any:
        return _sibling(self, "LinearMotor")

    def getBrake(self) -> Any:
        return _sibling(self, "Brake")


class TrackBrake(Brake):
    """The Brake of a Track: its damping constant slows the belt in force control,
    ``v = (F − c·v_prev)·dt / m`` (§7.2)."""

    _record: _Handle  # type: ignore[assignment]
    _webots_class = Brake

    @buffered()
    def setDampingConstant(self, c: Any) -> None:
        value = as_float(c, "Brake.setDampingConstant")
        if not finite(value) or value < 0:
            warn(f"'{self._name}': invalid damping constant {value}")
            return
        self._record.track.damping = value

    def getType(self) -> int:
        return self.LINEAR

    def getMotor(self) -> Any:
        return _sibling(self, "LinearMotor")

    def getPositionSensor(self) -> Any:
        return _sibling(self, "PositionSensor")

