"""The robot client does not trust the server: env options are checked, an unreachable server is one line."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.server.client import check_env_kwargs, deploy

ENV = "dualtwin/CartPole-MuJoCo-Continuous-v0"
ROOT = Path(__file__).resolve().parents[2]


def test_env_kwargs_a_training_run_records_are_accepted() -> None:
    kwargs = {"continuous": True, "control_period": 0.032, "knobs": {"joint.pole_hinge.damping": 0.05},
              "task_kwargs": {"cart_velocity": "ground_truth", "terminate_on_fall": True, "x_limit": 2}}
    assert check_env_kwargs(ENV, kwargs) == kwargs
    assert check_env_kwargs(ENV, None) == {} and check_env_kwargs(ENV, {}) == {}


BAD_KWARGS = {
    # The robot is the user's: a server naming a binding file would make the client read any path.
    "robot path": ({"robot": "/etc/passwd"}, "policy.env_kwargs.robot: not an option"),
    "twin": ({"twin": "webots"}, "policy.env_kwargs.twin: not an option"),
    "render option": ({"render_mode": "human"}, "policy.env_kwargs.render_mode: not an option"),
    "unknown": ({"exec": "import os"}, "policy.env_kwargs.exec: not an option"),
    "knob as text": ({"knobs": {"joint.pole_hinge.damping": "0.05"}}, "policy.env_kwargs.knobs"),
    "knob not finite": ({"knobs": {"joint.pole_hinge.damping": float("inf")}}, "finite"),
    "period as text": ({"control_period": "0.032"}, "policy.env_kwargs.control_period"),
    "negative period": ({"control_period": -1.0}, "must be > 0"),
    "bool as int": ({"continuous": 1}, "policy.env_kwargs.continuous"),
    "task option unknown": ({"task_kwargs": {"reward_fn": "lambda: 0"}}, "task_kwargs.reward_fn: not an option"),
    "task option wrong value": ({"task_kwargs": {"cart_velocity": "magic"}}, "task_kwargs.cart_velocity"),
    "task options not an object": ({"task_kwargs": [1]}, "task_kwargs: expected an object"),
    "not an object": (["robot"], "expected an object"),
}


@pytest.mark.parametrize("name", sorted(BAD_KWARGS))
def test_bad_env_kwargs_are_one_line_errors(name: str) -> None:
    kwargs, words = BAD_KWARGS[name]
    with pytest.raises(DualtwinError, match="policy.env_kwargs") as info:
        check_env_kwargs(ENV, kwargs)
    assert words in str(info.value) and "\n" not in str(info.value)


class _Handler(BaseHTTPRequestHandler):
    info: dict[str, Any] = {}

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        data = json.dumps(self.info if self.path == "/v1/info" else {"detail": "not found"}).encode()
        self.send_response(200 if self.path == "/v1/info" else 404)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, *args: Any) -> None:
        pass


@pytest.fixture
def hostile_server() -> Iterator[tuple[str, type[_Handler]]]:
    """A real HTTP server on loopback that answers /v1/info with whatever the test puts in it."""
    handler = type("Handler", (_Handler,), {"info": {}})
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}", handler
    server.shutdown()
    server.server_close()


def info_with(env_kwargs: Any) -> dict[str, Any]:
    return {"policy": {"observation": [{"name": "cart_position", "source": "onboard"}], "action": {},
                       "control_period_s": 0.032, "env_kwargs": env_kwargs, "onnx_sha256": None},
            "perception": {"resolution": [32, 32], "camera": {"name": "side"}}}


def test_deploy_refuses_a_servers_env_kwargs_before_building_the_env(hostile_server: Any, tmp_path: Path) -> None:
    url, handler = hostile_server
    handler.info = info_with({"robot": str(tmp_path / "evil.yaml")})
    # A local policy, so that the client does not need /v1/policy.onnx: the refusal comes first anyway.
    with pytest.raises(DualtwinError, match=r"policy\.env_kwargs\.robot: not an option"):
        deploy(url, ENV, 1, policy_dir=tmp_path)
    handler.info = {"hello": "not a RobotServer"}
    with pytest.raises(DualtwinError, match="policy is missing"):
        deploy(url, ENV, 1)


def closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_unreachable_server_is_one_line_naming_the_url() -> None:
    url = f"http://127.0.0.1:{closed_port()}"
    with pytest.raises(DualtwinError, match="cannot reach the RobotServer") as info:
        deploy(url, ENV, 1)
    assert url in str(info.value)
    done = subprocess.run([sys.executable, "-c", "from dualtwin.cli import main; main()", "deploy", "--server", url,
                           "--env", ENV, "--episodes", "1"], capture_output=True, text=True, timeout=120, cwd=ROOT,
                          check=False)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and url in lines[0] and lines[0].startswith("error: ")
    with pytest.raises(DualtwinError, match="--server"):
        deploy("127.0.0.1:8000", ENV, 1)  # no scheme
