"""Fixtures for the server tests: real exported models and a real uvicorn server on 127.0.0.1."""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
pytest.importorskip("stable_baselines3")

# No MUJOCO_GL here: without a display, `import dualtwin` picks EGL (else OSMesa) itself (tests/test_headless.py).

ENV = "dualtwin/CartPole-MuJoCo-Continuous-v0"
SIZE = 32
# One PPO rollout: enough for a real run folder and a real export, not for a good policy.
TINY_PPO = {"n_envs": 2, "n_steps": 256, "batch_size": 256, "n_epochs": 1, "eval_freq": 0, "checkpoint_freq": 0,
            "env_kwargs": {"max_episode_steps": 100}}


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


class RunningServer:
    """uvicorn serving an app from a background thread on a free loopback port."""

    def __init__(self, app: Any) -> None:
        import uvicorn

        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on")
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]}, daemon=True)

    def __enter__(self) -> RunningServer:
        self.thread.start()
        deadline = time.monotonic() + 20
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("uvicorn did not start")
            time.sleep(0.02)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()


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
