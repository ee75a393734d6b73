"""Propeller: thrust and torque on the closest upper Solid's body, from the propeller motor's speed.

Webots (``WbPropeller``) does not simulate the propeller as a body: its RotationalMotor runs a kinematic
controller every step. In velocity mode (``setPosition(inf)``) the speed ω ramps toward the target with the
motor's ``acceleration``, or with the available torque (``maxTorque`` unless ``setAvailableTorque`` lowered it;
read as rad/s²) when the acceleration is -1 or larger than that; in position mode the angle moves toward the target at a speed ramping the same way toward
``|velocity|`` (ω ≥ 0 there), and ω is 0 once it is reached (the same controller as kinematic joints'). Each step with ω ≠ 0, with ``V`` the velocity of the centre of thrust along the shaft axis,

    T = t1·ω·|ω| − t2·|ω|·V        Q = q1·ω·|ω| − q2·|ω|·V   (Q clamped to ±maxTorque)

the force ``T·a`` is applied at the centre of thrust and the torque ``−Q·a`` to the body (``a`` = the shaft axis
in the world), which is woken up. Webots projects V on the shaft axis expressed in the propeller's *parent
frame* (not rotated to the world), a quirk reproduced here. The helix Solids are visual and not simulated.
The body is the one that carries the closest upper Solid (its own, or, for a Solid without Physics, its nearest
ancestor's). Without a body upstream there is no effect (and a build warning, as in Webots). A supervisor's edit of
the Propeller's shaftAxis, centerOfThrust, thrustConstants or torqueConstants, or of its motor's fields, acts from
the next step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import warn
from dualtwin.webots.fixed_link import body_of
from dualtwin.webots.kinematic_motor import KinematicMotor
from dualtwin.webots.motor_api import check_maxima, read_motor_fields
from dualtwin.webots.motor_law import kinematic_motion
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import AttachmentRec, Simulation
from dualtwin.webots.physics.edit_stamps import stamps_of, written_since

__all__ = ["PropellerMotor", "PropellerRec", "install"]


def _vec(value: Any, default: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(float(v) for v in value) if value is not None else default


@dataclass(eq=False)
class PropellerRec:
    """A Propeller and the state of its motor's kinematic controller."""

    site: AttachmentRec
    motor: Node | None
    name: str
    axis: m3.Vec3  # unit shaft axis in the parent frame (the closest upper Pose)
    center: m3.Vec3  # centre of thrust in the parent frame
    t1: float
    t2: float
    q1: float
    q2: float
    max_velocity: float
    max_force: float  # the motor's maxTorque, under the name every motor's record uses (motor_api)
    acceleration: float
    multiplier: float
    min_position: float = 0.0
    max_position: float = 0.0
    available: float = 0.0  # the available torque (setAvailableTorque), at most maxTorque
    target_position: float = 0.0
    target_velocity: float = 0.0
    omega: float = 0.0  # current speed (rad/s)
    angle: float = 0.0
    thrust: float = 0.0  # last applied values, for inspection
    torque: float = 0.0
    load_acceleration: float = field(init=False, default=-1.0)  # the acceleration field as loaded
    #: the write stamps (physics/edit_stamps.py) of the propeller's and its motor's fields when last read
    stamps: dict[Any, int] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.load_acceleration = self.acceleration  # the motor's acceleration field as loaded
        self.initial()

    def initial(self) -> None:
        """Webots' motor state at load and reset (webots-on-ode.md §5.1): holding the current angle with target
        velocity maxVelocity and available torque maxTorque; at rest."""
        self.omega = self.angle = self.target_position = 0.0
        self.target_velocity = self.max_velocity
        self.available = self.max_force

    @property
    def api_class(self) -> type[PropellerMotor]:
        return PropellerMotor

    def control(self, dt: float) -> None:
        """One step of Webots' kinematic motor controller: updates ω and the angle (ω is a speed magnitude in
        position mode, as in Webots)."""
        self.angle, omega = kinematic_motion(
            position=self.angle, current_velocity=self.omega, target_position=self.target_position,
            target_velocity=self.target_velocity, available=self.available, acceleration=self.acceleration, dt=dt)
        self.omega = omega if math.isinf(self.target_position) else abs(omega)


def _make(site: AttachmentRec, sim: Simulation) -> PropellerRec:
    motor = site.node.fields.get("device")
    motor = motor if isinstance(motor, Node) and motor.type_name == "RotationalMotor" else None
    if motor is not None:
        check_maxima(motor, sim.warn)
    name = str(motor.fields.get("name", "rotational motor")) if motor is not None else "rotational motor"
    rec = PropellerRec(site=site, motor=motor, name=name, axis=(1.0, 0.0, 0.0), center=(0.0, 0.0, 0.0), t1=1.0,
                       t2=0.0, q1=1.0, q2=0.0, max_velocity=10.0, max_force=10.0, acceleration=-1.0, multiplier=1.0)
    _read(rec, sim, PROPELLER_FIELDS, MOTOR_FIELDS)
    rec.load_acceleration = rec.acceleration
    rec.initial()
    return rec


#: the Propeller's and its motor's fields, read at load and again after a supervisor's edit (from the next step;
#: the motor's commands and getters at once, as a joint motor's, physics/motor_edits.py)
PROPELLER_FIELDS = ("shaftAxis", "centerOfThrust", "thrustConstants", "torqueConstants")
MOTOR_FIELDS = ("maxVelocity", "maxTorque", "acceleration", "minPosition", "maxPosition", "multiplier")


