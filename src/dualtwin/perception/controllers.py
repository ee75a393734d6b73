"""Controllers that drive the twin while perception data is recorded.

They may use the privileged state (they run in simulation, to visit the states a policy visits); the frames
and labels they produce are what matters. Each is seeded per episode, so an episode's data depends only on
(seed, episode index).

* ``scripted``: a balancing controller with noise. The wheels are velocity servos, so the controller
  integrates a state-feedback acceleration ``a = 25 θ + 6 θ' + 1 (x - x*) + 2 x'`` into the velocity command
  (a velocity proportional to the tilt cannot stabilise the pole; an acceleration can). Gains are jittered per
  episode, Ornstein-Uhlenbeck noise is added to ``a`` and the target position ``x*`` jumps every 1.5-3 s, so
  the pole stays mostly upright while the cart roams (about ±0.5 m) and the pole tilts. An episode that
  drops the pole (|θ| > 0.6 rad) or runs far (|x| > 1.2 m) ends there.
* ``random``: uniform random actions (the pole falls: coverage of large angles).
* ``noisy-policy``: a trained policy (exported ``policy.onnx`` or a training run) plus Gaussian action noise
  (discrete: a random action with probability 0.15).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError

CONTROLLERS = ("scripted", "random", "noisy-policy")


class Controller(ABC):
    """Chooses env actions from the privileged state ``[x, x', θ, θ']`` and the env observation."""

    def __init__(self, action_space: Any, control_period: float, max_speed: float) -> None:
        self.action_space = action_space
        self.dt = control_period
        self.max_speed = max_speed
        self.discrete = not hasattr(action_space, "shape") or action_space.shape in ((), None)

    @abstractmethod
    def reset(self, rng: np.random.Generator) -> None: ...

    @abstractmethod
    def act(self, state: np.ndarray, observation: np.ndarray) -> Any: ...

    def finished(self, state: np.ndarray) -> bool:
        """End the episode early (the data would no longer be useful)."""
        return False

    def _from_speed(self, speed: float) -> Any:
        if self.discrete:
            return int(speed > 0.0)
        return np.array([np.clip(speed / self.max_speed, -1.0, 1.0)], dtype=np.float32)


class ScriptedController(Controller):
    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.gains = np.array([25.0, 6.0, 1.0, 2.0]) * rng.uniform(0.8, 1.2, 4)
        self.noise_scale = float(rng.uniform(0.2, 1.2))
        self.noise = 0.0
        self.command = 0.0
        self.target = 0.0
        self.next_target = 0

    def act(self, state: np.ndarray, observation: np.ndarray) -> Any:
        x, v, theta, omega = (float(s) for s in state)
        if self.next_target <= 0:
            self.target = float(self.rng.uniform(-0.3, 0.3))
            self.next_target = int(self.rng.integers(int(1.5 / self.dt), int(3.0 / self.dt)))
        self.next_target -= 1
        # Ornstein-Uhlenbeck noise on the acceleration: smooth, so the servo follows it.
        self.noise += -0.3 * self.noise + self.noise_scale * float(self.rng.normal())
        k = self.gains
        accel = k[0] * theta + k[1] * omega + k[2] * (x - self.target) + k[3] * v + self.noise
        self.command = float(np.clip(self.command + accel * self.dt, -self.max_speed, self.max_speed))
        return self._from_speed(self.command)


    def finished(self, state: np.ndarray) -> bool:
        # A fallen pole or a cart far out is not what a balancing policy sees: stop recording.
        return bool(abs(float(state[2])) > 0.6 or abs(float(state[0])) > 1.2)


class RandomController(Controller):
    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def act(self, state: np.ndarray, observation: np.ndarray) -> Any:
        if self.discrete:
            return int(self.rng.integers(2))
        return self.rng.uniform(-1.0, 1.0, size=(1,)).astype(np.float32)


class PolicyController(Controller):
    """A trained policy (``policy.onnx`` from :func:`dualtwin.rl.export_policy`) with exploration noise."""

    def __init__(self, action_space: Any, control_period: float, max_speed: float, policy: Path | str) -> None:
        super().__init__(action_space, control_period, max_speed)
        from dualtwin.perception.onnx_policy import OnnxPolicy

        self.policy = OnnxPolicy.load(policy)

    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def act(self, state: np.ndarray, observation: np.ndarray) -> Any:
        action = self.policy.action(observation)
        if self.discrete:
            return int(self.rng.integers(2)) if self.rng.random() < 0.15 else int(action)
        noisy = np.asarray(action, dtype=np.float32).reshape(-1) + self.rng.normal(0.0, 0.2, 1)
        return np.clip(noisy, -1.0, 1.0).astype(np.float32)


def make_controller(name: str, action_space: Any, control_period: float, max_speed: float,
                    policy: Path | str | None = None) -> Controller:
    if name == "scripted":
        return ScriptedController(action_space, control_period, max_speed)
    if name == "random":
        return RandomController(action_space, control_period, max_speed)
    if name == "noisy-policy":
        if policy is None:
            raise DualtwinError("controller 'noisy-policy' needs a policy (an exported policy folder or a run)")
        return PolicyController(action_space, control_period, max_speed, policy)
    raise DualtwinError(f"unknown controller {name!r} (available: {', '.join(CONTROLLERS)})")
