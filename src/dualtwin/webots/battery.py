"""The Robot battery and the Charger, as Webots documents them.

``Robot.battery`` is ``[current J, maximum J, recharge W]``. Every physics step of ``dt`` seconds takes
``dt · (cpuConsumption + Σ consumptionFactor · |output|)`` joules, the sum running over the robot's motors with
``|output|`` the torque (N·m) or force (N) the motor applies along its axis in that step (the joint's ODE
feedback projected on the axis, which is the motor row plus any stop; the raw command in torque mode). The
level never goes below 0, and the first value of the ``battery`` field is updated as Webots does.

When the level reaches 0 the robot is out of power. Webots' Robot documentation: "when the current energy
value reaches zero, the corresponding controller process terminates and the simulated robot stops all motion".
Here the controller's ``step`` returns -1 (it then ends as after any -1, within Webots' 1 s grace) and every
motor of the robot (its Track belts' and Propellers' too) holds velocity 0 with its full torque from that step on
(our reading of "stops all motion": Webots' wording does not say whether the motors brake or go limp).

A ``Charger`` is itself a battery: its ``battery`` field ``[current J, maximum J, charging W]`` gains
``charging · dt`` per step up to its maximum, as Webots documents ("it accumulates energy with time"). A robot
with a battery whose origin lies within ``radius`` of the charger's origin takes ``recharge · dt`` per step
(its own third value), at most what the charger holds and what its battery lacks; the charger loses what the
robot gains. Our reading where Webots' text is silent: the charger fills itself before it gives, each charger
serves the first such robot in world order (one robot at a time), and robots drain before chargers give. A
robot recharged after it ran out has power again, but its controller has ended: its motors keep holding still
until a controller the supervisor restarts (``Node.restartController``) commands them. The
charger's colour change (``emissiveColor``, ``gradual``) is visual and not drawn headless.

The controller API (``Robot.batterySensorEnable``/``GetValue``...) reads the level through
:func:`battery_sensor`, a sensor sampled like every Webots sensor: NaN before its first sample, or when the
robot has no ``battery``.
"""

from __future__ import annotations

import ctypes
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import ode
from dualtwin.webots.device_base import DeviceBinding, DeviceHost, SampledDevice
from dualtwin.webots.physics import MotorRec, RobotRec, Simulation, SolidRec

__all__ = ["Battery", "BatterySensor", "battery_sensor", "install"]


@dataclass(eq=False)
class Battery:
    """One robot's battery."""

    robot: RobotRec
    motors: list[MotorRec]
    feedback: dict[int, Any] = field(default_factory=dict)  # joint ptr -> the dJointFeedback we installed
    powered: bool = True  # False from the step the battery ran out until it holds energy again

    @property
    def values(self) -> list[float]:
        return self.robot.node.fields.get("battery", []) or []

    @property
    def energy(self) -> float:
        values = self.values
        return float(values[0]) if values else math.nan


def _motor_output(lib: Any, battery: Battery, motor: MotorRec) -> float:
    """|torque| or |force| the motor applied along its axis during the last step."""
    if motor.torque_mode:
        return abs(motor.raw_torque)
    joint = motor.joint
    if not joint.ptr or joint.kind not in ("hinge", "slider"):
        return 0.0
    fb_ptr = lib.dJointGetFeedback(joint.ptr)
    if not fb_ptr:
        fb = battery.feedback[joint.ptr] = ode.dJointFeedback()
        lib.dJointSetFeedback(joint.ptr, ctypes.byref(fb))
        return 0.0  # no feedback before the first step with it
    fb = ode.dJointFeedback.from_address(fb_ptr)
    axis = (ctypes.c_double * 4)()
    if joint.kind == "slider":
        lib.dJointGetSliderAxis(joint.ptr, axis)
        vec = (fb.f1[0], fb.f1[1], fb.f1[2])
    else:
        # ODE reports the torque about body 1's centre of mass: move it to the hinge anchor
        lib.dJointGetHingeAxis(joint.ptr, axis)
        anchor = (ctypes.c_double * 4)()
        lib.dJointGetHingeAnchor(joint.ptr, anchor)
        # feedback 1 belongs to the first body, or to the only one of a joint to the static world
        body = lib.dJointGetBody(joint.ptr, 0) or lib.dJointGetBody(joint.ptr, 1)
        if not body:
            return 0.0
        com = (ctypes.c_double * 3).from_address(lib.dBodyGetPosition(body))
        arm = (com[0] - anchor[0], com[1] - anchor[1], com[2] - anchor[2])
        f = fb.f1
        vec = (
            fb.t1[0] + arm[1] * f[2] - arm[2] * f[1],
            fb.t1[1] + arm[2] * f[0] - arm[0] * f[2],
            fb.t1[2] + arm[0] * f[1] - arm[1] * f[0],
        )
    return abs(vec[0] * axis[0] + vec[1] * axis[1] + vec[2] * axis[2])


