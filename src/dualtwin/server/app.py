"""The RobotServer (Pattern 3): a policy and a perception model served over HTTP, for supervisor-free control.

A policy trained on privileged state cannot run on a robot that has no supervisor. The server closes that gap:
the robot sends its on-board sensor readings (named as the policy contract's ``onboard`` observations) and a
camera frame; the perception model estimates the privileged quantities from the recent frames; the policy
turns the assembled observation into an action. Camera-only mode (``camera_only=True``, or a policy folder
written by :func:`dualtwin.perception.camera_only.export_camera_only`) keeps only the wheel odometry on board:
the pole angle and rate come from the camera, and ``/v1/info`` says ``observation_mode: camera_only``.

Endpoints:

* ``GET /healthz``: liveness (no key needed).
* ``GET /v1/info``: the I/O contract: sensors to send, frame format and camera, action, limits.
* ``POST /v1/act``: ``{"session", "sensors": {name: value}, "frame": {...}, "reset"?, "time_s"?}`` ->
  the action, the command in physical units, the observation used and where each entry came from.
  ``frame`` is ``{"png_base64": ...}`` or ``{"data_base64": ..., "shape": [H, W, 3], "dtype": "uint8"}``.
* ``GET /v1/policy.onnx``: the served policy file (lets a client compare with privileged-state control).

Safety: models are ONNX only, loaded once by ONNX Runtime when the app is created (a file that is not ONNX
is a :class:`DualtwinError` before anything listens); nothing from the user is unpickled. Optional API keys
(``X-API-Key``, compared in constant time; 401 otherwise); with a key set, ``/openapi.json`` needs it too and
the browser docs (``/docs``, ``/redoc``, which cannot send the header) are off. Every client is bounded:
request bodies above ``max_body_bytes`` get 413 before they are parsed, frames above ``max_frame_pixels`` get
413 before they are decoded (PNG only: Pillow is told to try no other format), an optional request rate per
client (429), and sessions (below); everything else malformed gets 400/422 with a message, never a 5xx.
ONNX Runtime sessions are safe for concurrent ``run`` calls; inference runs in the thread pool.

Sessions (decision): a session id names one robot's frame history and filter *within its owner's namespace*.
The owner is the API key the request carries, or, without keys, the client's network address: another key
or another machine cannot reset, poison or evict a robot's history, whatever session id it sends. Each owner
keeps at most ``max_sessions`` (its own least recently used dropped first), the server at most
``max_total_sessions`` (a new session beyond that gets 429 rather than evicting someone else's), and a
session idle for ``session_idle_s`` (monotonic wall clock: server housekeeping, not a log) is dropped.
"""

from __future__ import annotations

import base64
import binascii
import errno
import hashlib
import hmac
import io
import ipaddress
import json
import math
import socket
import sys
import threading
import time
from collections import OrderedDict
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping, Sequence
from contextlib import asynccontextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from fastapi import Depends, FastAPI, HTTPException, Request, Security
from fastapi.openapi.utils import get_openapi
from fastapi.responses import JSONResponse, Response
from fastapi.security import APIKeyHeader
from pydantic import BaseModel, Field, Strict, ValidationError
from starlette.concurrency import run_in_threadpool

from dualtwin.errors import DualtwinError
from dualtwin.models import StrictModel
from dualtwin.perception.camera_only import camera_only_contract, is_camera_only
from dualtwin.perception.estimator import DEFAULT_VELOCITY, VELOCITY_MODES, EstimatorSession, StateEstimator
from dualtwin.perception.onnx_policy import POLICY_FILE, OnnxPolicy

API_VERSION = "v1"
DEFAULT_MAX_BODY_BYTES = 1 << 20
DEFAULT_MAX_FRAME_PIXELS = 1 << 20
DEFAULT_MAX_SESSIONS = 64
DEFAULT_MAX_TOTAL_SESSIONS = 1024
DEFAULT_SESSION_IDLE_S = 600.0
#: Sensor readings beyond float32's range would become inf inside the policy.
FLOAT32_MAX = float(np.finfo(np.float32).max)

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


