"""Webots' motor law (docs/reference/webots-on-ode.md §5.3), as one pure function for every twin that follows it.

Per physics step, a motor turns its controller targets into the velocity ``u`` its joint motor tracks:
available torque 0 means no control; velocity control (infinite target position) uses the target velocity;
position control runs Webots' PID on the position error and clamps the output to the target velocity; an
acceleration limit then slews ``u`` from the previous value. A motor without an ODE joint (a kinematic joint or a
Propeller) moves its position itself (:func:`kinematic_motion`).
"""

from __future__ import annotations

import math


def motor_velocity(*, target_position: float, target_velocity: float, available: float, position: float,
                   integral: float, previous_error: float, current_velocity: float, kp: float, ki: float,
                   kd: float, acceleration: float, dt: float) -> tuple[float, float, float]:
    """Returns ``(u, integral, previous_error)``; ``u`` is in Webots' sign convention."""
    if available == 0.0:
        u = 0.0
    elif math.isinf(target_position):
        u = target_velocity
    else:
        error = target_position - position
        integral += error * dt
        # Webots starts previous_error at 0, so the first step has a derivative kick when kd > 0.
        out = kp * error + ki * integral + kd * (error - previous_error) / dt
        previous_error = error
        limit = abs(target_velocity)
        u = out if abs(out) < limit else math.copysign(limit, out)
    if acceleration >= 0:  # -1 means unlimited
        step = acceleration * dt
        u = max(current_velocity - step, min(current_velocity + step, u))
    return u, integral, previous_error


def kinematic_motion(*, position: float, current_velocity: float, target_position: float, target_velocity: float,
                     available: float, acceleration: float, dt: float) -> tuple[float, float]:
    """One step of Webots' kinematic motor controller (``WbMotor.runKinematicControl``, §5.3): returns
    ``(position, current_velocity)``.

    The current velocity changes by at most ``a·dt``, ``a`` being the acceleration, or the available torque/force
    when the acceleration is -1 or larger than that. Velocity control integrates it; position control moves toward
    the target at the current speed (a magnitude that ramps toward ``|target_velocity|``) and stops on the target
    once within a step or 1e-6, where the velocity is 0. The returned velocity carries the sign of the motion.
    """
    accel = available if acceleration == -1.0 or acceleration > available else acceleration
    slew = accel * dt
    if math.isinf(target_position):
        current_velocity += max(-slew, min(slew, target_velocity - current_velocity))
        return position + current_velocity * dt, current_velocity
    error = target_position - position
    speed = abs(current_velocity)
    speed += max(-slew, min(slew, abs(target_velocity) - speed))
    step = speed * dt
    if abs(error) <= max(step, 1e-6):
        return target_position, 0.0
    return position + math.copysign(step, error), math.copysign(speed, error)
