"""The joint devices of the controller API: ``PositionSensor`` and ``Motor`` (RotationalMotor and LinearMotor).

Moved out of :mod:`dualtwin.webots.devices` so the joint devices (motors, their sensors and brakes) and the
solid-state sensors each have a module; :mod:`dualtwin.webots.controller` re-exports them under their Webots API
names.
"""

from __future__ import annotations

import ctypes
import math
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import motor_api, ode
from dualtwin.webots.api_args import as_float, finite, warn
from dualtwin.webots.device_base import Device, SampledDevice, api_property
from dualtwin.webots.physics import BrakeRec, MotorRec, PositionSensorRec
from dualtwin.webots.step_hints import buffered, command_value, step_value

__all__ = ["Brake", "Motor", "PositionSensor"]

_warn = warn
_finite = finite

_Sampled = SampledDevice


class PositionSensor(_Sampled):
    """Joint position sensor (§5.4): NaN until the first sample."""

    ROTATIONAL = 0
    LINEAR = 1

    _record: PositionSensorRec

    def _invalidate(self) -> None:
        self._value = math.nan

    def _read(self) -> None:
        rec = self._record
        value = rec.joint.positions[rec.axis_index]
        self._value = self._robot._sim.sensor_noise(value, rec.noise, rec.resolution)

    @step_value
    def getValue(self) -> float:
        self._check_enabled("wb_position_sensor_get_value", "wb_position_sensor_enable")
        return getattr(self, "_value", math.nan)

    def getType(self) -> int:
        return self.LINEAR if self._record.joint.kind == "slider" else self.ROTATIONAL

    def getMotor(self) -> Motor | None:
        rec = self._record
        motor = rec.joint.motors[rec.axis_index]
        return self._robot._device_for(motor) if motor is not None else None  # type: ignore[return-value]

    def getBrake(self) -> Brake | None:
        rec = self._record
        brake = rec.joint.brakes[rec.axis_index]
        return self._robot._device_for(brake) if brake is not None else None  # type: ignore[return-value]

    brake = api_property("getBrake")
    motor = api_property("getMotor")
    value = api_property("getValue")
    type = api_property("getType")


class Brake(Device):
    """A joint axis' Brake: ``setDampingConstant(c)`` adds ``c`` (N·m·s/rad or N·s/m) to the axis'
    dampingConstant, acting through the same implicit damper row from the next step (§4.5)."""

    ROTATIONAL = 0
    LINEAR = 1

    _record: BrakeRec

    @buffered()
    def setDampingConstant(self, c: Any) -> None:
        value = as_float(c, "Brake.setDampingConstant")
        if not _finite(value) or value < 0:
            _warn(f"'{self._name}': invalid damping constant {value}")
            return
        rec = self._record
        rec.damping = value
        sim = self._robot._sim
        sim.rebuild_springs(rec.joint)
        sim.wake(rec.joint)

    def getType(self) -> int:
        return self.LINEAR if self._record.joint.kind == "slider" else self.ROTATIONAL

    def getMotor(self) -> Motor | None:
        rec = self._record
        motor = rec.joint.motors[rec.axis_index]
        return self._robot._device_for(motor) if motor is not None else None  # type: ignore[return-value]

    def getPositionSensor(self) -> PositionSensor | None:
        rec = self._record
        sensor = rec.joint.sensors[rec.axis_index]
        return self._robot._device_for(sensor) if sensor is not None else None  # type: ignore[return-value]

    motor = api_property("getMotor")
    position_sensor = api_property("getPositionSensor")
    type = api_property("getType")
    dampingConstant = api_property(None, "setDampingConstant")


class _Feedback(_Sampled):
    """The sampled torque/force feedback of a Motor: what its ODE joint applied to the endPoint along the motor's
    axis over the last step (ODE's joint feedback: torque about the anchor projected on the axis — the hinge's,
    or the Hinge2 axis the motor drives — or force along the slider axis), in the sense a setTorque/setForce
    command would have; in torque/force control, the torque/force commanded. NaN until the first sample."""

    def __init__(self, motor: Motor) -> None:
        self._motor = motor
        super().__init__(motor._binding())
        self._value = math.nan
        self._buffer: ode.dJointFeedback | None = None

    def enable(self, samplingPeriod: Any) -> None:
        rec: MotorRec = self._record
        joint = rec.joint
        if self._buffer is None and joint.ptr and joint.kind in ("hinge", "slider", "hinge2"):
            self._buffer = ode.dJointFeedback()
            self._robot._sim._lib.dJointSetFeedback(joint.ptr, ctypes.byref(self._buffer))
        super().enable(samplingPeriod)

    def _invalidate(self) -> None:
        self._value = math.nan

    def _read(self) -> None:
        rec: MotorRec = self._record
        if rec.torque_mode:
            self._value = rec.raw_torque
            return
        fb, joint = self._buffer, rec.joint
        if fb is None or joint.child_body is None:
            self._value = 0.0
            return
        sim = self._robot._sim
        frame = sim.solid_world_pose(joint.parent) * joint.frame_rel if joint.parent is not None else joint.frame_rel
        if joint.kind == "hinge2":
            # both Hinge2 positions grow as the endPoint turns about ODE's (world) axis 1 or 2 (physics/joints.py)
            out = (ctypes.c_double * 4)()
            lib = sim._lib
            (lib.dJointGetHinge2Axis1 if rec.axis_index == 0 else lib.dJointGetHinge2Axis2)(joint.ptr, out)
            axis = m3.normalized((out[0], out[1], out[2]))
        else:
            axis = m3.normalized(frame.rotate(joint.axis_local[0]))
        # the endPoint is ODE's second body, or its first one when the joint is reversed (static parent)
        f, t = (fb.f1, fb.t1) if joint.reverse else (fb.f2, fb.t2)
        force = (f[0], f[1], f[2])
        if joint.kind == "slider":
            self._value = m3.dot(force, axis)
            return
        anchor = frame.apply(joint.anchor_local)
        com = tuple(joint.child_body.pos[i] for i in range(3))
        torque = m3.add((t[0], t[1], t[2]), m3.cross(m3.sub(com, anchor), force))
        self._value = m3.dot(torque, axis)


