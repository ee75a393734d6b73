"""Drive the three robots of ``four_wheels.wbt`` straight ahead, written by us in Webots controller style.

Every wheel motor is switched to velocity control. The Ackermann and skid-steer robots spin all
wheels at +SPEED (their hinge axes are -x, so they roll toward +y); the omni robot's 45° wheels get
alternating signs so that their pushes add up along +y.
"""

from __future__ import annotations

from controller import Robot

TIME_STEP = 16
SPEED = 4.0
WHEELS = ("rear_right_wheel", "rear_left_wheel", "front_right_wheel", "front_left_wheel")
OMNI_SIGNS = {
    "rear_right_wheel": -1.0,
    "rear_left_wheel": 1.0,
    "front_right_wheel": -1.0,
    "front_left_wheel": 1.0,
}

robot = Robot()
name = robot.getName()
for wheel in WHEELS:
    motor = robot.getDevice(wheel)
    motor.setPosition(float("inf"))
    motor.setVelocity(SPEED * (OMNI_SIGNS[wheel] if name == "omni_wheels" else 1.0))

steps = 0
while robot.step(TIME_STEP) != -1:
    steps += 1

print(f"{name}: {steps} steps, t={robot.getTime():.3f}")