class Batteries:
    """Per-simulation hook: after each step, drains every robot's battery, cuts the power of a robot whose battery
    ran out, and lets each Charger fill itself and recharge a robot in its radius (module docstring).

    Robots and chargers are looked up at every step (a few field reads), so a battery set by a supervisor, or a
    robot or charger it imports, takes part from the next step."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.batteries: dict[int, Battery] = {}
        #: called with the Robot node whose battery ran out (the runtime ends its controller), by runtime
        self.power_off_listeners: dict[int, Callable[[Any], None]] = {}
        self._charger_key: tuple[int, int] = (-1, 0)
        self._charger_list: list[SolidRec] = []
        for robot in sim.robots:
            battery = self.battery(robot)
            if battery.values:  # install the feedback now, so that the first step already reports
                for motor in battery.motors:
                    _motor_output(sim._lib, battery, motor)
        sim.step_hooks.append(self.after_step)

    def battery(self, robot: RobotRec) -> Battery:
        battery = self.batteries.get(id(robot))
        if battery is None or battery.robot is not robot:
            sim = self.sim
            motors = [
                m for m in sim.motors
                if (m.joint.child is not None and m.joint.child.robot is robot)
                or (m.joint.parent is not None and m.joint.parent.robot is robot)
            ]  # fmt: skip
            battery = self.batteries[id(robot)] = Battery(robot, motors)
        return battery

    def after_step(self) -> None:
        sim = self.sim
        lib = sim._lib
        dt = sim.dt
        charged: list[Battery] = []
        for robot in sim.robots:
            values = robot.node.fields.get("battery")
            if not values:
                continue
            battery = self.battery(robot)
            fields = robot.node.fields
            power = float(fields.get("cpuConsumption", 10.0))
            for motor in battery.motors:
                power += float(motor.node.fields.get("consumptionFactor", 10.0)) * _motor_output(lib, battery, motor)
            values = [float(v) for v in values]
            values[0] = max(0.0, values[0] - power * dt)
            fields["battery"] = values
            charged.append(battery)
            if values[0] > 0.0:
                battery.powered = True  # (again, after a reset or a charger: a controller restarted may drive)
            else:
                if battery.powered:
                    self._power_off(battery)
                _stop_motors(battery.motors)  # at every step without energy: what the ended controller sent last
                # (a command between its -1 and its exit) does not move the robot
                _stop_kinematic_motors(sim, battery.robot)
        chargers = self._chargers()
        if chargers:
            self._charge(chargers, charged, dt)

    def _power_off(self, battery: Battery) -> None:
        battery.powered = False
        for listener in list(self.power_off_listeners.values()):
            listener(battery.robot.node)

    def _chargers(self) -> list[SolidRec]:
        """The Charger solids, found again when the scene's solids change (a supervisor's import or removal)."""
        solids = self.sim.solids
        key = (len(solids), id(solids[-1]) if solids else 0)
        if key != self._charger_key:
            self._charger_key = key
            self._charger_list = [solid for solid in solids if solid.node.type_name == "Charger"]
        return self._charger_list

    def _charge(self, chargers: list[SolidRec], batteries: list[Battery], dt: float) -> None:
        sim = self.sim
        for solid in chargers:
            fields = solid.node.fields
            own = [float(v) for v in fields.get("battery") or []]
            if len(own) < 3:
                continue
            own[0] = min(own[1], own[0] + own[2] * dt) if own[0] < own[1] else own[0]
            here = sim.solid_world_pose(solid).t
            radius = float(fields.get("radius", 0.04))
            for battery in batteries:
                robot_values = battery.robot.node.fields["battery"]
                if len(robot_values) < 3:
                    continue
                there = sim.solid_world_pose(battery.robot.solid).t
                if math.dist(here, there) >= radius:
                    continue
                level, top, speed = (float(v) for v in robot_values[:3])
                gain = max(0.0, min(speed * dt, own[0], top - level))
                own[0] -= gain
                battery.robot.node.fields["battery"] = [level + gain, *robot_values[1:]]
                break  # one robot at a time
            fields["battery"] = [*own, *(fields.get("battery") or [])[3:]]


def _stop_motors(motors: list[MotorRec]) -> None:
    """Velocity 0 with the full torque: the motors of a robot out of power hold it still (module docstring)."""
    for motor in motors:
        motor.target_position = math.inf
        motor.target_velocity = 0.0
        motor.available = motor.max_force
        motor.torque_mode = False
        motor.raw_torque = 0.0


def _stop_kinematic_motors(sim: Simulation, robot: RobotRec) -> None:
    """The robot's Track belts and Propellers stop too ("stops all motion"): their motors' controllers (their
    modules' records, found through the simulation's hooks) get velocity 0 with the full force or torque."""
    for key in ("tracks", "propellers"):
        for rec in getattr(sim.extensions.get(key), "recs", ()):
            place = rec.solid if key == "tracks" else rec.site
            if rec.motor is None or place.robot is not robot:
                continue
            rec.target_position, rec.target_velocity = math.inf, 0.0
            rec.available = rec.max_force  # a Propeller's maxTorque under the Motor API's shared name
            if key == "tracks":
                rec.force_mode, rec.force = False, 0.0


def install(sim: Simulation) -> Batteries:
    """The simulation's battery hook (created once)."""
    hook = sim.extensions.get("batteries")
    if hook is None:
        hook = sim.extensions["batteries"] = Batteries(sim)
    return hook  # type: ignore[no-any-return]


class BatterySensor(SampledDevice):
    """A robot's battery level sensor (J), sampled like every Webots sensor."""

    def _invalidate(self) -> None:
        self.value = math.nan

    def _read(self) -> None:
        battery = install(self._robot._sim).batteries.get(id(self._record))
        self.value = battery.energy if battery is not None else math.nan


# kept outside the Robot object: Webots' Robot has no such attribute for a user subclass to collide with
_SENSORS: weakref.WeakKeyDictionary[Any, BatterySensor] = weakref.WeakKeyDictionary()


def battery_sensor(robot: DeviceHost) -> BatterySensor:
    """The battery sensor of the controller ``robot`` (one per Robot object), for ``Robot.batterySensor*``:
    ``enable(ms)``, ``disable()``, ``getSamplingPeriod()`` and ``value`` (J)."""
    sensor = _SENSORS.get(robot)
    if sensor is None:
        install(robot._sim)
        sensor = _SENSORS[robot] = BatterySensor(DeviceBinding(robot, "battery", robot._rec, 0))
        sensor._invalidate()
    return sensor
