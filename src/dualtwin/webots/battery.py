"""The Robot battery: the energy in ``Robot.battery`` drained by the CPU and the motors, as Webots documents.

``battery`` is ``[current J, maximum J, recharge W]``. Every physics step of ``dt`` seconds takes
``dt · (cpuConsumption + Σ consumptionFactor · |output|)`` joules, the sum running over the robot's motors with
``|output|`` the torque (N·m) or force (N) the motor applies along its axis in that step (the joint's ODE
feedback projected on the axis, which is the motor row plus any stop; the raw command in torque mode). The
level never goes below 0, and the first value of the ``battery`` field is updated as Webots does.

The controller API (``Robot.batterySensorEnable``/``GetValue``...) reads it through :func:`battery_sensor`,
a sensor sampled like every Webots sensor: NaN before its first sample, or when the robot has no ``battery``.

What differs: recharging at a ``Charger`` is not simulated (the recharge speed is never used), and an empty
battery does not stop the motors or end the controller as it does in Webots (a warning says so, once).
"""

from __future__ import annotations

import ctypes
import math
import weakref
from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import ode
from dualtwin.webots.api_args import warn
from dualtwin.webots.device_base import DeviceBinding, DeviceHost, SampledDevice
from dualtwin.webots.physics import MotorRec, RobotRec, Simulation

__all__ = ["Battery", "BatterySensor", "battery_sensor", "install"]


@dataclass(eq=False)
class Battery:
    """One robot's battery."""

    robot: RobotRec
    motors: list[MotorRec]
    feedback: dict[int, Any] = field(default_factory=dict)  # joint ptr -> the dJointFeedback we installed
    empty_reported: bool = False

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
    """Per-simulation hook draining every robot's battery after each step."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.batteries: dict[int, Battery] = {}
        for robot in sim.robots:
            motors = [
                m for m in sim.motors
                if (m.joint.child is not None and m.joint.child.robot is robot)
                or (m.joint.parent is not None and m.joint.parent.robot is robot)
            ]  # fmt: skip
            self.batteries[id(robot)] = Battery(robot, motors)
        self._active = [b for b in self.batteries.values() if b.values]
        for battery in self._active:
            for motor in battery.motors:  # install feedback now so the first step already reports
                _motor_output(sim._lib, battery, motor)
        if self._active:
            sim.step_hooks.append(self.after_step)

    def after_step(self) -> None:
        lib = self.sim._lib
        dt = self.sim.dt
        for battery in self._active:
            fields = battery.robot.node.fields
            power = float(fields.get("cpuConsumption", 10.0))
            for motor in battery.motors:
                power += float(motor.node.fields.get("consumptionFactor", 10.0)) * _motor_output(lib, battery, motor)
            values = list(battery.values)
            values[0] = max(0.0, float(values[0]) - power * dt)
            fields["battery"] = values
            if values[0] == 0.0 and not battery.empty_reported:
                battery.empty_reported = True
                warn(
                    f"robot '{battery.robot.name}': battery empty; the Webots twin does not stop its motors or "
                    "its controller"
                )


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
