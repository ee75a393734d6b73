"""The joint devices of the controller API: ``PositionSensor`` and ``Motor`` (RotationalMotor and LinearMotor).

Moved out of :mod:`dualtwin.webots.devices` so the joint devices (motors, their sensors and brakes) and the
solid-state sensors each have a module; :mod:`dualtwin.webots.controller` re-exports them under their Webots API
names.
"""

from __future__ import annotations

import math
from typing import Any

from dualtwin.webots.api_args import as_float, finite, warn
from dualtwin.webots.device_base import Device, SampledDevice
from dualtwin.webots.physics import MotorRec, PositionSensorRec

__all__ = ["Motor", "PositionSensor"]

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

    def getValue(self) -> float:
        return getattr(self, "_value", math.nan)

    def getType(self) -> int:
        return self.LINEAR if self._record.joint.kind == "slider" else self.ROTATIONAL

    def getMotor(self) -> Motor | None:
        rec = self._record
        motor = rec.joint.motors[rec.axis_index]
        return self._robot._device_for(motor) if motor is not None else None  # type: ignore[return-value]


class Motor(Device):
    """RotationalMotor / LinearMotor (§5.2)."""

    ROTATIONAL = 0
    LINEAR = 1

    _record: MotorRec

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

    def setPosition(self, position: Any) -> None:
        position = as_float(position, "Motor.setPosition")
        if not _finite(position):
            _warn(f"Motor.setPosition() called with an invalid value (NaN) on '{self._name}'")
            return
        for motor in self._coupled():
            motor._set_position(position)

    def _set_position(self, position: float) -> None:
        rec = self._record
        p = position * rec.multiplier
        if rec.min_position != rec.max_position and math.isfinite(p):
            clamped = min(max(p, rec.min_position), rec.max_position)
            if clamped != p:
                _warn(f"'{self._name}': requested position {p} outside [minPosition, maxPosition]")
            p = clamped
        rec.target_position = p
        rec.torque_mode = False
        self._changed()

    def setVelocity(self, velocity: Any) -> None:
        velocity = as_float(velocity, "Motor.setVelocity")
        if not _finite(velocity):
            _warn(f"Motor.setVelocity() called with an invalid value (NaN) on '{self._name}'")
            return
        for motor in self._coupled():
            motor._set_velocity(velocity)

    def _set_velocity(self, velocity: float) -> None:
        rec = self._record
        v = velocity * rec.multiplier
        if abs(v) > rec.max_velocity:
            _warn(f"'{self._name}': requested velocity {v} exceeds maxVelocity {rec.max_velocity}")
            v = math.copysign(rec.max_velocity, v)
        rec.target_velocity = v
        self._changed()

    def setAcceleration(self, acceleration: Any) -> None:
        acceleration = as_float(acceleration, "Motor.setAcceleration")
        if _finite(acceleration):
            self._record.acceleration = float(acceleration)

    def setAvailableForce(self, force: Any) -> None:
        rec = self._record
        force = as_float(force, "Motor.setAvailableForce")
        if not _finite(force) or force < 0:
            _warn(f"'{self._name}': invalid available force/torque {force}")
            return
        rec.available = min(float(force), rec.max_force)
        self._changed()

    setAvailableTorque = setAvailableForce

    def setForce(self, force: Any) -> None:
        force = as_float(force, "Motor.setForce")
        if not _finite(force):
            _warn(f"Motor.setForce()/setTorque() called with an invalid value (NaN) on '{self._name}'")
            return
        for motor in self._coupled():
            motor._set_force(force)

    def _set_force(self, force: float) -> None:
        rec = self._record
        f = force * rec.multiplier
        rec.raw_torque = max(-rec.available, min(rec.available, f))
        if not rec.torque_mode:
            rec.torque_mode = True
            rec.torque_params_set = False
        self._changed()

    setTorque = setForce

    def setControlPID(self, p: Any, i: Any, d: Any) -> None:
        rec = self._record
        gains = [as_float(v, "Motor.setControlPID") for v in (p, i, d)]
        if not _finite(*gains):
            _warn(f"Motor.setControlPID() called with NaN on '{self._name}'; ignored")
            return
        rec.kp, rec.ki, rec.kd = gains
        rec.integral = 0.0
        rec.prev_error = 0.0

    def getTargetPosition(self) -> float:
        return self._record.target_position

    def getMinPosition(self) -> float:
        return self._record.min_position

    def getMaxPosition(self) -> float:
        return self._record.max_position

    def getVelocity(self) -> float:
        return self._record.target_velocity

    def getMaxVelocity(self) -> float:
        return self._record.max_velocity

    def getAcceleration(self) -> float:
        return self._record.acceleration

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
