"""Loopback HTTP servers that speak the OpenAI chat-completions and Anthropic messages APIs and replay scripted
replies. The real client libraries talk to them over 127.0.0.1; nothing is monkeypatched."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any


@dataclass
class Reply:
    """One scripted answer: reply text, or an HTTP error status, optionally after a delay; or a hostile one."""

    text: str = ""
    status: int = 200
    delay_s: float = 0.0
    raw: bytes | None = None  # the whole HTTP body, sent as it is (not JSON, the wrong shape...)
    # a reply that never ends: the headers, then a byte every 50 ms for this long (until the client hangs up), then
    # the server hangs up (so that a client that waits for the end fails instead of hanging the test)
    trickle_s: float = 0.0


@dataclass
class ReplayLog:
    requests: list[dict[str, Any]] = field(default_factory=list)
    headers: list[dict[str, str]] = field(default_factory=list)
    paths: list[str] = field(default_factory=list)


def _handler(script: list[Reply], log: ReplayLog, protocol: str) -> type[BaseHTTPRequestHandler]:
    lock = threading.Lock()

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: Any) -> None:  # keep test output clean
            pass

        def do_POST(self) -> None:  # noqa: N802 - http.server API
            length = int(self.headers.get("Content-Length", "0"))
            body = json.loads(self.rfile.read(length) or b"{}")
            with lock:
                log.requests.append(body)
                log.headers.append({k.lower(): v for k, v in self.headers.items()})
                log.paths.append(self.path)
                reply = script.pop(0) if script else Reply(status=500)
            if reply.delay_s:
                time.sleep(reply.delay_s)
            if reply.status != 200:
                payload: dict[str, Any] = {"error": {"message": f"scripted failure {reply.status}",
                                                     "type": "server_error"}}
                if protocol == "anthropic":
                    payload = {"type": "error", "error": {"type": "api_error", "message": "scripted failure"}}
            elif protocol == "openai":
                payload = {"id": "chatcmpl-1", "object": "chat.completion", "created": 0, "model": body.get("model"),
                           "choices": [{"index": 0, "finish_reason": "stop",
                                        "message": {"role": "assistant", "content": reply.text}}],
                           "usage": {"prompt_tokens": 1, "completion_tokens": 1, "total_tokens": 2}}
            else:
                payload = {"id": "msg_1", "type": "message", "role": "assistant", "model": body.get("model"),
                           "content": [{"type": "text", "text": reply.text}], "stop_reason": "end_turn",
                           "stop_sequence": None, "usage": {"input_tokens": 1, "output_tokens": 1}}
            data = json.dumps(payload).encode() if reply.raw is None else reply.raw
            try:
                self.send_response(reply.status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(10**9 if reply.trickle_s else len(data)))
                self.end_headers()
                if reply.trickle_s:
                    end = time.monotonic() + reply.trickle_s
                    while time.monotonic() < end:
                        self.wfile.write(b" ")
                        self.wfile.flush()
                        time.sleep(0.05)
                    return
                self.wfile.write(data)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the client gave up (timeout test)

    return Handler


@contextmanager
def replay_server(script: list[Reply], protocol: str = "openai") -> Iterator[tuple[str, ReplayLog]]:
    """Serve ``script`` on a free loopback port; yields (base_url, log)."""
    log = ReplayLog()
    server = ThreadingHTTPServer(("127.0.0.1", 0), _handler(list(script), log, protocol))
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    host, port = server.server_address[:2]
    base = f"http://127.0.0.1:{port}" + ("/v1" if protocol == "openai" else "")
    try:
        yield base, log
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