class FramePayload(StrictModel):
    """A camera frame: a base64 PNG, or base64 raw bytes with their shape and dtype."""

    png_base64: str | None = None
    data_base64: str | None = None
    shape: list[int] | None = Field(default=None, max_length=3, description="[height, width, 3] for raw data")
    dtype: Literal["uint8"] | None = None


class ActRequest(StrictModel):
    session: str = Field(min_length=1, max_length=128, pattern=r"^[A-Za-z0-9_.:\-]+$",
                         description="client-chosen id; frame history and filter are kept per session, in the "
                                     "namespace of the caller's API key (or address, without keys)")
    # Strict numbers: true/false or "1.0" is a malformed reading (the schema says number), not 1.0.
    sensors: dict[str, Annotated[float, Strict()]] = Field(
        description="on-board readings named as the policy's onboard observations")
    frame: FramePayload
    # Strict too: "yes" or "1.5" is a malformed request, not true or 1.5
    reset: Annotated[bool, Strict()] = Field(default=False,
                                             description="start a new episode: drop this session's history first")
    time_s: Annotated[float, Strict()] | None = Field(default=None,
                                                      description="robot time of the readings (echoed back)")


class ActResponse(BaseModel):
    """The action for one request, and what it was computed from."""

    session: str
    new_session: bool = Field(description="true if this request started the session (new, reset or expired)")
    step: int = Field(description="frames seen by this session")
    action: int | list[float] = Field(description="the policy's action (discrete index or normalised vector)")
    command: dict[str, float | str | None] = Field(description="the action in physical units, with 'unit'")
    observation: dict[str, float] = Field(description="the observation the policy saw")
    sources: dict[str, str] = Field(description="'onboard' (from the request) or 'perception' per observation")
    estimate: dict[str, float] = Field(description="the perception model's estimate")
    time_s: float | None


class ErrorResponse(BaseModel):
    detail: Any = Field(description="what was wrong: a message, or pydantic's list of validation errors")


@dataclass
class _Session:
    estimator: EstimatorSession
    last_used: float
    lock: threading.Lock = field(default_factory=threading.Lock)
    requests: int = 0


