"""Fixtures for the RL tests: one tiny trained run per action type, shared by the whole session."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("stable_baselines3")

from tests.support.rl_runs import ALIGNED_KNOBS, TINY, train_tiny  # noqa: E402 - after the skips


@pytest.fixture(autouse=True)
def _one_torch_thread() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_config() -> dict[str, object]:
    return dict(TINY)


@pytest.fixture(scope="session")
def discrete_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train_tiny(tmp_path_factory.mktemp("discrete") / "run", "dualtwin/CartPole-MuJoCo-v0", 2048)


@pytest.fixture(scope="session")
def aligned_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("aligned")
    knobs = folder / "knobs.json"
    knobs.write_text(json.dumps(ALIGNED_KNOBS))
    return train_tiny(folder / "run", "dualtwin/CartPole-MuJoCo-v0", 1024, aligned=knobs)


@pytest.fixture(scope="session")
def dr_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    ranges = {"knobs": {"body.pole.mass": {"low": 0.15, "high": 0.35}}}
    return train_tiny(tmp_path_factory.mktemp("dr") / "run", "dualtwin/CartPole-MuJoCo-v0", 1024, dr_ranges=ranges)


@pytest.fixture(scope="session")
def continuous_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    # gSDE, as in the bundled config, so the export parity covers its policy head too.
    return train_tiny(tmp_path_factory.mktemp("continuous") / "run", "dualtwin/CartPole-MuJoCo-Continuous-v0", 2048,
                  {"use_sde": True, "sde_sample_freq": -1, "policy_kwargs": {"log_std_init": -3.0}})


