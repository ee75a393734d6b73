"""Soak a running RobotServer: many clients, valid and malformed requests, clients that vanish mid-request.

Used by ``bench/bench_server_soak.py`` (60 s) and the tests (a short run). Each client thread runs until the
deadline, choosing by its own seeded generator between

* a valid ``POST /v1/act`` on one of its sessions (PNG or raw frame; now and then a fresh session id, so
  sessions churn through the per-key bound), on a keep-alive connection;
* a malformed request on a fresh connection (bad JSON, wrong schema, bad base64, a GIF, a frame of the wrong
  size, a PNG bomb header, an oversized body, an invalid Content-Length, a wrong key, a wrong method or path,
  non-finite or float32-overflowing sensors, bytes that are not HTTP);
* a request abandoned half-way (headers only, half a body, or the whole request but no wait for the answer).

The report counts requests by kind and status; the server passes when no answer is a 5xx and every valid
request got a 200. The server's resident memory (``VmRSS`` from ``/proc``) is sampled throughout.
"""

from __future__ import annotations

import base64
import http.client
import json
import socket
import struct
import threading
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


def rss_kib(pid: int) -> int | None:
    """Resident set size of process ``pid`` in KiB (Linux ``/proc``), or None where unavailable."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


@dataclass
class SoakReport:
    seconds: float
    clients: int
    valid_sent: int = 0
    valid_ok: int = 0
    valid_failures: list[str] = field(default_factory=list)
    malformed_sent: int = 0
    abandoned: int = 0
    statuses: Counter[str] = field(default_factory=Counter)
    server_errors: list[str] = field(default_factory=list)
    rss_kib: list[tuple[float, int]] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.server_errors and not self.valid_failures and self.valid_ok == self.valid_sent > 0

    def to_dict(self) -> dict[str, Any]:
        return {"seconds": self.seconds, "clients": self.clients, "valid_sent": self.valid_sent,
                "valid_ok": self.valid_ok, "valid_failures": self.valid_failures[:20],
                "malformed_sent": self.malformed_sent, "abandoned": self.abandoned,
                "statuses": dict(sorted(self.statuses.items())), "server_errors": self.server_errors[:20],
                "rss_kib": self.rss_kib, "passed": self.passed}


def _png(frame: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(frame).save(buffer, format="PNG", compress_level=1)
    return buffer.getvalue()


def _png_bomb_header() -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", 60_000, 60_000, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\x00" * 64))


def _request(path: str, body: bytes, headers: dict[str, str], method: str = "POST") -> bytes:
    lines = [f"{method} {path} HTTP/1.1", "Host: soak", *(f"{k}: {v}" for k, v in headers.items())]
    return ("\r\n".join(lines) + "\r\n\r\n").encode() + body


class _Plan:
    """The requests a soak sends, prepared once (encoding is not what is being measured)."""

    def __init__(self, width: int, height: int, sensors: list[str], key: str | None, max_body_bytes: int) -> None:
        # Malformed requests go on their own connection, closed by the server after its answer.
        rng = np.random.default_rng(0)
        frame = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
        self.sensors = dict.fromkeys(sensors, 0.01)
        self.png = base64.b64encode(_png(frame)).decode()
        self.raw = {"data_base64": base64.b64encode(frame.tobytes()).decode(), "shape": [height, width, 3],
                    "dtype": "uint8"}
        self.key = key
        self.auth = {"X-API-Key": key} if key else {}
        good = {"session": "m", "sensors": self.sensors, "frame": {"png_base64": self.png}}
        small = _png(rng.integers(0, 255, (height + 3, width, 3), dtype=np.uint8))

        def js(value: Any) -> bytes:
            return json.dumps(value).encode()

        json_headers = {"Content-Type": "application/json", **self.auth}
        once = {**json_headers, "Connection": "close"}
        # (name, raw HTTP request bytes): each is refused with a 4xx (or the connection is closed).
        bad_bodies: dict[str, bytes] = {
            "invalid json": b"{not json",
            "not an object": js([1, 2, 3]),
            "missing frame": js({"session": "m", "sensors": self.sensors}),
            "bad base64": js({**good, "frame": {"png_base64": "@@@"}}),
            "gif": js({**good, "frame": {"png_base64": base64.b64encode(b"GIF89a" + b"\x00" * 40).decode()}}),
            "wrong size png": js({**good, "frame": {"png_base64": base64.b64encode(small).decode()}}),
            "png bomb header": js({**good, "frame": {"png_base64": base64.b64encode(_png_bomb_header()).decode()}}),
            "huge raw shape": js({**good, "frame": {**self.raw, "shape": [100_000, 100_000, 3]}}),
            "nan sensor": js(good).replace(b"0.01", b"NaN", 1),
            "float32 overflow": js({**good, "sensors": dict.fromkeys(sensors, 1e300)}),
            "unknown sensor": js({**good, "sensors": {**self.sensors, "secret": 1.0}}),
            "bad session id": js({**good, "session": "../../etc"}),
            "oversized": js({**good, "pad": "x" * (max_body_bytes + 10)}),
        }
        self.malformed: list[tuple[str, bytes]] = [
            (name, _request("/v1/act", data, {**once, "Content-Length": str(len(data))}))
            for name, data in bad_bodies.items()]
        data = js(good)
        self.malformed += [
            ("bad content-length", _request("/v1/act", data, {**once, "Content-Length": "12x"})),
            ("wrong method", _request("/v1/act", b"", {**self.auth, "Connection": "close"}, method="GET")),
            ("unknown path", _request("/v1/nothing", data, {**once, "Content-Length": str(len(data))})),
            ("not http", b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + bytes(range(64)) + b"\r\n\r\n"),
        ]
        if key:
            self.malformed.append(("wrong key", _request("/v1/act", data, {
                **once, "X-API-Key": key + "x", "Content-Length": str(len(data))})))
        self.abandon_body = data
        self.json_headers = json_headers

    def valid(self, session: str, raw: bool, reset: bool) -> bytes:
        frame = self.raw if raw else {"png_base64": self.png}
        return json.dumps({"session": session, "sensors": self.sensors, "frame": frame, "reset": reset}).encode()


def _read_status(sock: socket.socket) -> int | None:
    """The status code of the answer on ``sock`` (None if the server just closed it); reads to the end."""
    data = b""
    sock.settimeout(30)
    try:
        while b"\r\n" not in data:
            chunk = sock.recv(65536)
            if not chunk:
                break
            data += chunk
        while sock.recv(65536):
            pass
    except (TimeoutError, ConnectionError, OSError):
        pass
    if not data.startswith(b"HTTP/1."):
        return None
    return int(data.split(b" ", 2)[1])


def soak(host: str, port: int, *, seconds: float, clients: int, width: int, height: int, sensors: list[str],
         key: str | None = None, keys: list[str] | None = None, max_body_bytes: int = 1 << 20,
         server_pid: int | None = None, pace_s: float = 0.0, seed: int = 0, warmup_s: float = 2.0) -> SoakReport:
    """Run the soak against ``host:port`` for ``seconds`` with ``clients`` threads (see the module docstring).

    ``keys``: client ``i`` uses ``keys[i % len(keys)]`` (default ``[key]``). ``pace_s``: pause between a
    client's requests (0: back to back). RSS of ``server_pid`` is sampled before (after ``warmup_s`` of valid
    traffic), every few seconds, and after.
    """
    key_list: list[str | None] = list(keys) if keys else [key]
    plans = [_Plan(width, height, sensors, k, max_body_bytes) for k in key_list]
    report = SoakReport(seconds, clients)
    lock = threading.Lock()

    def record(kind: str, status: int | None, detail: str = "") -> None:
        with lock:
            report.statuses[f"{kind}:{status}"] += 1
            if status is not None and status >= 500:
                report.server_errors.append(f"{kind} {detail}: {status}")

    def warm(plan: _Plan, i: int) -> None:
        conn = http.client.HTTPConnection(host, port, timeout=30)
        end = time.monotonic() + warmup_s
        n = 0
        while time.monotonic() < end:
            conn.request("POST", "/v1/act", body=plan.valid(f"warm-{i}", n % 2 == 1, n == 0), headers=plan.json_headers)
            conn.getresponse().read()
            n += 1
        conn.close()

    def run(i: int, deadline: float) -> None:
        rng = np.random.default_rng([seed, i])
        plan = plans[i % len(plans)]
        conn: http.client.HTTPConnection | None = None
        n = 0
        while time.monotonic() < deadline:
            n += 1
            pick = rng.random()
            if pick < 0.5:
                session = f"c{i}-{n}" if n % 25 == 0 else f"c{i}-{n % 3}"
                data = plan.valid(session, bool(rng.random() < 0.5), n % 50 == 1)
                with lock:
                    report.valid_sent += 1
                try:
                    if conn is None:
                        conn = http.client.HTTPConnection(host, port, timeout=30)
                    conn.request("POST", "/v1/act", body=data, headers=plan.json_headers)
                    reply = conn.getresponse()
                    reply.read()
                    record("valid", reply.status)
                    if reply.status == 200:
                        with lock:
                            report.valid_ok += 1
                    else:
                        with lock:
                            report.valid_failures.append(f"status {reply.status}")
                except (OSError, http.client.HTTPException) as exc:
                    with lock:
                        report.valid_failures.append(f"{type(exc).__name__}: {exc}")
                    if conn is not None:
                        conn.close()
                    conn = None
            elif pick < 0.85:
                name, raw = plan.malformed[int(rng.integers(len(plan.malformed)))]
                with lock:
                    report.malformed_sent += 1
                try:
                    with socket.create_connection((host, port), timeout=30) as sock:
                        sock.sendall(raw)
                        record(f"malformed[{name}]", _read_status(sock), name)
                except OSError:
                    record(f"malformed[{name}]", None, name)  # the server may reset a connection it refused
            else:
                body = plan.abandon_body
                head = _request("/v1/act", b"", {**plan.json_headers, "Content-Length": str(len(body))})
                how = int(rng.integers(3))
                with lock:
                    report.abandoned += 1
                try:
                    with socket.create_connection((host, port), timeout=30) as sock:
                        if how == 0:
                            sock.sendall(head[: len(head) // 2])  # half the headers
                        elif how == 1:
                            sock.sendall(head + body[: len(body) // 2])  # half the body
                        else:
                            sock.sendall(head + body)  # all of it, but gone before the answer
                        # Close with RST (linger 0), as a client that crashes or loses its network does.
                        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                except OSError:
                    pass
            if pace_s:
                time.sleep(pace_s)
        if conn is not None:
            conn.close()

    def sample() -> None:
        if server_pid is not None and (value := rss_kib(server_pid)) is not None:
            report.rss_kib.append((round(time.monotonic() - started, 1), value))

    warmers = [threading.Thread(target=warm, args=(plans[i % len(plans)], i)) for i in range(min(clients, 4))]
    for t in warmers:
        t.start()
    for t in warmers:
        t.join()
    started = time.monotonic()
    sample()
    deadline = started + seconds
    threads = [threading.Thread(target=run, args=(i, deadline), daemon=True) for i in range(clients)]
    for t in threads:
        t.start()
    while time.monotonic() < deadline:
        time.sleep(min(5.0, max(0.0, deadline - time.monotonic())))
        sample()
    for t in threads:
        t.join(timeout=60)
    time.sleep(0.5)  # let the server finish with the abandoned connections
    sample()
    return report