class _Sessions:
    """Sessions keyed by (owner, session id): per-owner LRU bound, a global bound, idle expiry; thread-safe."""

    def __init__(self, estimator: StateEstimator, velocity: str, limit: int, total: int, idle_s: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.estimator, self.velocity, self.limit, self.total, self.idle_s = estimator, velocity, limit, total, idle_s
        self.clock = clock
        self._owners: dict[str, OrderedDict[str, _Session]] = {}
        # Every session in order of last use, oldest first: expiry pops from the front.
        self._order: OrderedDict[tuple[str, str], None] = OrderedDict()
        self._lock = threading.Lock()
        self.evicted = 0
        self.expired = 0

    def get(self, owner: str, key: str) -> tuple[_Session, bool]:
        now = self.clock()
        with self._lock:
            self._expire(now)
            mine = self._owners.setdefault(owner, OrderedDict())
            item = mine.get(key)
            if item is not None:
                mine.move_to_end(key)
                self._order.move_to_end((owner, key))
                item.last_used = now
                return item, False
            if len(mine) >= self.limit:
                # Only the owner's own oldest session makes room: nobody else's history is touched.
                old, _ = mine.popitem(last=False)
                del self._order[(owner, old)]
                self.evicted += 1
            elif len(self._order) >= self.total:
                if not mine:
                    del self._owners[owner]
                raise HTTPException(429, f"the server holds its maximum of {self.total} sessions; retry later "
                                         f"(sessions idle for {self.idle_s:g} s are dropped)")
            item = mine[key] = _Session(self.estimator.session(self.velocity), now)
            self._order[(owner, key)] = None
            return item, True

    def _expire(self, now: float) -> None:
        while self._order:
            owner, key = next(iter(self._order))
            mine = self._owners[owner]
            if now - mine[key].last_used < self.idle_s:
                break
            del self._order[(owner, key)]
            del mine[key]
            if not mine:
                del self._owners[owner]
            self.expired += 1

    def count(self, owner: str) -> int:
        with self._lock:
            self._expire(self.clock())
            return len(self._owners.get(owner, ()))

    def __len__(self) -> int:
        return len(self._order)

    def clear(self) -> None:
        with self._lock:
            self._owners.clear()
            self._order.clear()


class _RateLimit:
    """A token bucket per owner: ``rate`` requests/s sustained, bursts of ``burst``; thread-safe."""

    def __init__(self, rate: float, burst: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.rate, self.burst, self.clock = rate, burst, clock
        self._buckets: dict[str, tuple[float, float]] = {}
        self._lock = threading.Lock()

    def allow(self, owner: str) -> bool:
        now = self.clock()
        with self._lock:
            tokens, then = self._buckets.get(owner, (self.burst, now))
            tokens = min(self.burst, tokens + (now - then) * self.rate)
            if len(self._buckets) > 4096:  # forget owners whose buckets are full again (bounded memory)
                self._buckets = {k: v for k, v in self._buckets.items()
                                 if v[0] + (now - v[1]) * self.rate < self.burst}
            if tokens < 1.0:
                self._buckets[owner] = (tokens, now)
                return False
            self._buckets[owner] = (tokens - 1.0, now)
            return True


@dataclass
class ServerModels:
    """The policy and perception model the server runs, checked against each other."""

    policy: OnnxPolicy
    perception: StateEstimator

    @staticmethod
    def load(policy_dir: Path | str, perception_dir: Path | str, *, camera_only: bool = False) -> ServerModels:
        """Load and check both models; ``camera_only`` rewrites the policy's contract so that only wheel odometry
        is read from the robot and every other observation comes from the perception model
        (:func:`dualtwin.perception.camera_only.camera_only_contract`)."""
        policy = OnnxPolicy.load_exported(policy_dir)
        perception = StateEstimator.load(perception_dir)
        if camera_only or is_camera_only(policy.contract):
            policy = replace(policy, contract=camera_only_contract(policy.contract, perception.names))
        missing = [n for n in policy.privileged if n not in perception.names]
        if missing:
            raise DualtwinError(f"{perception_dir}: the perception model estimates {perception.names}, but the policy "
                                f"also needs {missing} (its privileged observations)")
        if not math.isclose(policy.control_period, perception.frame_period, rel_tol=1e-6):
            raise DualtwinError(f"policy control period {policy.control_period} s differs from the perception "
                                f"model's frame period {perception.frame_period} s")
        return ServerModels(policy, perception)


class _BodyLimit:
    """Pure ASGI middleware: 413 for request bodies above ``limit`` bytes, checked before the app parses them."""

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        if length is not None:
            try:
                declared = int(length)
            except ValueError:
                await _plain(send, 400, "invalid Content-Length header")
                return
            if declared > self.limit:
                if declared <= DRAIN_BYTES:
                    await _drain(receive)
                await _plain(send, 413, f"request body of {declared} bytes exceeds the limit of {self.limit} bytes")
                return
        # Read (at most limit + 1 bytes of) the body now, so a chunked upload cannot exceed the limit either.
        chunks, size, more = [], 0, True
        while more:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.limit:
                if message.get("more_body", False):
                    await _drain(receive, DRAIN_BYTES - size)
                await _plain(send, 413, f"request body exceeds the limit of {self.limit} bytes")
                return
            chunks.append(chunk)
            more = message.get("more_body", False)
        body = b"".join(chunks)
        sent = False

        async def replay() -> Message:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


#: An oversized body up to this size is read (and dropped) before the 413 is sent: a server that answers and
#: closes while the client is still uploading resets the connection, and the client may see the reset instead
#: of the answer (a flaky 'ReadError' under load). A larger one is answered at once.
DRAIN_BYTES = 16 << 20


async def _drain(receive: Receive, budget: int = DRAIN_BYTES) -> None:
    while budget > 0:
        message = await receive()
        if message["type"] == "http.disconnect" or not message.get("more_body", False):
            return
        budget -= len(message.get("body", b""))


async def _plain(send: Send, status: int, detail: str) -> None:
    payload = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(payload)).encode()),
                            (b"connection", b"close")]})
    await send({"type": "http.response.body", "body": payload})


