"""CartPole2 PID controller: balance the pole on the Pioneer 3-AT by driving all four wheels.

Written for dualtwin's tests the way the paper's CartPole2 PID controller is written (plain Webots Python API,
no dualtwin import): a supervisor that gives the pole a start push, then runs a PID on the pole angle whose
output is the wheel speed. It tries two start pushes, one after the other, resetting the simulation in between,
and prints one result line per push:

    push=<N> max_abs_angle=<rad> balanced_s=<s>
"""

from controller import Supervisor

TIME_STEP = 16
TRIAL_S = 20.0
PUSHES = [1.0, 5.0]  # horizontal force (N) on the pole for the first PUSH_S seconds
PUSH_S = 0.1
KP, KI, KD = 60.0, 240.0, 2.0  # wheel rad/s per rad, per rad*s, per rad/s
MAX_SPEED = 6.4
FALLEN = 0.3  # rad

robot = Supervisor()
robot.keyboard = robot.getKeyboard()  # the paper's controllers keep the keyboard on the robot (a plain attribute)
robot.simulationSetMode(Supervisor.SIMULATION_MODE_FAST)
wheels = [robot.getDevice(name)
          for name in ["front left wheel", "front right wheel", "back left wheel", "back right wheel"]]
pole_sensor = robot.getDevice("pole position sensor")
pole_sensor.enable(TIME_STEP)
pole = robot.getFromDef("POLE")
dt = TIME_STEP / 1000.0

stopped = False
for push in PUSHES:
    # simulationReset() puts the motors back in position control: switch to velocity control every trial
    for motor in wheels:
        motor.setPosition(float("inf"))
        motor.setVelocity(0.0)
    integral = 0.0
    previous = 0.0
    max_angle = 0.0
    balanced = 0.0
    start = robot.getTime()
    while robot.getTime() - start < TRIAL_S:
        if robot.getTime() - start < PUSH_S:
            pole.addForce([push, 0.0, 0.0], False)
        if robot.step(TIME_STEP) == -1:
            stopped = True
            break
        angle = pole_sensor.getValue()
        max_angle = max(max_angle, abs(angle))
        if abs(angle) > FALLEN:
            break
        balanced = robot.getTime() - start
        integral += angle * dt
        derivative = (angle - previous) / dt
        previous = angle
        speed = KP * angle + KI * integral + KD * derivative
        speed = max(-MAX_SPEED, min(MAX_SPEED, speed))
        for motor in wheels:
            motor.setVelocity(speed)
    print(f"push={push} max_abs_angle={max_angle:.4f} balanced_s={balanced:.2f}", flush=True)
    if stopped:
        break
    robot.simulationReset()
    robot.step(TIME_STEP)
