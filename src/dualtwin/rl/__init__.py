"""Reinforcement learning on the twins: Gymnasium envs, domain randomisation, PPO training, transfer, export.

Importing this package registers the env ids (``gym.make("dualtwin/CartPole-MuJoCo-v0")``). It imports only
Gymnasium; PyTorch and Stable-Baselines3 load with the modules that need them:
``from dualtwin.rl.train import train``, ``from dualtwin.rl.transfer import transfer``,
``from dualtwin.rl.export import export_policy``, ``from dualtwin.rl.policy import load_policy``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym

from dualtwin.errors import DualtwinError
from dualtwin.rl.drive_to_goal import DriveToGoal
from dualtwin.rl.env import CartPoleBalance, ObservationTerm, Task, TwinEnv
from dualtwin.rl.randomize import DomainRandomization, FixedKnobs, apply_knobs, load_knob_values, load_ranges

if TYPE_CHECKING:
    from dualtwin.rl.export import export_policy
    from dualtwin.rl.policy import LoadedPolicy, load_policy
    from dualtwin.rl.transfer import TransferReport

NAMESPACE = "dualtwin"
DEFAULT_MAX_EPISODE_STEPS = 1000

# id -> TwinEnv keyword arguments. Every id gets the same conformance tests (tests/rl/test_env.py).
ENV_IDS: dict[str, dict[str, Any]] = {
    "dualtwin/CartPole-MuJoCo-v0": {"twin": "mujoco", "continuous": False},
    "dualtwin/CartPole-Webots-v0": {"twin": "webots", "continuous": False},
    "dualtwin/CartPole-MuJoCo-Continuous-v0": {"twin": "mujoco", "continuous": True},
    "dualtwin/CartPole-Webots-Continuous-v0": {"twin": "webots", "continuous": True},
    "dualtwin/Pioneer-DriveToGoal-MuJoCo-v0": {"twin": "mujoco", "robot": "pioneer3at", "task": "drive_to_goal",
                                               "continuous": True},
    "dualtwin/Pioneer-DriveToGoal-Webots-v0": {"twin": "webots", "robot": "pioneer3at", "task": "drive_to_goal",
                                               "continuous": True},
}
# Episode caps (control periods) of ids that do not use DEFAULT_MAX_EPISODE_STEPS. 250 x 32 ms = 8 s: the
# farthest goal (2.5 m) behind the robot takes about 5 s at full wheel speed (half a turn in place, then 2.5 m).
MAX_EPISODE_STEPS: dict[str, int] = {"dualtwin/Pioneer-DriveToGoal-MuJoCo-v0": 250,
                                     "dualtwin/Pioneer-DriveToGoal-Webots-v0": 250}


def _register() -> None:
    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="dualtwin.rl.env:TwinEnv",
                         max_episode_steps=MAX_EPISODE_STEPS.get(env_id, DEFAULT_MAX_EPISODE_STEPS),
                         kwargs=dict(kwargs))


_register()


def registered_ids() -> list[str]:
    """Every registered ``dualtwin/...`` env id (ours and any a user registered in the namespace)."""
    return sorted(k for k in gym.registry if k.startswith(f"{NAMESPACE}/"))


def check_env_id(env_id: str) -> str:
    """Return ``env_id`` if it is a registered dualtwin id, else raise a :class:`DualtwinError` listing them."""
    if env_id not in gym.registry or not env_id.startswith(f"{NAMESPACE}/"):
        raise DualtwinError(f"unknown env id {env_id!r} (registered dualtwin ids: {', '.join(registered_ids())})")
    return env_id


def make_env(env_id: str, **kwargs: Any) -> gym.Env[Any, Any]:
    """``gym.make`` for dualtwin ids, with a readable error for unknown ids."""
    return gym.make(check_env_id(env_id), **kwargs)


def __getattr__(name: str) -> Any:
    # Lazy: keep `import dualtwin.rl` free of torch and SB3 (seconds of import time). `train` and `transfer`
    # are not offered here: they share their names with their submodules, which would shadow them.
    lazy = {"load_policy": "policy", "LoadedPolicy": "policy", "TransferReport": "transfer",
            "export_policy": "export"}
    if name in lazy:
        import importlib

        return getattr(importlib.import_module(f"dualtwin.rl.{lazy[name]}"), name)
    raise AttributeError(f"module 'dualtwin.rl' has no attribute {name!r}")


__all__ = [
    "ENV_IDS", "MAX_EPISODE_STEPS", "CartPoleBalance", "DomainRandomization", "DriveToGoal", "FixedKnobs",
    "LoadedPolicy", "ObservationTerm", "Task", "TransferReport", "TwinEnv", "apply_knobs", "check_env_id",
    "export_policy", "load_knob_values", "load_policy", "load_ranges", "make_env", "registered_ids",
]