def decode_frame(payload: FramePayload, height: int, width: int, max_pixels: int) -> np.ndarray:
    """The frame as uint8 [height, width, 3]; HTTPException 413/422 with a message otherwise."""
    if (payload.png_base64 is None) == (payload.data_base64 is None):
        raise HTTPException(422, "frame: give exactly one of 'png_base64' or 'data_base64'")
    expected = f"{width}x{height} RGB (height {height}, width {width}, 3 channels)"
    try:
        raw = base64.b64decode(payload.png_base64 or payload.data_base64 or "", validate=True)
    except (binascii.Error, ValueError):
        raise HTTPException(422, "frame: not valid base64") from None
    if payload.png_base64 is not None:
        from PIL import Image, UnidentifiedImageError

        try:
            # PNG only: Pillow must not parse (or even identify) the header of any other format it knows.
            image = Image.open(io.BytesIO(raw), formats=["PNG"])
            w, h = image.size  # header only: the pixels are not decoded yet
            if w * h > max_pixels:
                raise HTTPException(413, f"frame of {w}x{h} pixels exceeds the limit of {max_pixels} pixels")
            if image.format != "PNG":
                raise HTTPException(422, f"frame: expected a PNG image, got {image.format}")
            if (w, h) != (width, height):
                raise HTTPException(422, f"frame is {w}x{h}; the camera model expects {expected}")
            if image.mode not in ("RGB", "RGBA"):
                raise HTTPException(422, f"frame: PNG mode {image.mode!r}; send RGB (or RGBA) pixels")
            pixels = np.asarray(image.convert("RGB"), dtype=np.uint8)
        except HTTPException:
            raise
        except UnidentifiedImageError:
            raise HTTPException(422, "frame: not a PNG image") from None
        except Image.DecompressionBombError:  # Pillow's own header check, for sizes far beyond ours
            raise HTTPException(413, f"frame: the PNG header claims more than {max_pixels} pixels") from None
        except Exception as exc:  # noqa: BLE001 - any decoder failure on untrusted bytes is the client's bad data
            raise HTTPException(422, f"frame: not a readable PNG image ({type(exc).__name__})") from None
        return pixels
    if payload.shape is None or payload.dtype is None:
        raise HTTPException(422, "frame: raw 'data_base64' needs 'shape' [height, width, 3] and 'dtype' 'uint8'")
    shape = list(payload.shape)
    if len(shape) != 3 or any(s < 1 for s in shape):
        raise HTTPException(422, f"frame: shape must be [height, width, 3] of positive sizes, got {shape}")
    if shape[0] * shape[1] > max_pixels:
        raise HTTPException(413, f"frame of {shape[1]}x{shape[0]} pixels exceeds the limit of {max_pixels} pixels")
    if shape != [height, width, 3]:
        raise HTTPException(422, f"frame shape {shape}; the camera model expects [{height}, {width}, 3] ({expected})")
    if len(raw) != height * width * 3:
        raise HTTPException(422, f"frame: {len(raw)} bytes of data, shape {shape} uint8 needs {height * width * 3}")
    return np.frombuffer(raw, dtype=np.uint8).reshape(height, width, 3)


