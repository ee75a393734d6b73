"""Webots' motor law (docs/reference/webots-on-ode.md §5.3), as one pure function for every twin that follows it.

Per physics step, a motor turns its controller targets into the velocity ``u`` its joint motor tracks:
available torque 0 means no control; velocity control (infinite target position) uses the target velocity;
position control runs Webots' PID on the position error and clamps the output to the target velocity; an
acceleration limit then slews ``u`` from the previous value.
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
