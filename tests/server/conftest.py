"""Fixtures for the server tests: real exported models and a real uvicorn server on 127.0.0.1."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support.servers import ENV, SIZE, TINY_PPO, RunningServer

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
pytest.importorskip("stable_baselines3")

# No MUJOCO_GL here: without a display, `import dualtwin` picks EGL (else OSMesa) itself (tests/test_headless.py).


@pytest.fixture(scope="session")
def policy_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real ``export_policy`` output (policy.onnx + policy_contract.json) of a tiny PPO run."""
    import torch

    from dualtwin.rl.export import export_policy
    from dualtwin.rl.train import train

    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("policy")
    run = train(ENV, TINY_PPO, root / "run", seed=0, total_timesteps=512, progress_bar=False)
    export_policy(run, root / "export")
    return root / "export"


@pytest.fixture(scope="session")
def perception_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real collect + train_perception output at 32x32 (one epoch: the server only needs a valid model)."""
    import torch

    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import train_perception

    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("perception")
    try:
        data = collect(ENV, 2, root / "data", controller="random", max_steps=12, width=SIZE, height=SIZE)
    except Exception as exc:  # noqa: BLE001 - no headless GL: the server tests cannot build a model
        pytest.skip(f"headless rendering unavailable (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {exc}")
    return train_perception(data, root / "model", epochs=1, seed=0, threads=1, holdout=0.5)


@pytest.fixture
def serve_app() -> Iterator[Callable[[Any], RunningServer]]:
    servers: list[RunningServer] = []

    def start(app: Any) -> RunningServer:
        server = RunningServer(app).__enter__()
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.__exit__()