def _keys(api_key: str | Sequence[str] | None) -> list[bytes]:
    keys = [api_key] if isinstance(api_key, str) else list(api_key or [])
    if any(not isinstance(k, str) or not k for k in keys):
        raise DualtwinError("an API key must not be empty (omit it to serve without one)")
    return [k.encode() for k in keys]


def create_app(policy_dir: Path | str, perception_dir: Path | str, *, api_key: str | Sequence[str] | None = None,
               max_body_bytes: int = DEFAULT_MAX_BODY_BYTES, max_frame_pixels: int = DEFAULT_MAX_FRAME_PIXELS,
               max_sessions: int = DEFAULT_MAX_SESSIONS, max_total_sessions: int = DEFAULT_MAX_TOTAL_SESSIONS,
               session_idle_s: float = DEFAULT_SESSION_IDLE_S, max_requests_per_s: float | None = None,
               velocity: str = DEFAULT_VELOCITY, camera_only: bool = False) -> FastAPI:
    """The RobotServer app for an exported policy folder and a perception model folder.

    Args:
        api_key: one key or several; each key is its own session namespace. None: no key, sessions are kept
            per client address.
        max_sessions: sessions per key (or per client address without keys).
        max_total_sessions: sessions in the whole server.
        session_idle_s: a session unused this long is dropped.
        max_requests_per_s: optional sustained request rate per key or client address (bursts of one
            second's worth); 429 beyond it.
        camera_only: serve the policy camera-only: requests carry the wheel odometry only (no pole encoder, no
            other sensor: the request schema has no field for it) and the perception model estimates the rest.
            A policy folder written by :func:`dualtwin.perception.camera_only.export_camera_only` is served
            camera-only without the flag.

    Raises:
        DualtwinError: a model is missing, is not ONNX, or the two do not fit together (before serving).
    """
    if max_body_bytes < 1024 or max_frame_pixels < 1 or max_sessions < 1 or max_total_sessions < max_sessions:
        raise DualtwinError("max_body_bytes must be >= 1024, max_frame_pixels and max_sessions >= 1, and "
                            "max_total_sessions >= max_sessions")
    if not session_idle_s > 0 or (max_requests_per_s is not None and not max_requests_per_s > 0):
        raise DualtwinError("session_idle_s and max_requests_per_s must be > 0")
    if velocity not in VELOCITY_MODES:
        raise DualtwinError(f"unknown velocity mode {velocity!r} (available: {', '.join(VELOCITY_MODES)})")
    keys = _keys(api_key)
    # Loaded once, here, so a bad file fails before anything listens; the lifespan owns them afterwards.
    models = ServerModels.load(policy_dir, perception_dir, camera_only=camera_only)
    policy, perception = models.policy, models.perception
    perception.session(velocity)  # a model the velocity mode cannot use fails here, not at the first request
    onboard = policy.onboard
    height, width = perception.height, perception.width
    policy_bytes = (policy.directory / POLICY_FILE).read_bytes()
    limiter = _RateLimit(max_requests_per_s, max(1.0, max_requests_per_s)) if max_requests_per_s else None

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.models = models
        app.state.sessions = _Sessions(perception, velocity, max_sessions, max_total_sessions, session_idle_s)
        app.state.started = time.time()
        yield
        app.state.sessions.clear()

    # With a key the schema needs it too, and the browser docs (which cannot send the header) are off.
    app = FastAPI(title="dualtwin RobotServer", version=API_VERSION, lifespan=lifespan,
                  openapi_url=None if keys else "/openapi.json", docs_url=None if keys else "/docs",
                  redoc_url=None if keys else "/redoc")
    key_header = APIKeyHeader(name="X-API-Key", auto_error=False,
                              description="the server's API key; sessions are kept per key")

    async def owner(request: Request, given: str | None = Security(key_header)) -> str:
        """Who is asking: their key's namespace (401 without a valid key), or their address without keys."""
        if keys:
            presented = (given or "").encode()
            # Constant-time compare against every key: the time taken reveals nothing about a key.
            matched = [hmac.compare_digest(presented, key) for key in keys]
            if not any(matched):
                raise HTTPException(401, "missing or wrong API key (header X-API-Key)")
            who = "key:" + hashlib.sha256(presented).hexdigest()[:16]
        else:
            who = "client:" + (request.client.host if request.client else "unknown")
        if limiter is not None and not limiter.allow(who):
            raise HTTPException(429, f"more than {max_requests_per_s:g} requests/s from this client; slow down")
        return who

    errors: dict[int | str, dict[str, Any]] = {
        401: {"model": ErrorResponse, "description": "missing or wrong API key"},
        429: {"model": ErrorResponse, "description": "request rate or session limit reached"}}

    info = {
        "api_version": API_VERSION,
        "observation_mode": policy.contract.get("observation_mode", "onboard_sensors_and_camera"),
        "odometry": policy.contract.get("odometry"),
        "policy": {"env_id": policy.contract.get("env_id"), "env_kwargs": policy.contract.get("env_kwargs") or {},
                   "source_twin": policy.contract.get("source_twin"),
                   "observation": policy.terms, "action": policy.contract.get("action"),
                   "control_period_s": policy.control_period,
                   "onnx_sha256": policy.contract.get("onnx", {}).get("sha256")},
        "perception": {"state": perception.contract["state"], "frame_stack": perception.stack,
                       "frame_period_s": perception.frame_period, "camera": perception.contract.get("camera"),
                       "resolution": [width, height], "trained_on": perception.contract.get("trained_on"),
                       "velocity": velocity},
        "request": {
            "sensors": {t["name"]: {"unit": t.get("unit"), "channel": t.get("channel")}
                        for t in policy.terms if t["name"] in onboard},
            "estimated": [t["name"] for t in policy.terms if t["name"] not in onboard],
            "frame": {"formats": ["png_base64", "data_base64 + shape + dtype"], "shape": [height, width, 3],
                      "dtype": "uint8", "order": "RGB, row-major from the top-left pixel"},
            "session": "one id per robot/episode stream; reset=true at an episode start; ids are scoped to the "
                       "API key (or the client address without keys)",
        },
        "limits": {"max_body_bytes": max_body_bytes, "max_frame_pixels": max_frame_pixels,
                   "max_sessions": max_sessions, "max_total_sessions": max_total_sessions,
                   "session_idle_s": session_idle_s, "max_requests_per_s": max_requests_per_s},
        "auth": "X-API-Key header" if keys else None,
    }

    @app.exception_handler(DualtwinError)
    async def _dualtwin_error(request: Request, exc: DualtwinError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    @app.get("/healthz")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    @app.get(f"/{API_VERSION}/info", responses=errors)
    async def get_info(request: Request, who: str = Depends(owner)) -> dict[str, Any]:
        """The I/O contract; ``sessions`` counts the caller's own sessions."""
        return {**info, "sessions": request.app.state.sessions.count(who)}

    @app.get(f"/{API_VERSION}/policy.onnx", dependencies=[Depends(owner)], response_class=Response,
             responses={200: {"content": {"application/octet-stream": {"schema": {"type": "string",
                                                                                  "format": "binary"}}},
                              "description": "the served ONNX policy"}, **errors})
    async def get_policy() -> Response:
        return Response(policy_bytes, media_type="application/octet-stream")

    if keys:
        @app.get("/openapi.json", include_in_schema=False, dependencies=[Depends(owner)])
        async def get_openapi_json() -> JSONResponse:
            return JSONResponse(app.openapi())

    action_names = policy.contract["action"].get("names", ["command"])
    action_unit = policy.contract["action"].get("unit")
    sources = {name: "onboard" if name in onboard else "perception" for name in policy.names}

    def compute(body: ActRequest, sessions: _Sessions, who: str) -> bytes:
        missing = [n for n in onboard if n not in body.sensors]
        unknown = sorted(set(body.sensors) - set(onboard))
        if missing or unknown:
            parts = ([f"missing {missing}"] if missing else []) + ([f"unknown {unknown}"] if unknown else [])
            raise HTTPException(422, f"sensors: {'; '.join(parts)}; send exactly the on-board observations "
                                     f"{onboard}")
        huge = sorted(n for n, v in body.sensors.items() if abs(v) > FLOAT32_MAX)
        if huge:
            raise HTTPException(422, f"sensors: {huge} beyond the float32 range the policy computes in")
        frame = decode_frame(body.frame, height, width, max_frame_pixels)
        session, created = sessions.get(who, body.session)
        with session.lock:  # one request at a time per session: the frame history is ordered
            if body.reset:
                session.estimator.reset()
            estimate = session.estimator.update(frame)
            session.requests += 1
            steps = session.estimator.steps
        estimated = dict(zip(perception.names, (float(v) for v in estimate), strict=True))
        observation = {name: float(body.sensors[name]) if name in onboard else estimated[name]
                       for name in policy.names}
        action, command = policy.run(np.array([list(observation.values())], dtype=np.float32))
        action_value: Any = int(action[0]) if policy.discrete else [float(v) for v in np.ravel(action[0])]
        reply = {
            "session": body.session, "new_session": created, "step": steps, "action": action_value,
            "command": {**dict(zip(action_names, (float(v) for v in command[0]), strict=True)), "unit": action_unit},
            "observation": observation, "sources": sources, "estimate": estimated, "time_s": body.time_s,
        }
        try:
            return json.dumps(reply, allow_nan=False).encode()
        except ValueError:  # a non-finite estimate or action: the input drove the models out of range
            raise HTTPException(422, "the frame and sensors drove the models to a non-finite result") from None

    @app.post(f"/{API_VERSION}/act", response_model=None, responses={
        200: {"model": ActResponse, "description": "the action"},
        400: {"model": ErrorResponse, "description": "malformed request (e.g. an invalid Content-Length)"},
        413: {"model": ErrorResponse, "description": "body or frame above the limits"},
        422: {"model": ErrorResponse, "description": "invalid request"}, **errors},
        openapi_extra={"requestBody": {"required": True, "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/ActRequest"}}}}})
    async def act(request: Request, who: str = Depends(owner)) -> Response:
        """The action for on-board sensor readings and a camera frame (see /v1/info for the contract)."""
        # Parsed and validated by pydantic's JSON parser in one pass (faster than FastAPI's dict round trip).
        try:
            body = ActRequest.model_validate_json(await request.body())
        except ValidationError as exc:
            problems = exc.errors(include_url=False, include_context=False, include_input=False)
            return JSONResponse(status_code=422, content={"detail": problems})
        # Inference runs in the thread pool: ONNX Runtime releases the GIL, so requests overlap on the cores.
        payload = await run_in_threadpool(compute, body, request.app.state.sessions, who)
        return Response(payload, media_type="application/json")

    def openapi() -> dict[str, Any]:
        # The request body is parsed by hand (one pass), so its schema is added to the components here.
        if app.openapi_schema is None:
            schema = get_openapi(title=app.title, version=app.version, routes=app.routes)
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            body = ActRequest.model_json_schema(ref_template="#/components/schemas/{model}")
            components.update(body.pop("$defs", {}))
            # This server's contract, more precisely than the generic model can say: exactly its on-board
            # sensors, and a frame that is either a base64 PNG or base64 raw pixels of the camera's shape.
            body["properties"]["sensors"] = {
                "type": "object", "description": body["properties"]["sensors"].get("description", ""),
                "properties": {name: {"type": "number"} for name in onboard}, "required": list(onboard),
                "additionalProperties": False}
            components["FramePayload"] = {"description": components["FramePayload"].get("description", ""), "oneOf": [
                {"type": "object", "properties": {"png_base64": {"type": "string", "format": "byte"}},
                 "required": ["png_base64"], "additionalProperties": False},
                {"type": "object", "properties": {
                    "data_base64": {"type": "string", "format": "byte"},
                    "shape": {"type": "array", "items": {"type": "integer", "minimum": 1}, "minItems": 3,
                              "maxItems": 3},
                    "dtype": {"type": "string", "enum": ["uint8"]}},
                 "required": ["data_base64", "shape", "dtype"], "additionalProperties": False}]}
            components["ActRequest"] = body
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    app.add_middleware(_BodyLimit, limit=max_body_bytes)
    return app


