"""The Motor of a Track or a Propeller: a Webots ``Motor`` (the Python API has one Motor class for every motor
node) that drives a kinematic state (a belt's travel, a propeller's spin) instead of an ODE joint row.

It refuses, clips and echoes as a joint motor does (:mod:`.motor_api`). Where it differs from a joint motor:
there is no joint, so no torque/force feedback ("Force feedback is not available for Track motors",
webots-devices.md §7.2; the same is assumed for a Propeller's motor): the feedback can be enabled, as in Webots'
API, but it reads NaN (the value libController caches before any sample), and enabling it prints a warning. Its
energy consumption is 0 (a robot's battery counts only joint motors).
"""

from __future__ import annotations

import math
from typing import Any

from dualtwin.webots.api_args import as_float, as_int, error, finite, warn
from dualtwin.webots.joint_devices import Brake, Motor, PositionSensor
from dualtwin.webots.motor_api import (
    clamp_position,
    clamp_velocity,
    echo,
    refuse_acceleration,
    refuse_available,
    refuse_nan,
    refuse_velocity,
)
from dualtwin.webots.step_hints import buffered, command_value, step_value

__all__ = ["KinematicMotor"]


class KinematicMotor(Motor):
    """The state (``_state()``) holds ``multiplier``, ``min_position``, ``max_position``, ``max_velocity``,
    ``max_force`` (maxForce or maxTorque), ``available``, ``target_position``, ``target_velocity``,
    ``acceleration`` and ``kp``, ``ki``, ``kd``."""

    _record: Any  # type: ignore[assignment]  # the module's own record, not a joint's MotorRec
    _webots_class = Motor
    _feedback_period = 0

    def _state(self) -> Any:
        return self._record

    def _position_set(self) -> None:
        """What else a setPosition changes (a Track leaves force control)."""

    def _sibling(self, kind: str) -> PositionSensor | Brake | None:
        """This motor's PositionSensor or Brake, where its device holds one (a Track's)."""
        return None

    @buffered()
    def setPosition(self, position: Any) -> None:
        p = as_float(position, "Motor.setPosition")
        if refuse_nan("setPosition", self._name, p):
            return
        state = self._state()
        state.target_position = clamp_position(self._name, p * state.multiplier, state.min_position,
                                               state.max_position)
        self._echo_position = (state.target_position, p)
        self._position_set()

    @buffered()
    def setVelocity(self, velocity: Any) -> None:
        state = self._state()
        v = as_float(velocity, "Motor.setVelocity")
        if refuse_nan("setVelocity", self._name, v) or refuse_velocity(self._name, v, state.target_position):
            return
        state.target_velocity = clamp_velocity(self._name, v * state.multiplier, state.max_velocity)
        self._echo_velocity = (state.target_velocity, v)

    @buffered()
    def setAcceleration(self, acceleration: Any) -> None:
        a = as_float(acceleration, "Motor.setAcceleration")
        if finite(a) and not refuse_acceleration(self._name, a):
            self._state().acceleration = a

    @buffered()
    def setAvailableForce(self, force: Any) -> None:
        f = as_float(force, "Motor.setAvailableForce")
        if not refuse_available(self._name, f):
            state = self._state()
            state.available = min(f, state.max_force)

    @buffered()
    def setAvailableTorque(self, torque: Any) -> None:
        self.setAvailableForce(torque)

    @buffered()
    def setControlPID(self, p: Any, i: Any, d: Any) -> None:
        gains = [as_float(v, "Motor.setControlPID") for v in (p, i, d)]
        if refuse_nan("setControlPID", self._name, *gains):
            return
        state = self._state()
        state.kp, state.ki, state.kd = gains
        state.integral = state.prev_error = 0.0

    @buffered()
    def setForce(self, force: Any) -> None:
        """Force/torque control: only a Track's motor has one (TrackMotor); a Propeller's is speed-controlled."""
        as_float(force, "Motor.setForce")
        warn(f"'{self._name}': this motor is speed-controlled; setForce/setTorque is ignored")

    @buffered()
    def setTorque(self, torque: Any) -> None:
        self.setForce(torque)

    @command_value
    def getTargetPosition(self) -> float:
        state = self._state()
        return float(echo(state.target_position, self._echo_position, state.multiplier))

    @command_value
    def getVelocity(self) -> float:
        state = self._state()
        return float(echo(state.target_velocity, self._echo_velocity, state.multiplier))

    def getMinPosition(self) -> float:
        return float(self._state().min_position)

    def getMaxPosition(self) -> float:
        return float(self._state().max_position)

    def getMaxVelocity(self) -> float:
        return float(self._state().max_velocity)

    @command_value
    def getAcceleration(self) -> float:
        return float(self._state().acceleration)

    @command_value
    def getAvailableForce(self) -> float:
        return float(self._state().available)

    @command_value
    def getAvailableTorque(self) -> float:
        return self.getAvailableForce()

    def getMaxForce(self) -> float:
        return float(self._state().max_force)

    def getMaxTorque(self) -> float:
        return self.getMaxForce()

    def getMultiplier(self) -> float:
        return float(self._state().multiplier)

    def getPositionSensor(self) -> PositionSensor | None:
        return self._sibling("PositionSensor")  # type: ignore[return-value]

    def getBrake(self) -> Brake | None:
        return self._sibling("Brake")  # type: ignore[return-value]

    # -- no torque / force feedback without a joint

    def enableForceFeedback(self, sampling_period: Any) -> None:
        period = as_int(sampling_period, "Motor.enableForceFeedback")
        if period < 0:
            error(f"Motor.enableForceFeedback() called with a negative sampling period ({period}).")
            return
        if period > 0 and self._feedback_period == 0:
            warn(f"'{self._name}': force/torque feedback is not available for this motor (it has no joint); "
                 "it reads NaN")
        self._feedback_period = period

    def disableForceFeedback(self) -> None:
        self._feedback_period = 0

    def getForceFeedbackSamplingPeriod(self) -> int:
        return self._feedback_period

    @step_value
    def getForceFeedback(self) -> float:
        if self._feedback_period <= 0:
            error("wb_motor_get_force_feedback() called for a disabled device! Please use: "
                  "wb_motor_enable_force_feedback().")
        return math.nan

    def enableTorqueFeedback(self, sampling_period: Any) -> None:
        self.enableForceFeedback(sampling_period)

    def disableTorqueFeedback(self) -> None:
        self.disableForceFeedback()

    def getTorqueFeedbackSamplingPeriod(self) -> int:
        return self._feedback_period

    @step_value
    def getTorqueFeedback(self) -> float:
        if self._feedback_period <= 0:
            error("wb_motor_get_torque_feedback() called for a disabled device! Please use: "
                  "wb_motor_enable_torque_feedback().")
        return math.nan
