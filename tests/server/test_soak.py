"""A bounded soak of a real RobotServer process (the 60 s version is ``bench/bench_server_soak.py``)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from dualtwin.server.soak import soak
from tests.support.servers import SIZE

KEYS = ["soak-a", "soak-b"]
SECONDS = 12.0


def test_soak_16_clients_valid_malformed_and_abandoned(policy_dir: Path, perception_dir: Path) -> None:
    with httpx.Client() as probe:  # a free loopback port
        import socket

        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        code = ("from dualtwin.server.app import serve; "
                f"serve({str(policy_dir)!r}, {str(perception_dir)!r}, host='127.0.0.1', port={port}, "
                f"api_key={KEYS!r}, max_body_bytes=64 * 1024, max_sessions=8, log_level='error')")
        server = subprocess.Popen([sys.executable, "-c", code])
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    if probe.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    pass
                assert time.monotonic() < deadline and server.poll() is None, "the server did not start"
                time.sleep(0.1)
            sensors = [t["name"] for t in json.loads((policy_dir / "policy_contract.json").read_text())["observation"]
                       if t["source"] == "onboard"]
            # Paced clients: the point is many clients and kinds of abuse at once, not saturating a shared CPU.
            report = soak("127.0.0.1", port, seconds=SECONDS, clients=16, width=SIZE, height=SIZE, sensors=sensors,
                          keys=KEYS, max_body_bytes=64 * 1024, server_pid=server.pid, pace_s=0.01, warmup_s=1.0)
            # Still serving normally afterwards.
            assert probe.get(f"http://127.0.0.1:{port}/v1/info", headers={"X-API-Key": KEYS[0]}).status_code == 200
            assert server.poll() is None
        finally:
            server.terminate()
            server.wait(timeout=10)
    statuses = report.statuses
    assert not report.server_errors, report.server_errors
    assert report.valid_sent > 200 and report.valid_ok == report.valid_sent, report.valid_failures[:5]
    assert report.malformed_sent > 100 and report.abandoned > 30
    # Every malformed kind was answered with a 4xx (none was merely dropped), nothing with a 5xx.
    codes = {kind: int(status) for kind, status in (k.split(":") for k in statuses) if status != "None"}
    assert len([k for k, c in codes.items() if k.startswith("malformed") and 400 <= c < 500]) >= 17, statuses
    assert all(code < 500 for code in codes.values())
    before, after = report.rss_kib[0][1], report.rss_kib[-1][1]
    assert after - before < max(0.10 * before, 20 * 1024), report.rss_kib  # flat memory (KiB)
    if not report.passed:
        pytest.fail(json.dumps(report.to_dict())[:2000])