def is_loopback(host: str) -> bool:
    """True for addresses only this machine can reach (127.0.0.0/8, ::1, localhost)."""
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # a host name: it may resolve to any interface


def serve(policy_dir: Path | str, perception_dir: Path | str, host: str = "127.0.0.1", port: int = 8000,
          api_key: str | Sequence[str] | None = None, *, max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
          max_frame_pixels: int = DEFAULT_MAX_FRAME_PIXELS, max_sessions: int = DEFAULT_MAX_SESSIONS,
          max_total_sessions: int = DEFAULT_MAX_TOTAL_SESSIONS, session_idle_s: float = DEFAULT_SESSION_IDLE_S,
          max_requests_per_s: float | None = None, velocity: str = DEFAULT_VELOCITY, log_level: str = "info",
          camera_only: bool = False) -> None:
    """Run the RobotServer with uvicorn until interrupted (models are checked before it listens)."""
    import uvicorn

    app = create_app(policy_dir, perception_dir, api_key=api_key, max_body_bytes=max_body_bytes,
                     max_frame_pixels=max_frame_pixels, max_sessions=max_sessions,
                     max_total_sessions=max_total_sessions, session_idle_s=session_idle_s,
                     max_requests_per_s=max_requests_per_s, velocity=velocity, camera_only=camera_only)
    # Bind here, before uvicorn starts: a port in use or an address this machine does not have is one line naming
    # the option (uvicorn would log several lines and exit 3); uvicorn then serves on this very socket.
    sock = listening_socket(host, port)
    warning = exposure_warning(host, port, api_key)
    if warning:
        print(warning, file=sys.stderr)
    # No per-request access log: at hundreds of requests/s it costs more than inference.
    config = uvicorn.Config(app, host=host, port=port, log_level=log_level, access_log=False)
    try:
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        sock.close()


