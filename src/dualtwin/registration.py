"""The ``dualtwin/...`` Gymnasium env ids: the one list, registered by entry-point string only.

This module imports nothing heavy (no MuJoCo, no Webots, no torch): registering an id only records the string
``"dualtwin.rl.env:TwinEnv"``, which Gymnasium imports at ``gym.make``. ``import dualtwin`` calls
:func:`register_envs` when Gymnasium is installed, so ``gym.make("dualtwin/CartPole-MuJoCo-v0")`` works without
importing :mod:`dualtwin.rl` first. Gymnasium's idiom for plugin packages is ``gym.register_envs(dualtwin)``:
it only marks the import as used (linters would drop a bare ``import dualtwin``); the import registers.
"""

from __future__ import annotations

import importlib.util
from typing import Any

NAMESPACE = "dualtwin"
DEFAULT_MAX_EPISODE_STEPS = 1000
ENTRY_POINT = "dualtwin.rl.env:TwinEnv"

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
    # The six-joint arm's reach task (issue 19): joint-position-delta actions, 32 ms control periods.
    "dualtwin/Arm-Reach-MuJoCo-v0": {"twin": "mujoco", "robot": "arm", "task": "reach", "continuous": True},
    "dualtwin/Arm-Reach-Webots-v0": {"twin": "webots", "robot": "arm", "task": "reach", "continuous": True},
}
# Episode caps (control periods) of ids that do not use DEFAULT_MAX_EPISODE_STEPS. 250 x 32 ms = 8 s: the
# farthest goal (2.5 m) behind the robot takes about 5 s at full wheel speed (half a turn in place, then 2.5 m).
MAX_EPISODE_STEPS: dict[str, int] = {"dualtwin/Pioneer-DriveToGoal-MuJoCo-v0": 250,
                                     "dualtwin/Pioneer-DriveToGoal-Webots-v0": 250,
                                     # 100 x 32 ms = 3.2 s: the longest joint move in the box takes ~0.6 s.
                                     "dualtwin/Arm-Reach-MuJoCo-v0": 100, "dualtwin/Arm-Reach-Webots-v0": 100}


def gymnasium_installed() -> bool:
    return importlib.util.find_spec("gymnasium") is not None


def register_envs() -> list[str]:
    """Register every id not yet in Gymnasium's registry; the ids registered now ([] without Gymnasium)."""
    if not gymnasium_installed():
        return []
    import gymnasium as gym

    added = []
    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY_POINT,
                         max_episode_steps=MAX_EPISODE_STEPS.get(env_id, DEFAULT_MAX_EPISODE_STEPS),
                         kwargs=dict(kwargs))
            added.append(env_id)
    return added
