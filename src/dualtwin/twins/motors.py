"""Webots motor semantics, shared by every twin that has to emulate them (spec §5 of docs/reference/webots-on-ode.md).

Webots turns every controller command into a target velocity ``u`` for the ODE joint motor once per physics
step: velocity control uses the target velocity, position control runs Webots' PID on the position error
and clamps it to the target velocity, and an acceleration limit slews the result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from dualtwin.webots.motor_law import motor_velocity


@dataclass
class MotorParams:
    """A Webots RotationalMotor/LinearMotor's fields."""

    max_velocity: float = 10.0
    max_torque: float = 10.0
    kp: float = 10.0
    ki: float = 0.0
    kd: float = 0.0
    acceleration: float = -1.0
    #: Webots' minPosition/maxPosition: position targets are clamped into them when they differ.
    min_position: float = 0.0
    max_position: float = 0.0


@dataclass
class MotorState:
    """The controller-side state of one motor, as Webots keeps it (WbMotor)."""

    params: MotorParams
    target_position: float = 0.0
    target_velocity: float = 0.0
    torque: float = 0.0
    available_torque: float = 0.0
    torque_mode: bool = False
    integral: float = 0.0
    previous_error: float = 0.0
    current_velocity: float = 0.0
    gain: float = 1.0
    extra: dict[str, float] = field(default_factory=dict)

    def reset(self, position: float) -> None:
        """Webots' initial state: hold the current position at up to max velocity (spec §5.1)."""
        self.target_position = position
        self.target_velocity = self.params.max_velocity
        self.available_torque = self.params.max_torque
        self.torque = 0.0
        self.torque_mode = False
        self.integral = 0.0
        self.previous_error = 0.0
        self.current_velocity = 0.0

    def set_velocity(self, velocity: float) -> None:
        """Velocity control: ``setPosition(inf)`` + ``setVelocity(v)``, clamped to max velocity."""
        v = velocity * self.gain
        self.target_position = math.inf
        self.target_velocity = max(-self.params.max_velocity, min(self.params.max_velocity, v))
        self.torque_mode = False

    def set_position(self, position: float) -> None:
        p = self.params
        target = position * self.gain
        if p.min_position != p.max_position and math.isfinite(target):
            target = min(max(target, p.min_position), p.max_position)
        self.target_position = target
        self.target_velocity = self.params.max_velocity
        self.torque_mode = False

    def set_torque(self, torque: float) -> None:
        limit = min(self.available_torque, self.params.max_torque)
        self.torque = max(-limit, min(limit, torque * self.gain))
        self.torque_mode = True

    @property
    def needs_feedback(self) -> bool:
        """Position control and acceleration limits change ``u`` every physics step."""
        return not math.isinf(self.target_position) or self.params.acceleration > 0 or self.available_torque == 0.0

    def velocity_command(self, position: float, dt: float) -> float:
        """The velocity ``u`` the joint motor tracks this physics step (WbMotor.computeCurrentDynamicVelocity)."""
        p = self.params
        u, self.integral, self.previous_error = motor_velocity(
            target_position=self.target_position, target_velocity=self.target_velocity,
            available=self.available_torque, position=position, integral=self.integral,
            previous_error=self.previous_error, current_velocity=self.current_velocity, kp=p.kp, ki=p.ki, kd=p.kd,
            acceleration=p.acceleration, dt=dt)
        self.current_velocity = u
        return u