def _read(rec: PropellerRec, sim: Simulation, names: Any, motor_names: Any) -> None:
    """Read the Propeller fields ``names`` and the motor fields ``motor_names`` into ``rec``: a target beyond new
    limits (velocity, position) is clipped into them, a multiplier of 0 refused with the load's warning."""
    f = rec.site.node.fields
    if "shaftAxis" in names:
        axis = _vec(f.get("shaftAxis"), (1.0, 0.0, 0.0))
        if m3.norm(axis) == 0.0:
            warn("Propeller: a zero shaftAxis is replaced by (0, 1, 0)")
            axis = (0.0, 1.0, 0.0)
        rec.axis = m3.normalized(axis)  # type: ignore[arg-type]
    if "centerOfThrust" in names:
        rec.center = _vec(f.get("centerOfThrust"), (0.0, 0.0, 0.0))  # type: ignore[assignment]
    if "thrustConstants" in names:
        rec.t1, rec.t2 = _vec(f.get("thrustConstants"), (1.0, 0.0))
    if "torqueConstants" in names:
        rec.q1, rec.q2 = _vec(f.get("torqueConstants"), (1.0, 0.0))
    if rec.motor is None:
        return
    read_motor_fields(rec, rec.motor, motor_names, rec.name, sim.warn)


class _Propellers:
    """Per-simulation pre-physics hook applying every propeller's thrust and torque."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.recs = [_make(site, sim) for site in sim.attachments if site.node.type_name == "Propeller"]
        self.stamps = stamps_of(sim)
        for rec in self.recs:
            robot = rec.site.robot
            if rec.motor is not None and robot is not None:
                robot.devices.setdefault(rec.name, rec)
            if body_of(rec.site.solid) is None:  # webots-devices.md §8: "No Physics upstream ⇒ warning, no effect"
                sim.warn(f"Propeller '{rec.name}': no Solid with Physics above it; it has no effect")
        sim.pre_step_hooks.append(self.apply)
        sim.reset_hooks.append(self.reset)

    def follow(self, rec: PropellerRec) -> None:
        """Read the fields of the propeller and its motor written since they were last read (or restored)."""
        motor = rec.motor
        changed = written_since(self.stamps, rec.site.node, PROPELLER_FIELDS, rec.stamps)
        motor_changed = written_since(self.stamps, motor, MOTOR_FIELDS, rec.stamps)
        if not (changed or motor_changed):
            return
        if motor is not None:
            check_maxima(motor, self.sim.warn)  # a negative maximum, as at load
        _read(rec, self.sim, changed, motor_changed)

    def reset(self) -> None:
        for rec in self.recs:
            # the load values the reset restored in the fields a supervisor edited
            stamps = self.stamps
            _read(rec, self.sim, {n for n in PROPELLER_FIELDS if stamps.get((id(rec.site.node), n), 0)},
                  {n for n in MOTOR_FIELDS if rec.motor is not None and stamps.get((id(rec.motor), n), 0)})
            # setAcceleration replaced the motor's acceleration field, which a reset restores (webots-on-ode.md
            # §5.2, webots-devices.md §11.3), as for joint motors
            rec.acceleration = rec.load_acceleration
            rec.initial()

    def apply(self, dt: float) -> None:
        sim = self.sim
        lib = sim._lib
        for rec in self.recs:
            self.follow(rec)
            rec.control(dt)
            rec.thrust = rec.torque = 0.0
            solid = rec.site.solid
            # the closest upper Solid's merged body: a Solid without Physics inside a body is carried by its
            # nearest ancestor's (the build warns only when no Solid upstream has Physics, webots-devices.md §8)
            body = body_of(solid)
            if rec.omega == 0.0 or body is None or solid is None:
                continue
            frame = sim.solid_world_pose(solid) * rec.site.frame_rel
            a_world = frame.rotate(rec.axis)
            # (upperPose·centerOfThrust: the upper Pose's matrix holds the scale of the Transforms above it, on-ODE
            # §3.1, so below a scaled Transform the centre of thrust is as far from the frame as the scale says)
            p_world = frame.apply(m3.scale(rec.center, rec.site.scale))
            # velocity of the centre of thrust: v + w × (p − CoM)
            w = (body.avel[0], body.avel[1], body.avel[2])
            r = m3.sub(p_world, (body.pos[0], body.pos[1], body.pos[2]))
            v = m3.add((body.lvel[0], body.lvel[1], body.lvel[2]), m3.cross(w, r))
            speed = m3.dot(v, rec.axis)  # Webots' quirk: the local axis, not rotated to the world
            om = rec.omega
            thrust = rec.t1 * om * abs(om) - rec.t2 * abs(om) * speed
            torque = rec.q1 * om * abs(om) - rec.q2 * abs(om) * speed
            torque = max(-rec.max_force, min(rec.max_force, torque))
            rec.thrust, rec.torque = thrust, torque
            f = m3.scale(a_world, thrust)
            lib.dBodyAddForceAtPos(body.ptr, f[0], f[1], f[2], p_world[0], p_world[1], p_world[2])
            q = m3.scale(a_world, -torque)
            lib.dBodyAddTorque(body.ptr, q[0], q[1], q[2])
            lib.dBodyEnable(body.ptr)


def install(sim: Simulation) -> list[PropellerRec]:
    """Make the simulation's propellers act (idempotent); their motors become robot devices."""
    hook = sim.extensions.get("propellers")
    if hook is None:
        hook = sim.extensions["propellers"] = _Propellers(sim)
    return hook.recs


class PropellerMotor(KinematicMotor):
    """The RotationalMotor of a Propeller: Webots' Motor API over the kinematic controller."""

    ROTATIONAL = 0
    _record: PropellerRec

    def _state(self) -> PropellerRec:
        # an edit of the motor's fields acts on the commands and getters from now on, as on a joint's motor
        self._robot._sim.extensions["propellers"].follow(self._record)
        return self._record

    def getType(self) -> int:
        return self.ROTATIONAL
