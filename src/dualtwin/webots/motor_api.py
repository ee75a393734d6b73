"""The checks and echoes of Webots' Motor API, shared by every kind of motor (joint motors, a Track's LinearMotor, a
Propeller's RotationalMotor), so that they all refuse the same arguments with the same lines.

libController checks the arguments before anything is sent (webots-devices.md §9, "Controller-side checks"):
NaN targets are refused, a negative velocity is refused while the motor is in position control, a negative
acceleration other than -1 and a negative available force/torque are refused. What it caches for
``getTargetPosition``/``getVelocity`` is the raw value the controller passed, not the one Webots multiplied by
the motor's ``multiplier`` (§9).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Container, Iterable
from typing import Any, TypeVar

from dualtwin.webots.api_args import warn

__all__ = ["MULTIPLIER_ZERO", "check_maxima", "clamp_force", "clamp_position", "clamp_velocity", "coupled_groups",
           "echo", "field_multiplier", "read_motor_fields", "refuse_acceleration", "refuse_available", "refuse_nan",
           "refuse_velocity", "target_in_limits"]

T = TypeVar("T")

#: the load warning of a motor whose multiplier is 0 (webots-devices.md §9: "0 → reset to 1 with warning")
MULTIPLIER_ZERO = "motor '{name}': multiplier 0 is not allowed; using 1"


def field_multiplier(motor: Any, name: str, report: Callable[[str], None]) -> float:
    """A motor node's ``multiplier`` field, 0 refused with :data:`MULTIPLIER_ZERO` and 1 used (at load and after a
    supervisor's edit)."""
    multiplier = float(motor.fields.get("multiplier", 1.0))
    if multiplier == 0.0:
        report(MULTIPLIER_ZERO.format(name=name))
        return 1.0
    return multiplier


def target_in_limits(target: float, min_position: float, max_position: float) -> float:
    """A finite target position that new limits (min ≠ max) leave outside, clipped into them silently: what a
    supervisor's edit of ``minPosition``/``maxPosition`` does to the target (physics/motor_edits.py)."""
    if min_position != max_position and math.isfinite(target):
        return min(max(target, min_position), max_position)
    return target


def read_motor_fields(rec: Any, motor: Any, names: Container[str], label: str, report: Callable[[str], None]) -> None:
    """Read the motor node ``motor``'s fields ``names`` into its record ``rec`` (a joint motor's, a Track's
    LinearMotor's or a Propeller's RotationalMotor's, which keep them under the same names): at load and after a
    supervisor's edit. A target velocity beyond a new maxVelocity is clipped into it, ``maxTorque``/``maxForce`` is
    also the available force, new gains (``controlPID``) start the error integral again, a finite target left outside
    new limits is clipped into them (:func:`target_in_limits`), and a multiplier of 0 is refused with the load's
    warning, naming the motor ``label`` (:func:`field_multiplier`; webots-devices.md §9)."""
    f = motor.fields
    if "maxVelocity" in names:
        rec.max_velocity = float(f.get("maxVelocity", 10.0))
        rec.target_velocity = max(-rec.max_velocity, min(rec.max_velocity, rec.target_velocity))
    for force in ("maxTorque", "maxForce"):
        if force in names:
            rec.max_force = rec.available = float(f.get(force, 10.0))
    if "acceleration" in names:
        # §5.2: the field is the motor's acceleration (setAcceleration replaces it), -1 unlimited
        rec.acceleration = float(f.get("acceleration", -1.0))
    if "controlPID" in names:
        rec.kp, rec.ki, rec.kd = (float(v) for v in f.get("controlPID", (10.0, 0.0, 0.0)))
        rec.integral = rec.prev_error = 0.0
    if "minPosition" in names or "maxPosition" in names:
        rec.min_position = float(f.get("minPosition", 0.0))
        rec.max_position = float(f.get("maxPosition", 0.0))
        rec.target_position = target_in_limits(rec.target_position, rec.min_position, rec.max_position)
    if "multiplier" in names:
        rec.multiplier = field_multiplier(motor, label, report)


