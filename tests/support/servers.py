"""A real uvicorn server on a free loopback port, and the settings the server tests share."""

from __future__ import annotations

import socket
import threading
import time
from typing import Any

ENV = "dualtwin/CartPole-MuJoCo-Continuous-v0"
SIZE = 32
# One PPO rollout: enough for a real run folder and a real export, not for a good policy.
TINY_PPO = {"n_envs": 2, "n_steps": 256, "batch_size": 256, "n_epochs": 1, "eval_freq": 0, "checkpoint_freq": 0,
            "env_kwargs": {"max_episode_steps": 100}}


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
