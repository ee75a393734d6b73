"""Settings and helpers shared by the RL tests: the tiny PPO config, env-id parameters, a tiny training run.

Import it after skipping on missing gymnasium / stable_baselines3 (``tests/rl/conftest.py`` does).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from typing import Any

import pytest

import dualtwin.rl  # registers the env ids

WEBOTS_TWIN = importlib.util.find_spec("dualtwin.twins.webots") is not None
# A few thousand steps: enough for every artifact and the parity checks, not for a good policy.
TINY = {"n_envs": 2, "n_steps": 256, "batch_size": 256, "n_epochs": 2, "eval_freq": 1024, "eval_episodes": 2,
        "checkpoint_freq": 1024, "env_kwargs": {"max_episode_steps": 200}}


def env_param(env_id: str) -> object:
    """Webots ids skip (cleanly, with the reason) only while the Webots twin module does not exist yet."""
    marks = [] if "Webots" not in env_id or WEBOTS_TWIN else [
        pytest.mark.skip(reason="dualtwin.twins.webots is not available yet")]
    return pytest.param(env_id, marks=marks, id=env_id.split("/")[-1])


ALL_IDS = [env_param(i) for i in dualtwin.rl.registered_ids()]


def train_tiny(tmp: Path, env_id: str, steps: int, extra: dict[str, object] | None = None, **kwargs: Any) -> Path:
    """A tiny PPO run (``TINY`` with ``extra`` over it) of ``steps`` steps in ``tmp``."""
    import torch

    from dualtwin.rl.train import train

    torch.set_num_threads(1)
    return train(env_id, {**TINY, **(extra or {})}, tmp, seed=0, total_timesteps=steps, progress_bar=False,
                 **kwargs)


# The aligned source twin: a heavier pole (tests/rl/test_transfer.py's stand-in target has the same).
ALIGNED_KNOBS = {"schema": "dualtwin.knobs/1", "twin": "mujoco",
                 "knobs": {"body.pole.mass": {"nominal": 0.2, "fitted": 0.3}}}


def can_render() -> bool:
    return os.environ.get("MUJOCO_GL", "") in ("egl", "osmesa")