def exposure_warning(host: str, port: int, api_key: str | Sequence[str] | None) -> str | None:
    """The warning for a server reachable beyond this machine without an API key (None when there is none)."""
    if api_key or is_loopback(host):
        return None
    return (f"warning: serving on {host} without an API key: anyone who can reach port {port} can drive the "
            "policy and read its contract; set one with --api-key-env")


def listening_socket(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``host:port`` (as uvicorn binds: SO_REUSEADDR), or one line naming the option.

    Raises:
        DualtwinError: a port outside 0-65535, a host that does not resolve, a port in use, or an address that is
            not this machine's.
    """
    if not 0 <= port <= 65535:
        raise DualtwinError(f"--port {port}: a TCP port is 0 to 65535")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        raise DualtwinError(f"--host {host!r}: not an address or a name this machine can resolve ({exc})") from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(2048)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            raise DualtwinError(f"--port {port}: {host}:{port} is already in use by another program; choose another "
                                "port") from None
        if exc.errno == errno.EADDRNOTAVAIL:
            raise DualtwinError(f"--host {host}: not an address of this machine ({exc.strerror})") from None
        if exc.errno == errno.EACCES:
            raise DualtwinError(f"--port {port}: not allowed to listen there ({exc.strerror}); ports below 1024 "
                                "need privileges") from None
        raise DualtwinError(f"--host {host} --port {port}: cannot listen ({exc.strerror or exc})") from None
    sock.set_inheritable(True)
    return sock
