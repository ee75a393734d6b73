"""The ``dualtwin/...`` Gymnasium env ids: the one list, registered by entry-point string only.

This module imports nothing heavy (no MuJoCo, no Webots, no torch): registering an id only records the string
``"dualtwin.rl.env:TwinEnv"``, which Gymnasium imports at ``gym.make``. ``import dualtwin`` calls
:func:`register_envs` when Gymnasium is installed, so ``gym.make("dualtwin/CartPole-MuJoCo-v0")`` works without
importing :mod:`dualtwin.rl` first. Gymnasium's idiom for plugin packages is ``gym.register_envs(dualtwin)``:
it only marks the import as used (linters would drop a bare ``import dualtwin``); the import registers.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType
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
# Ids whose envs can also be made N at a time as one batch of MuJoCo simulations (dualtwin.rl.vector_env):
# gym.make_vec(id, num_envs=N) then uses it (vectorization_mode="sync" still gives N separate envs).
VECTOR_ENTRY_POINT = "dualtwin.rl.vector_env:TwinVectorEnv"
VECTOR_ENV_IDS = ("dualtwin/CartPole-MuJoCo-v0", "dualtwin/CartPole-MuJoCo-Continuous-v0")
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
                         kwargs=dict(kwargs),
                         vector_entry_point=VECTOR_ENTRY_POINT if env_id in VECTOR_ENV_IDS else None)
            added.append(env_id)
    return added


def register_when_gymnasium_loads() -> None:
    """Register now if Gymnasium is already imported, else right after its first import.

    ``import dualtwin`` calls this instead of importing Gymnasium itself: Gymnasium (and NumPy under it) cost
    about 0.2 s, which every ``dualtwin`` command (``--help`` included) would pay although most never make an
    env. A program that does use Gymnasium imports it, and the ids are in the registry before that import
    returns, so ``gym.make("dualtwin/...")`` works in either import order.
    """
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(finder, _RegisterAfterImport) for finder in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterImport())


class _RegisterAfterImport(importlib.abc.MetaPathFinder):
    """Finds ``gymnasium`` through the other finders and registers the ids once its module has run."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)  # once: the real finders do the work, now and on any later import
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _ThenRegister(spec.loader)
        return spec


class _ThenRegister(importlib.abc.Loader):
    def __init__(self, loader: Any) -> None:
        self._loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self._loader.create_module(spec)  # type: ignore[no-any-return]

    def exec_module(self, module: ModuleType) -> None:
        self._loader.exec_module(module)
        register_envs()

    def __getattr__(self, name: str) -> Any:  # resource readers and the like: the real loader's
        return getattr(self._loader, name)