def check_maxima(motor: Any, report: Callable[[str], None]) -> None:
    """A motor node's negative ``maxVelocity``, ``maxTorque`` or ``maxForce`` is made positive, and a negative
    ``acceleration`` other than -1 becomes -1 (unlimited), with a ``report``ed warning, before any motor reads them
    (joint motors, a Track's, a Propeller's), as Webots' motor field checks reset them. Here a Propeller with
    maxTorque -1e308 clamped its torque to +1e308, or with acceleration -1e308 spun up by as much, and ODE stopped
    inside the step (found by fuzzing)."""
    fields = motor.fields
    for name in ("maxVelocity", "maxTorque", "maxForce"):
        value = fields.get(name)
        if isinstance(value, int | float) and value < 0:
            report(f"{motor.type_name} '{fields.get('name', '')}': {name} {value:g} is negative; using {-value:g}")
            fields[name] = -value
    acceleration = fields.get("acceleration")
    if isinstance(acceleration, int | float) and acceleration < 0 and acceleration != -1:
        # -1 is "unlimited"; another negative one (a Propeller spun up by -1e308 rad/s² a step) is reset to it
        report(f"{motor.type_name} '{fields.get('name', '')}': acceleration {acceleration:g} is negative; using -1 "
               "(unlimited)")
        fields["acceleration"] = -1.0


def coupled_groups(motors: Iterable[T], name: Callable[[T], str] = str) -> dict[str, list[T]]:
    """Webots' coupled motors: the motors named ``prefix::suffix`` (exactly two parts; ``name`` gives a motor's
    name), grouped by ``prefix`` in the given order (groups of one included: Webots warns that nothing is coupled)
    (webots-devices.md §9)."""
    groups: dict[str, list[T]] = {}
    for motor in motors:
        parts = name(motor).split("::")
        if len(parts) == 2:
            groups.setdefault(parts[0], []).append(motor)
    return groups


def refuse_nan(method: str, name: str, *values: float) -> bool:
    """True (after a warning) when one of ``values`` is NaN: the command is ignored."""
    if all(v == v for v in values):
        return False
    warn(f"Motor.{method}() called with an invalid value (NaN) on '{name}'")
    return True


def refuse_velocity(name: str, velocity: float, target_position: float) -> bool:
    """True (after libController's error line) for a negative velocity while the motor is in position control
    (a finite target position)."""
    if velocity < 0 and math.isfinite(target_position):
        print(f"Error: wb_motor_set_velocity() called with a negative velocity on '{name}', which is in "
              "position control: use setPosition(float('inf')) for velocity control", file=sys.stderr)
        return True
    return False


def refuse_acceleration(name: str, acceleration: float) -> bool:
    """True (after libController's error line) for a negative acceleration other than -1 (unlimited)."""
    if acceleration < 0 and acceleration != -1:
        print(f"Error: wb_motor_set_acceleration() called with a negative acceleration {acceleration} on "
              f"'{name}' (-1 means unlimited)", file=sys.stderr)
        return True
    return False


def refuse_available(name: str, force: float) -> bool:
    """True (after a warning) for a NaN or negative available force/torque."""
    if force == force and force >= 0:
        return False
    warn(f"'{name}': invalid available force/torque {force}")
    return True


def clamp_position(name: str, position: float, min_position: float, max_position: float) -> float:
    """A multiplied target position clipped into [minPosition, maxPosition] (with a warning) when the motor has
    limits (min ≠ max) and the target is finite (webots-on-ode.md §5.2)."""
    if min_position != max_position and math.isfinite(position):
        clamped = min(max(position, min_position), max_position)
        if clamped != position:
            warn(f"'{name}': requested position {position} outside [minPosition, maxPosition]")
        return clamped
    return position


def clamp_velocity(name: str, velocity: float, max_velocity: float) -> float:
    """A multiplied target velocity clipped to ±maxVelocity, with a warning (webots-on-ode.md §5.2)."""
    if abs(velocity) > max_velocity:
        warn(f"'{name}': requested velocity {velocity} exceeds maxVelocity {max_velocity}")
        return math.copysign(max_velocity, velocity)
    return velocity


def clamp_force(name: str, force: float, available: float, report: bool = True) -> float:
    """A multiplied force/torque command clipped to ±the available force/torque, with a warning unless the motor
    is coupled (webots-devices.md §9: "clipped to ±available force/torque; warning suppressed for coupled
    motors")."""
    if abs(force) > available:
        if report:
            warn(f"'{name}': requested force/torque {force} exceeds the available force/torque {available}")
        return math.copysign(available, force)
    return force


def echo(value: float, given: tuple[float, float] | None, multiplier: float) -> float:
    """What libController caches for a target a motor was last given: the raw, unmultiplied value (§9), in its
    own units when the motor's limits clipped it; the simulation's target ``value`` otherwise (a sibling's relayed
    command, the initial state, a reset). ``given`` is (the simulation's target, the value the controller gave)
    as recorded by the motor's own last command."""
    if given is None or given[0] != value:
        return value
    return given[1] if given[1] * multiplier == value else value / multiplier

