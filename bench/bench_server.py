"""RobotServer benchmark: latency and throughput of ``POST /v1/act`` with a 64x64 frame on CPU, over loopback.

Run: ``python bench/bench_server.py`` (or ``make bench``). The server runs in its own process (uvicorn, one
worker, as ``dualtwin serve`` runs it); the clients are threads of this process with lean keep-alive
``http.client`` connections (the numbers are the server's, not a client library's; httpx is measured once too).

Latency and throughput are measured separately, as load generators such as wrk2 and Locust do: with closed-loop
clients that never pause, latency is just clients / throughput (Little's law), so a saturating test measures
throughput, not latency.

* sequential: one client, one request at a time (PNG frames, then raw frames): p50 / p99;
* offered load (the latency goal): 8 clients that together send at a fixed rate (default 200 requests/s, the
  goal) on an open-loop schedule, request i of the run due at ``start + i / rate`` and sent by client
  ``i mod 8``. Latency counts from the *scheduled* send time, so a request that has to wait for its client's
  previous one (the server fell behind) is charged for the wait: coordinated omission is not hidden. Reports
  p50 / p99 / p99.9, the rate actually achieved, and how many requests were sent late;
* saturation (the throughput goal): 8 closed-loop clients sending back to back: maximum requests/s (and the
  latency at that load, for reference only).

Every load run is bounded in requests and in time. Goals: p50 <= 5 ms and p99 <= 20 ms at the offered load with
8 clients, and >= 200 requests/s at saturation. Models: ``DUALTWIN_BENCH_POLICY`` (an exported policy folder) and
``DUALTWIN_BENCH_PERCEPTION`` (a perception model folder, 64x64) if set; else the reference policy and a
perception model trained for one epoch on a small dataset (speed does not depend on the weights). Settings:
``DUALTWIN_BENCH_SERVER_RATE`` (offered requests/s, default 200), ``DUALTWIN_BENCH_SERVER_SECONDS`` (length of the
offered-load run, default 10 s), ``DUALTWIN_BENCH_SERVER_REQUESTS`` (requests per client at saturation, default
150).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

GOALS = {"p50_ms": 5.0, "p99_ms": 20.0, "requests_per_s": 200.0}
CLIENTS = 8
LOAD_TIME_LIMIT_S = 120.0
#: Open-loop runs stop this long after their last scheduled request, whatever is still outstanding.
OPEN_LOOP_GRACE_S = 30.0


def models(root: Path) -> tuple[Path, Path]:
    """Policy and perception folders: from the environment, or made here (64x64, reference policy)."""
    policy = os.environ.get("DUALTWIN_BENCH_POLICY")
    perception = os.environ.get("DUALTWIN_BENCH_PERCEPTION")
    if policy is None:
        from dualtwin.perception.reference_policy import export_reference_policy

        export_reference_policy(root / "policy")
        policy = str(root / "policy")
    if perception is None:
        # No MUJOCO_GL needed: without a display, `import dualtwin` picks EGL (else OSMesa) itself.
        from dualtwin.perception.dataset import collect
        from dualtwin.perception.model import train_perception

        data = collect("dualtwin/CartPole-MuJoCo-Continuous-v0", 4, root / "data", max_steps=40)
        train_perception(data, root / "perception", epochs=1, threads=1)
        perception = str(root / "perception")
    return Path(policy), Path(perception)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def start_server(policy: Path, perception: Path, port: int) -> subprocess.Popen[bytes]:
    code = ("from dualtwin.server.app import serve; "
            f"serve({str(policy)!r}, {str(perception)!r}, host='127.0.0.1', port={port}, log_level='warning')")
    process = subprocess.Popen([sys.executable, "-c", code])
    import httpx

    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                return process
        except httpx.HTTPError:
            time.sleep(0.1)
    process.kill()
    raise RuntimeError("the server did not start within 60 s")


def percentiles(seconds: list[float]) -> dict[str, Any]:
    ms = np.asarray(seconds) * 1000.0
    return {"p50_ms": round(float(np.percentile(ms, 50)), 2), "p99_ms": round(float(np.percentile(ms, 99)), 2),
            "p999_ms": round(float(np.percentile(ms, 99.9)), 2), "max_ms": round(float(ms.max()), 2),
            "mean_ms": round(float(ms.mean()), 2), "requests": int(len(ms))}


def body(session: str, payload: dict[str, Any], sensors: list[str], reset: bool) -> dict[str, Any]:
    return {"session": session, "sensors": dict.fromkeys(sensors, 0.0), "frame": payload, "reset": reset}


class Client:
    """A lean keep-alive HTTP client (``http.client``): the numbers are the server's, not a client library's."""

    def __init__(self, port: int) -> None:
        import http.client

        self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)

    def post(self, body: dict[str, Any] | bytes) -> tuple[int, float]:
        data = body if isinstance(body, bytes) else json.dumps(body).encode()
        start = time.perf_counter()
        self.conn.request("POST", "/v1/act", body=data, headers={"Content-Type": "application/json"})
        reply = self.conn.getresponse()
        reply.read()
        return reply.status, time.perf_counter() - start

    def close(self) -> None:
        self.conn.close()


def sequential(port: int, payload: dict[str, Any], sensors: list[str], n: int) -> dict[str, float]:
    client = Client(port)
    times = []
    for i in range(n + 20):
        status, elapsed = client.post(body("seq", payload, sensors, i == 0))
        if status != 200:
            raise RuntimeError(f"POST /v1/act answered {status}")
        if i >= 20:  # warm-up: connection, first ONNX runs
            times.append(elapsed)
    client.close()
    return percentiles(times)


def with_httpx(url: str, payload: dict[str, Any], sensors: list[str], n: int) -> dict[str, float]:
    """The same through httpx, which adds its own per-request cost (about 1-2 ms here)."""
    import httpx

    times = []
    with httpx.Client(base_url=url, timeout=10) as client:
        for i in range(n + 20):
            start = time.perf_counter()
            client.post("/v1/act", json=body("httpx", payload, sensors, i == 0)).raise_for_status()
            if i >= 20:
                times.append(time.perf_counter() - start)
    return percentiles(times)


def offered_load(port: int, payload: dict[str, Any], sensors: list[str], rate: float, seconds: float
                 ) -> dict[str, Any]:
    """8 clients sending ``rate`` requests/s together on a fixed schedule; latency from the scheduled time."""
    total = max(CLIENTS, int(round(rate * seconds)))
    from_schedule: list[float] = []
    service: list[float] = []
    late: list[int] = []
    failures: list[int] = []
    lock = threading.Lock()
    barrier = threading.Barrier(CLIENTS + 1)
    start_at: list[float] = []

    def client_loop(i: int) -> None:
        client = Client(port)
        data = json.dumps(body(f"open-{i}", payload, sensors, False)).encode()  # encoded once: client cost off
        client.post(body(f"open-{i}", payload, sensors, True))
        barrier.wait()
        start = start_at[0]
        for j in range(i, total, CLIENTS):
            due = start + j / rate
            now = time.perf_counter()
            if now < due:
                time.sleep(due - now)
            elif now - due > 1e-3:
                with lock:
                    late.append(j)
            if time.perf_counter() > start + seconds + OPEN_LOOP_GRACE_S:
                break
            status, elapsed = client.post(data)
            done = time.perf_counter()
            with lock:
                from_schedule.append(done - due)
                service.append(elapsed)
                if status != 200:
                    failures.append(status)
        client.close()

    threads = [threading.Thread(target=client_loop, args=(i,)) for i in range(CLIENTS)]
    for t in threads:
        t.start()
    start_at.append(time.perf_counter() + 0.05)
    barrier.wait()
    for t in threads:
        t.join()
    wall = time.perf_counter() - start_at[0]
    return {"clients": CLIENTS, "offered_per_s": rate, "achieved_per_s": round(len(from_schedule) / wall, 1),
            "wall_s": round(wall, 2), "late_sends": len(late), "failures": len(failures),
            **percentiles(from_schedule), "service": percentiles(service)}


def saturation(port: int, payload: dict[str, Any], sensors: list[str], per_client: int) -> dict[str, Any]:
    """8 closed-loop clients, back to back: the maximum throughput (latency here is clients / throughput)."""
    times: list[list[float]] = [[] for _ in range(CLIENTS)]
    failures: list[int] = []
    deadline = time.monotonic() + LOAD_TIME_LIMIT_S
    barrier = threading.Barrier(CLIENTS + 1)

    def client_loop(i: int) -> None:
        client = Client(port)
        client.post(body(f"load-{i}", payload, sensors, True))
        barrier.wait()
        for _ in range(per_client):
            if time.monotonic() > deadline:
                break
            status, elapsed = client.post(body(f"load-{i}", payload, sensors, False))
            times[i].append(elapsed)
            if status != 200:
                failures.append(status)
                break
        client.close()

    threads = [threading.Thread(target=client_loop, args=(i,)) for i in range(CLIENTS)]
    for t in threads:
        t.start()
    barrier.wait()
    start = time.perf_counter()
    for t in threads:
        t.join()
    wall = time.perf_counter() - start
    flat = [t for per in times for t in per]
    return {"clients": CLIENTS, "requests_per_s": round(len(flat) / wall, 1), "wall_s": round(wall, 2),
            "failures": len(failures), **percentiles(flat)}


def main() -> dict[str, Any]:
    from dualtwin.perception.estimator import StateEstimator
    from dualtwin.perception.onnx_policy import OnnxPolicy
    from dualtwin.server.client import frame_payload

    print("RobotServer benchmark (uvicorn, 1 worker, loopback; shared machine: other jobs may be running)")
    with tempfile.TemporaryDirectory(prefix="dualtwin-bench-server-") as tmp:
        policy, perception = models(Path(tmp))
        estimator = StateEstimator.load(perception)
        sensors = OnnxPolicy.load_exported(policy).onboard
        frame = np.random.default_rng(0).integers(0, 255, (estimator.height, estimator.width, 3), dtype=np.uint8)
        port = free_port()
        server = start_server(policy, perception, port)
        url = f"http://127.0.0.1:{port}"
        try:
            per_client = int(os.environ.get("DUALTWIN_BENCH_SERVER_REQUESTS", "150"))
            rate = float(os.environ.get("DUALTWIN_BENCH_SERVER_RATE", "200"))
            seconds = float(os.environ.get("DUALTWIN_BENCH_SERVER_SECONDS", "10"))
            results: dict[str, Any] = {"frame": f"{estimator.width}x{estimator.height}", "goals": GOALS,
                                       "cpu_count": os.cpu_count(), "load_average": list(os.getloadavg())}
            for fmt in ("png", "raw"):
                payload = frame_payload(frame, fmt)
                seq = sequential(port, payload, sensors, 300)
                offered = offered_load(port, payload, sensors, rate, seconds)
                conc = saturation(port, payload, sensors, per_client)
                results[fmt] = {"sequential": seq, "offered": offered, "saturation": conc}
                ok = (offered["p50_ms"] <= GOALS["p50_ms"] and offered["p99_ms"] <= GOALS["p99_ms"]
                      and offered["failures"] == 0 and conc["requests_per_s"] >= GOALS["requests_per_s"])
                print(f"  {fmt:>3} frame {results['frame']}: 1 client p50 {seq['p50_ms']:.2f} ms, p99 "
                      f"{seq['p99_ms']:.2f} ms")
                print(f"      {CLIENTS} clients offering {rate:.0f} req/s (open loop, {offered['requests']} requests, "
                      f"achieved {offered['achieved_per_s']:.0f}/s, {offered['late_sends']} sent > 1 ms late): "
                      f"p50 {offered['p50_ms']:.2f} ms, p99 {offered['p99_ms']:.2f} ms, p99.9 "
                      f"{offered['p999_ms']:.2f} ms, {offered['failures']} failures")
                print(f"      {CLIENTS} clients saturating: {conc['requests_per_s']:.0f} req/s ({conc['requests']} requests "
                      f"in {conc['wall_s']:.1f} s; latency there p50 {conc['p50_ms']:.2f} ms = clients/throughput), "
                      f"{conc['failures']} failures -> goals {'met' if ok else 'NOT met'}")
            results["png_httpx_client"] = with_httpx(url, frame_payload(frame, "png"), sensors, 200)
            print(f"  png through an httpx client instead: p50 {results['png_httpx_client']['p50_ms']:.2f} ms, "
                  f"p99 {results['png_httpx_client']['p99_ms']:.2f} ms (client-side overhead included)")
        finally:
            server.terminate()
            server.wait(timeout=10)
    print(f"  load average at start: {results['load_average']} on {results['cpu_count']} CPUs")
    return results


if __name__ == "__main__":
    main()
