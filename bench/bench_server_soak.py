"""RobotServer soak: 60 s of valid and malformed requests from 16 clients, some vanishing mid-request.

Run: ``python bench/bench_server_soak.py`` (or ``make bench``). The server runs in its own process (uvicorn, one
worker, two API keys, as ``dualtwin serve`` runs it); 16 client threads (8 per key) send, for
``DUALTWIN_BENCH_SOAK_SECONDS`` (default 60): valid ``POST /v1/act`` requests (PNG and raw frames, sessions that
churn through the per-key bound), malformed requests of 18 kinds, and requests abandoned half-way (see
:mod:`dualtwin.server.soak`). Goals: no 5xx, every valid request answered with 200, resident memory flat
(growth after warm-up below 10 % or 20 MiB, whichever is larger). No display or ``MUJOCO_GL`` needed.
Models: as ``bench/bench_server.py`` (``DUALTWIN_BENCH_POLICY`` / ``DUALTWIN_BENCH_PERCEPTION`` or made here).
"""

from __future__ import annotations

import importlib.util
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

CLIENTS = 16
KEYS = ["soak-key-one", "soak-key-two"]


def _bench_server() -> Any:
    spec = importlib.util.spec_from_file_location("bench_server", Path(__file__).with_name("bench_server.py"))
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def flat(rss: list[tuple[float, int]]) -> tuple[bool, int]:
    """(memory stayed flat, growth in KiB): last sample against the first (taken after the warm-up)."""
    growth = rss[-1][1] - rss[0][1]
    return growth <= max(0.10 * rss[0][1], 20 * 1024), growth


def main() -> dict[str, Any]:
    import subprocess
    import sys

    from dualtwin.perception.estimator import StateEstimator
    from dualtwin.perception.onnx_policy import OnnxPolicy
    from dualtwin.server.soak import soak

    bench = _bench_server()
    seconds = float(os.environ.get("DUALTWIN_BENCH_SOAK_SECONDS", "60"))
    print(f"RobotServer soak ({CLIENTS} clients, {seconds:g} s; shared machine: other jobs may be running)")
    with tempfile.TemporaryDirectory(prefix="dualtwin-bench-soak-") as tmp:
        policy, perception = bench.models(Path(tmp))
        estimator = StateEstimator.load(perception)
        sensors = OnnxPolicy.load_exported(policy).onboard
        port = bench.free_port()
        code = ("from dualtwin.server.app import serve; "
                f"serve({str(policy)!r}, {str(perception)!r}, host='127.0.0.1', port={port}, api_key={KEYS!r}, "
                "log_level='error')")  # uvicorn warns about every invalid request otherwise
        server = subprocess.Popen([sys.executable, "-c", code])
        try:
            import httpx

            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                try:
                    if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.1)
            start = time.perf_counter()
            report = soak("127.0.0.1", port, seconds=seconds, clients=CLIENTS, width=estimator.width,
                          height=estimator.height, sensors=sensors, keys=KEYS, server_pid=server.pid)
            wall = time.perf_counter() - start
            alive = server.poll() is None
        finally:
            server.terminate()
            server.wait(timeout=10)
    result = report.to_dict()
    ok_memory, growth = flat(report.rss_kib)
    result.update(wall_s=round(wall, 1), server_alive=alive, memory_flat=ok_memory, rss_growth_kib=growth,
                  load_average=list(os.getloadavg()))
    fivexx = sum(v for k, v in report.statuses.items() if k.split(":")[-1].startswith("5"))
    before, after = report.rss_kib[0][1], report.rss_kib[-1][1]
    print(f"  valid requests: {report.valid_ok} of {report.valid_sent} answered 200; malformed: "
          f"{report.malformed_sent}; abandoned mid-request: {report.abandoned}; 5xx answers: {fivexx}")
    print(f"  server RSS after warm-up {before / 1024:.1f} MiB, after {seconds:g} s {after / 1024:.1f} MiB "
          f"(growth {growth / 1024:+.1f} MiB; samples "
          f"{', '.join(f'{v / 1024:.0f}' for _, v in report.rss_kib)} MiB)")
    print("  statuses: " + json.dumps(result["statuses"]))
    print(f"  -> {'passed' if report.passed and ok_memory and alive else 'FAILED'} "
          f"(no 5xx, every valid request answered, memory flat, server alive)")
    return result


if __name__ == "__main__":
    main()
