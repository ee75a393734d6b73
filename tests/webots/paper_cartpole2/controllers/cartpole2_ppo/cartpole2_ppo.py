"""CartPole2 policy controller: run a trained policy on the Pioneer 3-AT pole, episode after episode.

Written for dualtwin's tests the way the paper's CartPole2 PPO controller is written (plain Webots Python
API, no dualtwin import): each control step it builds the observation, calls ``model.predict(obs,
deterministic=True)`` and passes the returned action, a shape-(1,) NumPy array, straight to
``Motor.setVelocity``. An episode ends when |pole| > 0.3 rad or after MAX_STEPS steps; the supervisor then
resets the simulation. It runs until ``step()`` returns -1 (``dualtwin webots run --duration``) and prints
one line per episode:

    episode=<k> steps=<n> max_abs_angle=<rad>

The paper's controller loads an SB3 PPO model (``PPO.load``). We have no such file (and ``PPO.load``
unpickles), so ``model`` here is a fixed linear policy read from ``linear_policy.json`` next to this script,
behind the same ``predict`` interface: it returns ``(action, None)`` with ``action`` a float32 array of shape
(1,), as SB3 does for a one-dimensional Box action space.
"""

import json
import math
import os

import numpy as np
from controller import Supervisor

TIME_STEP = 16
MAX_STEPS = 1000
FALLEN = 0.3
WHEEL_RADIUS = 0.11


class LinearPolicy:
    """``action = clip(weights · obs, low, high)``, with SB3's ``predict`` signature and return types."""

    def __init__(self, path):
        with open(path, encoding="utf-8") as handle:
            spec = json.load(handle)
        self.weights = np.asarray(spec["weights"], dtype=np.float32)
        self.low, self.high = float(spec["low"]), float(spec["high"])

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float32).reshape(-1)
        action = np.clip(np.array([self.weights @ obs], dtype=np.float32), self.low, self.high)
        return action, None


model = LinearPolicy(os.path.join(os.path.dirname(os.path.abspath(__file__)), "linear_policy.json"))

robot = Supervisor()
robot.keyboard = robot.getKeyboard()  # the paper's controllers keep the keyboard on the robot (a plain attribute)
robot.simulationSetMode(Supervisor.SIMULATION_MODE_FAST)
wheels = [robot.getDevice(name)
          for name in ["front left wheel", "front right wheel", "back left wheel", "back right wheel"]]
pole_sensor = robot.getDevice("pole position sensor")
pole_sensor.enable(TIME_STEP)
body = robot.getSelf()
pole = robot.getFromDef("POLE")
rng = np.random.default_rng(0)


def start_episode():
    for motor in wheels:
        motor.setPosition(float("inf"))
        motor.setVelocity(0.0)
    # a small random start push, as the training environment's reset does
    pole.addForce([float(rng.uniform(-1.0, 1.0)), 0.0, 0.0], False)


episode, steps, max_angle, previous = 0, 0, 0.0, 0.0
start_episode()
while robot.step(TIME_STEP) != -1:
    angle = pole_sensor.getValue()
    if math.isnan(angle):
        continue
    rate = (angle - previous) / (TIME_STEP / 1000.0) if steps else 0.0
    previous = angle
    x = body.getPosition()[0]
    x_dot = body.getVelocity()[0]
    obs = np.array([x, x_dot, angle, rate], dtype=np.float32)
    action, _ = model.predict(obs, deterministic=True)
    for motor in wheels:
        motor.setVelocity(action)
    steps += 1
    max_angle = max(max_angle, abs(angle))
    if abs(angle) > FALLEN or steps >= MAX_STEPS:
        print(f"episode={episode} steps={steps} max_abs_angle={max_angle:.4f}", flush=True)
        episode, steps, max_angle, previous = episode + 1, 0, 0.0, 0.0
        robot.simulationReset()
        if robot.step(TIME_STEP) == -1:
            break
        start_episode()
print(f"stopped after {episode} episodes", flush=True)
