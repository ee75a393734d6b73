"""Inverted pendulum balancing, written by us in Webots controller style.

Applies the PID law described in the fixture README for ``inverted_pendulum.wbt``:
``setForce(clamp(50·θ + 4·Δθ + 2·Σθ ± 4 centering, ±40))`` every 32 ms, where θ is the "hip" angle,
Δθ its change since the previous step and Σθ the running sum. The ±4 "centering" bias is applied
against the sign of the cart position; the integral term absorbs it, so the pole stays up while the
cart cruises along the 200 m rail (which is why the sample world's rail is that long and its viewpoint
follows the cart). Prints a one-line summary when the run ends.
"""

from __future__ import annotations

from controller import Robot

TIME_STEP = 32
KP, KD, KI = 50.0, 4.0, 2.0
CENTERING = 4.0
MAX_FORCE = 40.0

robot = Robot()
hip = robot.getDevice("hip")
hip.enable(TIME_STEP)
horizontal = robot.getDevice("horizontal position sensor")
horizontal.enable(TIME_STEP)
motor = robot.getDevice("horizontal_motor")

previous = 0.0
integral = 0.0
max_theta = 0.0
max_x = 0.0
while robot.step(TIME_STEP) != -1:
    theta = hip.getValue()
    x = horizontal.getValue()
    integral += theta
    force = KP * theta + KD * (theta - previous) + KI * integral
    force += -CENTERING if x > 0.0 else CENTERING
    motor.setForce(max(-MAX_FORCE, min(MAX_FORCE, force)))
    previous = theta
    max_theta = max(max_theta, abs(theta))
    max_x = max(max_x, abs(x))

print(f"inverted_pendulum: time={robot.getTime():.3f} max_abs_theta={max_theta:.4f} max_abs_x={max_x:.4f}")
