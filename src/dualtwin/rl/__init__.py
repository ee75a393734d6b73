"""Reinforcement learning on the twins: Gymnasium envs, domain randomisation, PPO training, transfer, export.

Importing this package registers the env ids (``gym.make("dualtwin/CartPole-MuJoCo-v0")``). It imports only
Gymnasium; PyTorch and Stable-Baselines3 load with the modules that need them:
``from dualtwin.rl.train import train``, ``from dualtwin.rl.transfer import transfer``,
``from dualtwin.rl.export import export_policy``, ``from dualtwin.rl.policy import load_policy``,
``from dualtwin.rl.shadow import ShadowCallback`` (a Webots shadow of training episodes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym

from dualtwin.errors import DualtwinError
from dualtwin.registration import ENV_IDS, MAX_EPISODE_STEPS, NAMESPACE, register_envs
from dualtwin.rl.drive_to_goal import DriveToGoal
from dualtwin.rl.env import CartPoleBalance, ObservationTerm, Task, TwinEnv
from dualtwin.rl.randomize import DomainRandomization, FixedKnobs, apply_knobs, load_knob_values, load_ranges
from dualtwin.rl.reach import ArmReach

if TYPE_CHECKING:
    from dualtwin.rl.export import export_policy
    from dualtwin.rl.policy import LoadedPolicy, load_policy
    from dualtwin.rl.shadow import ShadowCallback
    from dualtwin.rl.transfer import TransferReport

# The ids live in dualtwin.registration (light), so that `import dualtwin` registers them without this package.
register_envs()


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
            "export_policy": "export", "ShadowCallback": "shadow"}
    if name in lazy:
        import importlib

        return getattr(importlib.import_module(f"dualtwin.rl.{lazy[name]}"), name)
    raise AttributeError(f"module 'dualtwin.rl' has no attribute {name!r}")


__all__ = [
    "ENV_IDS", "MAX_EPISODE_STEPS", "ArmReach", "CartPoleBalance", "DomainRandomization", "DriveToGoal", "FixedKnobs",
    "LoadedPolicy", "ObservationTerm", "ShadowCallback", "Task", "TransferReport", "TwinEnv", "apply_knobs", "check_env_id",
    "export_policy", "load_knob_values", "load_policy", "load_ranges", "make_env", "registered_ids",
]
