"""CartPole2 with 17 discrete actions and the keyboard: a discrete controller a person can take over.

Written for dualtwin's tests the way the paper's 17-action CartPole2 controller is written (plain Webots
Python API, no dualtwin import). The 17 actions are wheel speeds evenly spaced over [-6.4, 6.4] rad/s. In
automatic mode the controller picks the action nearest to what a PID on the pole angle asks for; the
keyboard (``self.keyboard = self.getKeyboard()`` in a Supervisor subclass, as in the paper) switches modes and drives by hand:

    M       toggle manual / automatic
    LEFT    manual: one action slower      RIGHT   manual: one action faster
    R       reset the simulation           Q       quit the controller

Headless, no key is ever pressed (``getKey()`` returns -1) unless ``dualtwin webots run --keys FILE``
replays some. It prints one line per event and a summary when it stops:

    key=<code> ...  /  reset at t=<s>  /  done steps=<n> resets=<k> max_abs_angle=<rad> actions_used=<m>
"""

import numpy as np
from controller import Keyboard, Supervisor

TIME_STEP = 16
ACTIONS = np.linspace(-6.4, 6.4, 17)
KP, KI, KD = 60.0, 240.0, 2.0



class CartPole2(Supervisor):
    """As in the paper's controller: a Supervisor subclass that keeps its keyboard and state on itself."""

    def __init__(self):
        super().__init__()
        self.keyboard = self.getKeyboard()  # Webots' Robot.keyboard is a plain attribute
        self.keyboard.enable(TIME_STEP)
        self._mode = "automatic"  # names Webots' Robot does not use, so a subclass may
        self._sensors = {}
        self._devices = []


robot = CartPole2()
robot.simulationSetMode(Supervisor.SIMULATION_MODE_FAST)
keyboard = robot.keyboard
wheels = [robot.getDevice(name)
          for name in ["front left wheel", "front right wheel", "back left wheel", "back right wheel"]]
pole_sensor = robot.getDevice("pole position sensor")
pole_sensor.enable(TIME_STEP)
dt = TIME_STEP / 1000.0


def velocity_control():
    for motor in wheels:
        motor.setPosition(float("inf"))
        motor.setVelocity(0.0)


velocity_control()
manual = False
action = 8  # the middle action: 0 rad/s
integral, previous = 0.0, 0.0
steps, resets, max_angle = 0, 0, 0.0
used = set()
quit_requested = False
while robot.step(TIME_STEP) != -1:
    key = keyboard.getKey()
    while key != -1:
        code = key & Keyboard.KEY
        print(f"key={code}", flush=True)
        if code == ord("M"):
            manual = not manual
        elif code == Keyboard.LEFT:
            action = max(0, action - 1)
        elif code == Keyboard.RIGHT:
            action = min(len(ACTIONS) - 1, action + 1)
        elif code == ord("R"):
            print(f"reset at t={robot.getTime():.3f}", flush=True)
            robot.simulationReset()
            resets += 1
            integral, previous = 0.0, 0.0
        elif code == ord("Q"):
            quit_requested = True
        key = keyboard.getKey()
    if quit_requested:
        break
    if resets and robot.getTime() <= dt:
        velocity_control()  # the reset put the motors back in position control
    angle = pole_sensor.getValue()
    max_angle = max(max_angle, abs(angle))
    if not manual:
        integral += angle * dt
        wanted = KP * angle + KI * integral + KD * (angle - previous) / dt
        action = int(np.argmin(np.abs(ACTIONS - wanted)))
    previous = angle
    used.add(action)
    for motor in wheels:
        motor.setVelocity(ACTIONS[action])
    steps += 1
print(f"done steps={steps} resets={resets} max_abs_angle={max_angle:.4f} actions_used={len(used)}", flush=True)