class Motor(Device):
    """RotationalMotor / LinearMotor (§5.2)."""

    ROTATIONAL = 0
    LINEAR = 1

    _record: MotorRec
    #: (the simulation's target, the value this motor was given) of its last own setPosition / setVelocity
    _echo_position: tuple[float, float] | None = None
    _echo_velocity: tuple[float, float] | None = None

    def _changed(self) -> None:
        self._robot._sim.wake(self._record.joint)

    def _coupled(self) -> list[Motor]:
        """This motor and its coupled siblings: motors of the same robot named ``prefix::suffix`` (exactly two
        parts) with the same prefix. Webots relays setPosition, setVelocity and setForce/setTorque to them, each
        applying the raw value times its own multiplier within its own limits (§9)."""
        group: list[Motor] | None = getattr(self, "_group", None)
        if group is None:
            group = [self]
            parts = self._name.split("::")
            if len(parts) == 2:
                for rec in self._robot._rec.devices.values():
                    other = rec.name.split("::") if isinstance(rec, MotorRec) and rec is not self._record else []
                    if len(other) == 2 and other[0] == parts[0]:
                        group.append(self._robot._device_for(rec))  # type: ignore[arg-type]
                if len(group) == 1:
                    _warn(f"'{self._name}': no other motor is named '{parts[0]}::...'; nothing is coupled")
            self._group = group
        return group

    @buffered()
    def setPosition(self, position: Any) -> None:
        position = as_float(position, "Motor.setPosition")
        if motor_api.refuse_nan("setPosition", self._name, position):
            return
        for motor in self._coupled():
            motor._set_position(position)
            # libController's cache: the raw value for this motor, the multiplied one for its siblings (§9)
            motor._echo_position = (motor._record.target_position, position) if motor is self else None

    def _set_position(self, position: float) -> None:
        rec = self._record
        rec.target_position = motor_api.clamp_position(self._name, position * rec.multiplier, rec.min_position,
                                                       rec.max_position)
        rec.torque_mode = False
        self._changed()

    @buffered()
    def setVelocity(self, velocity: Any) -> None:
        velocity = as_float(velocity, "Motor.setVelocity")
        if motor_api.refuse_nan("setVelocity", self._name, velocity):
            return
        if motor_api.refuse_velocity(self._name, velocity, self._record.target_position):
            return
        for motor in self._coupled():
            motor._set_velocity(velocity)
            motor._echo_velocity = (motor._record.target_velocity, velocity) if motor is self else None

    def _set_velocity(self, velocity: float) -> None:
        rec = self._record
        rec.target_velocity = motor_api.clamp_velocity(self._name, velocity * rec.multiplier, rec.max_velocity)
        self._changed()

    @buffered()
    def setAcceleration(self, acceleration: Any) -> None:
        acceleration = as_float(acceleration, "Motor.setAcceleration")
        if not _finite(acceleration) or motor_api.refuse_acceleration(self._name, acceleration):
            return
        self._record.acceleration = float(acceleration)

    @buffered()
    def setAvailableForce(self, force: Any) -> None:
        rec = self._record
        force = as_float(force, "Motor.setAvailableForce")
        if motor_api.refuse_available(self._name, force):
            return
        rec.available = min(float(force), rec.max_force)
        self._changed()

    @buffered()
    def setAvailableTorque(self, torque: Any) -> None:
        self.setAvailableForce(torque)

    @buffered()
    def setForce(self, force: Any) -> None:
        force = as_float(force, "Motor.setForce")
        if motor_api.refuse_nan("setForce()/setTorque", self._name, force):
            return
        group = self._coupled()
        for motor in group:
            motor._set_force(force, report=len(group) == 1)

    def _set_force(self, force: float, report: bool = True) -> None:
        rec = self._record
        rec.raw_torque = motor_api.clamp_force(self._name, force * rec.multiplier, rec.available, report)
        if not rec.torque_mode:
            rec.torque_mode = True
            rec.torque_params_set = False
        self._changed()

    @buffered()
    def setTorque(self, torque: Any) -> None:
        self.setForce(torque)

    @buffered()
    def setControlPID(self, p: Any, i: Any, d: Any) -> None:
        rec = self._record
        gains = [as_float(v, "Motor.setControlPID") for v in (p, i, d)]
        if not _finite(*gains):
            _warn(f"Motor.setControlPID() called with NaN on '{self._name}'; ignored")
            return
        rec.kp, rec.ki, rec.kd = gains
        rec.integral = 0.0
        rec.prev_error = 0.0

    def _echo(self, value: float, echo: tuple[float, float] | None) -> float:
        """What Webots' libController caches for a target this motor was last given: the raw, unmultiplied
        value (§9), in its own units when its limits clipped it; the simulation's target otherwise (a sibling's
        relayed command, the initial state, a reset)."""
        return motor_api.echo(value, echo, self._record.multiplier)

    @command_value
    def getTargetPosition(self) -> float:
        return self._echo(self._record.target_position, self._echo_position)

    def getMinPosition(self) -> float:
        return self._record.min_position

    def getMaxPosition(self) -> float:
        return self._record.max_position

    @command_value
    def getVelocity(self) -> float:
        return self._echo(self._record.target_velocity, self._echo_velocity)

    def getMaxVelocity(self) -> float:
        return self._record.max_velocity

    @command_value
    def getAcceleration(self) -> float:
        return self._record.acceleration

    @command_value
    def getAvailableForce(self) -> float:
        return self._record.available

    getAvailableTorque = getAvailableForce

    def getMaxForce(self) -> float:
        return self._record.max_force

    getMaxTorque = getMaxForce

    def getMultiplier(self) -> float:
        return self._record.multiplier

    def getType(self) -> int:
        return self.ROTATIONAL if self._record.rotational else self.LINEAR

    def getPositionSensor(self) -> PositionSensor | None:
        sensor = self._record.sensor
        return self._robot._device_for(sensor) if sensor is not None else None  # type: ignore[return-value]

    def getBrake(self) -> Brake | None:
        brake = self._record.brake
        return self._robot._device_for(brake) if brake is not None else None  # type: ignore[return-value]

    # -- torque / force feedback (a sampled value of its own)

    def _feedback(self) -> _Feedback:
        fb: _Feedback | None = getattr(self, "_fb", None)
        if fb is None:
            fb = self._fb = _Feedback(self)
        return fb

    def enableForceFeedback(self, sampling_period: Any) -> None:
        self._feedback().enable(sampling_period)

    def disableForceFeedback(self) -> None:
        self._feedback().disable()

    def getForceFeedbackSamplingPeriod(self) -> int:
        return self._feedback().getSamplingPeriod()

    @step_value
    def getForceFeedback(self) -> float:
        feedback = self._feedback()
        feedback._check_enabled("wb_motor_get_force_feedback", "wb_motor_enable_force_feedback")
        return float(feedback._value)

    def enableTorqueFeedback(self, sampling_period: Any) -> None:
        self._feedback().enable(sampling_period)

    def disableTorqueFeedback(self) -> None:
        self._feedback().disable()

    def getTorqueFeedbackSamplingPeriod(self) -> int:
        return self._feedback().getSamplingPeriod()

    @step_value
    def getTorqueFeedback(self) -> float:
        feedback = self._feedback()
        feedback._check_enabled("wb_motor_get_torque_feedback", "wb_motor_enable_torque_feedback")
        return float(feedback._value)

    # -- Webots' properties

    brake = api_property("getBrake")
    position_sensor = api_property("getPositionSensor")
    max_position = api_property("getMaxPosition")
    min_position = api_property("getMinPosition")
    max_velocity = api_property("getMaxVelocity")
    max_force = api_property("getMaxForce")
    max_torque = api_property("getMaxTorque")
    multiplier = api_property("getMultiplier")
    force_feedback = api_property("getForceFeedback")
    torque_feedback = api_property("getTorqueFeedback")
    type = api_property("getType")
    force_feedback_sampling_period = api_property("getForceFeedbackSamplingPeriod", "enableForceFeedback")
    torque_feedback_sampling_period = api_property("getTorqueFeedbackSamplingPeriod", "enableTorqueFeedback")
    target_position = api_property("getTargetPosition", "setPosition")
    target_velocity = api_property("getVelocity", "setVelocity")
    target_acceleration = api_property("getAcceleration", "setAcceleration")
    available_force = api_property("getAvailableForce", "setAvailableForce")
    available_torque = api_property("getAvailableTorque", "setAvailableTorque")
    force = api_property(None, "setForce")
    torque = api_property(None, "setTorque")
