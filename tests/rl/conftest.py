"""Fixtures for the RL tests: one tiny trained run per action type, shared by the whole session."""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("stable_baselines3")

import dualtwin.rl  # noqa: E402 - registers the env ids

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


@pytest.fixture(autouse=True)
def _one_torch_thread() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_config() -> dict[str, object]:
    return dict(TINY)


def _train(tmp: Path, env_id: str, steps: int, extra: dict[str, object] | None = None, **kwargs: Any) -> Path:
    import torch

    from dualtwin.rl.train import train

    torch.set_num_threads(1)
    return train(env_id, {**TINY, **(extra or {})}, tmp, seed=0, total_timesteps=steps, progress_bar=False,
                 **kwargs)


@pytest.fixture(scope="session")
def discrete_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _train(tmp_path_factory.mktemp("discrete") / "run", "dualtwin/CartPole-MuJoCo-v0", 2048)


# The aligned source twin: a heavier pole (tests/rl/test_transfer.py's stand-in target has the same).
ALIGNED_KNOBS = {"schema": "dualtwin.knobs/1", "twin": "mujoco",
                 "knobs": {"body.pole.mass": {"nominal": 0.2, "fitted": 0.3}}}


@pytest.fixture(scope="session")
def aligned_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("aligned")
    knobs = folder / "knobs.json"
    knobs.write_text(json.dumps(ALIGNED_KNOBS))
    return _train(folder / "run", "dualtwin/CartPole-MuJoCo-v0", 1024, aligned=knobs)


@pytest.fixture(scope="session")
def dr_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    ranges = {"knobs": {"body.pole.mass": {"low": 0.15, "high": 0.35}}}
    return _train(tmp_path_factory.mktemp("dr") / "run", "dualtwin/CartPole-MuJoCo-v0", 1024, dr_ranges=ranges)


@pytest.fixture(scope="session")
def continuous_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    # gSDE, as in the bundled config, so the export parity covers its policy head too.
    return _train(tmp_path_factory.mktemp("continuous") / "run", "dualtwin/CartPole-MuJoCo-Continuous-v0", 2048,
                  {"use_sde": True, "sde_sample_freq": -1, "policy_kwargs": {"log_std_init": -3.0}})


def can_render() -> bool:
    return os.environ.get("MUJOCO_GL", "") in ("egl", "osmesa")
