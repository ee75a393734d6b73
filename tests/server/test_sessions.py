"""Sessions belong to their owner (API key, or client address without keys), are bounded and expire; limits."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from dualtwin.server.app import create_app, exposure_warning, is_loopback
from dualtwin.server.client import frame_payload
from tests.support.images import random_frame
from tests.support.servers import SIZE

KEYS = ["key-robot-a", "key-robot-b", "key-robot-c"]


def body(policy_dir: Path, session: str, **extra: Any) -> dict[str, Any]:
    terms = json.loads((policy_dir / "policy_contract.json").read_text())["observation"]
    return {"session": session, "sensors": {t["name"]: 0.0 for t in terms if t["source"] == "onboard"},
            "frame": frame_payload(random_frame(SIZE)), **extra}


def client(url: str, key: str | None = None, source: str | None = None) -> httpx.Client:
    transport = httpx.HTTPTransport(local_address=source) if source else None
    return httpx.Client(base_url=url, headers={"X-API-Key": key} if key else {}, timeout=10, transport=transport)


def test_another_key_cannot_reset_poison_or_evict_a_robots_session(policy_dir: Path, perception_dir: Path,
                                                                   serve_app: Any) -> None:
    running = serve_app(create_app(policy_dir, perception_dir, api_key=KEYS, max_sessions=4))
    with client(running.url, KEYS[0]) as robot, client(running.url, KEYS[1]) as intruder:
        for step in (1, 2, 3):
            reply = robot.post("/v1/act", json=body(policy_dir, "robot-1", reset=step == 1)).json()
            assert reply["step"] == step
        # The same session id under another key is another session: reset, frames and 10 new ids stay there.
        assert intruder.post("/v1/act", json=body(policy_dir, "robot-1", reset=True)).json()["new_session"]
        for i in range(10):
            intruder.post("/v1/act", json=body(policy_dir, f"flood-{i}"))
        assert intruder.get("/v1/info").json()["sessions"] == 4  # its own bound: its own oldest were dropped
        reply = robot.post("/v1/act", json=body(policy_dir, "robot-1")).json()
        assert reply["step"] == 4 and not reply["new_session"]
        assert robot.get("/v1/info").json()["sessions"] == 1


def test_without_keys_sessions_are_per_client_address(policy_dir: Path, perception_dir: Path,
                                                      serve_app: Any) -> None:
    running = serve_app(create_app(policy_dir, perception_dir, max_sessions=2))
    # Two machines, as far as the server can tell: 127.0.0.1 and 127.0.0.2 (both loopback on Linux).
    with client(running.url) as robot, client(running.url, source="127.0.0.2") as other:
        try:
            other.get("/healthz")
        except httpx.HTTPError as exc:
            pytest.skip(f"cannot use 127.0.0.2 as a source address here: {exc}")
        robot.post("/v1/act", json=body(policy_dir, "robot-1", reset=True))
        assert robot.post("/v1/act", json=body(policy_dir, "robot-1")).json()["step"] == 2
        for session in ("robot-1", "x", "y", "z"):
            assert other.post("/v1/act", json=body(policy_dir, session)).json()["new_session"]
        reply = robot.post("/v1/act", json=body(policy_dir, "robot-1")).json()
        assert reply["step"] == 3 and not reply["new_session"]


def test_idle_sessions_expire_and_the_server_total_is_bounded(policy_dir: Path, perception_dir: Path,
                                                              serve_app: Any) -> None:
    running = serve_app(create_app(policy_dir, perception_dir, api_key=KEYS, max_sessions=2, max_total_sessions=4,
                                   session_idle_s=2.5))
    a, b, c = (client(running.url, key) for key in KEYS)
    with a, b, c:
        for who in (a, b):
            for session in ("s1", "s2"):
                assert who.post("/v1/act", json=body(policy_dir, session)).status_code == 200
        # Full: a third key gets 429 for a new session instead of evicting someone else's.
        refused = c.post("/v1/act", json=body(policy_dir, "s1"))
        assert refused.status_code == 429 and "maximum of 4 sessions" in refused.json()["detail"]
        assert a.post("/v1/act", json=body(policy_dir, "s1")).json()["step"] == 2  # existing ones still served
        time.sleep(3.0)
        # Everything idle for over 2.5 s was dropped: room again, and "s1" starts afresh.
        assert c.post("/v1/act", json=body(policy_dir, "s1")).status_code == 200
        reply = a.post("/v1/act", json=body(policy_dir, "s1")).json()
        assert reply["new_session"] and reply["step"] == 1


def test_request_rate_is_bounded_per_key(policy_dir: Path, perception_dir: Path, serve_app: Any) -> None:
    # 2 requests/s: 12 requests are refused unless each took over half a second, even on a loaded machine.
    running = serve_app(create_app(policy_dir, perception_dir, api_key=KEYS, max_requests_per_s=2))
    with client(running.url, KEYS[0]) as fast, client(running.url, KEYS[1]) as calm:
        codes = [fast.get("/v1/info").status_code for _ in range(12)]
        assert codes[:2] == [200] * 2 and 429 in codes[2:]  # a burst of one second's worth, then 429
        assert calm.get("/v1/info").status_code == 200  # another key has its own budget
        time.sleep(1.0)
        assert fast.get("/v1/info").status_code == 200  # the bucket refills


def test_docs_without_a_key_and_limits_in_info(policy_dir: Path, perception_dir: Path, serve_app: Any) -> None:
    running = serve_app(create_app(policy_dir, perception_dir, max_sessions=3, session_idle_s=30))
    with client(running.url) as anyone:
        assert anyone.get("/docs").status_code == 200
        assert "/v1/act" in anyone.get("/openapi.json").json()["paths"]
        limits = anyone.get("/v1/info").json()["limits"]
        assert limits["max_sessions"] == 3 and limits["session_idle_s"] == 30


def test_serving_beyond_loopback_without_a_key_warns() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost") and is_loopback("127.8.0.1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.4") and not is_loopback("robots.example")
    # serve() prints this once it has bound the socket (a host it cannot bind is refused first, in one line)
    warning = exposure_warning("0.0.0.0", 8000, None)
    assert warning is not None and warning.startswith("warning: serving on 0.0.0.0 without an API key")
    assert exposure_warning("0.0.0.0", 8000, "k") is None and exposure_warning("127.0.0.1", 8000, None) is None
