"""The robot client does not trust the server: env options are checked, an unreachable server is one line."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.http_bounds import bounded_client, is_reply_limit
from dualtwin.rl.env import check_task_kwargs
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


@pytest.mark.parametrize("options", [{"x_limit": float("nan")}, {"pole_joint": None}, {"reward_fn": "lambda: 0"}])
def test_served_task_options_get_the_envs_own_check(options: dict[str, Any]) -> None:
    """One check of task options: the client refuses a served one with rl.env.check_task_kwargs's reason under its
    JSON path (it had a copy of that check, whose wording and NaN handling differed)."""
    with pytest.raises(DualtwinError) as client:
        check_env_kwargs(ENV, {"task_kwargs": options})
    with pytest.raises(DualtwinError) as env:
        check_task_kwargs("cartpole_balance", options, "WHERE")
    assert str(client.value) == str(env.value).replace("WHERE", "/v1/info policy.env_kwargs.task_kwargs", 1)


def test_served_task_options_null_is_refused() -> None:
    # The env takes None as no options; a server sends the object it recorded, so null is refused, as before.
    with pytest.raises(DualtwinError, match=r"policy\.env_kwargs\.task_kwargs: expected an object, got NoneType"):
        check_env_kwargs(ENV, {"task_kwargs": None})


class _Handler(BaseHTTPRequestHandler):
    info: dict[str, Any] = {}
    trickle_s = 0.0  # > 0: headers, then one byte of the body every trickle_s seconds (for at most 30 s)
    body_bytes = 0  # > 0: a body of this many spaces instead

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        if self.trickle_s or self.body_bytes:
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(self.body_bytes or 1 << 20))
            self.end_headers()
            try:
                if self.body_bytes:
                    self.wfile.write(b" " * self.body_bytes)
                for _ in range(int(30 / self.trickle_s) if self.trickle_s else 0):
                    self.wfile.write(b" ")
                    self.wfile.flush()
                    time.sleep(self.trickle_s)
            except OSError:  # the client hung up
                pass
            return
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


def test_a_server_whose_reply_never_ends_is_one_error_within_the_timeout(hostile_server: Any) -> None:
    """A byte every 0.2 s keeps every read within the timeout: before, deploy waited for the body forever."""
    url, handler = hostile_server
    handler.trickle_s = 0.2
    start = time.monotonic()
    with pytest.raises(DualtwinError, match=r"--server .*: no answer within 1 s \(ReadTimeout\)"):
        deploy(url, ENV, 1, timeout=1.0)
    assert time.monotonic() - start < 25  # (the server gives up after 30 s)


def test_a_reply_larger_than_the_limit_is_cut_off(hostile_server: Any) -> None:
    import httpx

    url, handler = hostile_server
    handler.body_bytes = 5000
    with bounded_client(httpx.Client, reply_s=10, max_bytes=1000, base_url=url) as http, \
            pytest.raises(httpx.ReadError) as info:
        http.get("/v1/info")
    assert is_reply_limit(info.value) and "larger than 1000 bytes" in str(info.value)
    with bounded_client(httpx.Client, reply_s=10, max_bytes=10_000, base_url=url) as http:  # control
        assert len(http.get("/v1/info").content) == 5000


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
