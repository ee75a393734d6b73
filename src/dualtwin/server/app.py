"""The RobotServer (Pattern 3): a policy and a perception model served over HTTP, for supervisor-free control.

A policy trained on privileged state cannot run on a robot that has no supervisor. The server closes that gap:
the robot sends its on-board sensor readings (named as the policy contract's ``onboard`` observations) and a
camera frame; the perception model estimates the privileged quantities from the recent frames; the policy
turns the assembled observation into an action.

Endpoints:

* ``GET /healthz``: liveness (no key needed).
* ``GET /v1/info``: the I/O contract: sensors to send, frame format and camera, action, limits.
* ``POST /v1/act``: ``{"session", "sensors": {name: value}, "frame": {...}, "reset"?, "time_s"?}`` ->
  the action, the command in physical units, the observation used and where each entry came from.
  ``frame`` is ``{"png_base64": ...}`` or ``{"data_base64": ..., "shape": [H, W, 3], "dtype": "uint8"}``.
* ``GET /v1/policy.onnx``: the served policy file (lets a client compare with privileged-state control).

Safety: models are ONNX only, loaded once by ONNX Runtime when the app is created (a file that is not ONNX
is a :class:`DualtwinError` before anything listens); nothing from the user is unpickled. Optional API key
(``X-API-Key``, compared in constant time; 401 otherwise), request bodies above ``max_body_bytes`` get 413
before they are parsed, frames above ``max_frame_pixels`` get 413 before they are decoded, everything else
malformed gets 400/422 with a message. Endpoints are synchronous, so FastAPI runs them in its thread pool;
ONNX Runtime sessions are safe for concurrent ``run`` calls. Each session id keeps its own frame history and
filter; at most ``max_sessions`` are kept (least recently used dropped first).
"""

from __future__ import annotations

import base64
import binascii
import hmac
import io
import json
import math
import threading
import time
from collections import OrderedDict
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from fastapi import Depends, FastAPI, HTTPException, Request
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from starlette.concurrency import run_in_threadpool

from dualtwin.errors import DualtwinError
from dualtwin.perception.estimator import DEFAULT_VELOCITY, VELOCITY_MODES, EstimatorSession, StateEstimator
from dualtwin.perception.onnx_policy import POLICY_FILE, OnnxPolicy

API_VERSION = "v1"
DEFAULT_MAX_BODY_BYTES = 1 << 20
DEFAULT_MAX_FRAME_PIXELS = 1 << 20
DEFAULT_MAX_SESSIONS = 64

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class FramePayload(_Strict):
    """A camera frame: a base64 PNG, or base64 raw bytes with their shape and dtype."""

    png_base64: str | None = None
    data_base64: str | None = None
    shape: list[int] | None = Field(default=None, description="[height, width, 3] for raw data")
    dtype: Literal["uint8"] | None = None


class ActRequest(_Strict):
    session: str = Field(min_length=1, max_length=128, pattern=r"^[A-Za-z0-9_.:\-]+$",
                         description="client-chosen id; frame history and filter are kept per session")
    sensors: dict[str, float] = Field(description="on-board readings named as the policy's onboard observations")
    frame: FramePayload
    reset: bool = Field(default=False, description="start a new episode: drop this session's history first")
    time_s: float | None = Field(default=None, description="robot time of the readings (echoed back)")


@dataclass
class _Session:
    estimator: EstimatorSession
    lock: threading.Lock = field(default_factory=threading.Lock)
    requests: int = 0


class _Sessions:
    """At most ``limit`` sessions, least recently used dropped first; thread-safe."""

    def __init__(self, estimator: StateEstimator, velocity: str, limit: int) -> None:
        self.estimator, self.velocity, self.limit = estimator, velocity, limit
        self._items: OrderedDict[str, _Session] = OrderedDict()
        self._lock = threading.Lock()
        self.evicted = 0

    def get(self, key: str) -> tuple[_Session, bool]:
        with self._lock:
            item = self._items.get(key)
            created = item is None
            if item is None:
                item = self._items[key] = _Session(self.estimator.session(self.velocity))
                while len(self._items) > self.limit:
                    self._items.popitem(last=False)
                    self.evicted += 1
            else:
                self._items.move_to_end(key)
            return item, created

    def __len__(self) -> int:
        return len(self._items)

    def clear(self) -> None:
        with self._lock:
            self._items.clear()


@dataclass
class ServerModels:
    """The policy and perception model the server runs, checked against each other."""

    policy: OnnxPolicy
    perception: StateEstimator

    @staticmethod
    def load(policy_dir: Path | str, perception_dir: Path | str) -> ServerModels:
        policy = OnnxPolicy.load_exported(policy_dir)
        perception = StateEstimator.load(perception_dir)
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
            image = Image.open(io.BytesIO(raw))
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
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
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


def create_app(policy_dir: Path | str, perception_dir: Path | str, *, api_key: str | None = None,
               max_body_bytes: int = DEFAULT_MAX_BODY_BYTES, max_frame_pixels: int = DEFAULT_MAX_FRAME_PIXELS,
               max_sessions: int = DEFAULT_MAX_SESSIONS, velocity: str = DEFAULT_VELOCITY) -> FastAPI:
    """The RobotServer app for an exported policy folder and a perception model folder.

    Raises:
        DualtwinError: a model is missing, is not ONNX, or the two do not fit together (before serving).
    """
    if max_body_bytes < 1024 or max_frame_pixels < 1 or max_sessions < 1:
        raise DualtwinError("max_body_bytes must be >= 1024, max_frame_pixels and max_sessions >= 1")
    if velocity not in VELOCITY_MODES:
        raise DualtwinError(f"unknown velocity mode {velocity!r} (available: {', '.join(VELOCITY_MODES)})")
    if api_key is not None and not api_key:
        raise DualtwinError("the API key must not be empty (omit it to serve without one)")
    # Loaded once, here, so a bad file fails before anything listens; the lifespan owns them afterwards.
    models = ServerModels.load(policy_dir, perception_dir)
    policy, perception = models.policy, models.perception
    perception.session(velocity)  # a model the velocity mode cannot use fails here, not at the first request
    onboard = policy.onboard
    height, width = perception.height, perception.width
    policy_bytes = (policy.directory / POLICY_FILE).read_bytes()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.models = models
        app.state.sessions = _Sessions(perception, velocity, max_sessions)
        app.state.started = time.time()
        yield
        app.state.sessions.clear()

    app = FastAPI(title="dualtwin RobotServer", version=API_VERSION, lifespan=lifespan)
    key_bytes = api_key.encode() if api_key else None

    def check_key(request: Request) -> None:
        if key_bytes is None:
            return
        given = request.headers.get("x-api-key", "")
        # Constant-time compare: the time taken reveals nothing about how much of the key matched.
        if not hmac.compare_digest(given.encode(), key_bytes):
            raise HTTPException(401, "missing or wrong API key (header X-API-Key)")

    info = {
        "api_version": API_VERSION,
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
            "session": "one id per robot/episode stream; reset=true at an episode start",
        },
        "limits": {"max_body_bytes": max_body_bytes, "max_frame_pixels": max_frame_pixels,
                   "max_sessions": max_sessions},
        "auth": "X-API-Key header" if key_bytes else None,
    }

    @app.exception_handler(DualtwinError)
    async def _dualtwin_error(request: Request, exc: DualtwinError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    @app.get("/healthz")
    def healthz() -> dict[str, Any]:
        return {"status": "ok"}

    @app.get(f"/{API_VERSION}/info", dependencies=[Depends(check_key)])
    def get_info(request: Request) -> dict[str, Any]:
        return {**info, "sessions": len(request.app.state.sessions)}

    @app.get(f"/{API_VERSION}/policy.onnx", dependencies=[Depends(check_key)])
    def get_policy() -> Response:
        return Response(policy_bytes, media_type="application/octet-stream")

    action_names = policy.contract["action"].get("names", ["command"])
    action_unit = policy.contract["action"].get("unit")
    sources = {name: "onboard" if name in onboard else "perception" for name in policy.names}

    def compute(body: ActRequest, sessions: _Sessions) -> bytes:
        missing = [n for n in onboard if n not in body.sensors]
        unknown = sorted(set(body.sensors) - set(onboard))
        if missing or unknown:
            parts = ([f"missing {missing}"] if missing else []) + ([f"unknown {unknown}"] if unknown else [])
            raise HTTPException(422, f"sensors: {'; '.join(parts)}; send exactly the on-board observations "
                                     f"{onboard}")
        frame = decode_frame(body.frame, height, width, max_frame_pixels)
        session, created = sessions.get(body.session)
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
        return json.dumps({
            "session": body.session, "new_session": created, "step": steps, "action": action_value,
            "command": {**dict(zip(action_names, (float(v) for v in command[0]), strict=True)), "unit": action_unit},
            "observation": observation, "sources": sources, "estimate": estimated, "time_s": body.time_s,
        }).encode()

    @app.post(f"/{API_VERSION}/act", openapi_extra={"requestBody": {"required": True, "content": {
        "application/json": {"schema": ActRequest.model_json_schema()}}}})
    async def act(request: Request) -> Response:
        """The action for on-board sensor readings and a camera frame (see /v1/info for the contract)."""
        check_key(request)
        # Parsed and validated by pydantic's JSON parser in one pass (faster than FastAPI's dict round trip).
        try:
            body = ActRequest.model_validate_json(await request.body())
        except ValidationError as exc:
            errors = exc.errors(include_url=False, include_context=False, include_input=False)
            return JSONResponse(status_code=422, content={"detail": errors})
        # Inference runs in the thread pool: ONNX Runtime releases the GIL, so requests overlap on the cores.
        payload = await run_in_threadpool(compute, body, request.app.state.sessions)
        return Response(payload, media_type="application/json")

    app.add_middleware(_BodyLimit, limit=max_body_bytes)
    return app


def serve(policy_dir: Path | str, perception_dir: Path | str, host: str = "127.0.0.1", port: int = 8000,
          api_key: str | None = None, *, max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
          max_frame_pixels: int = DEFAULT_MAX_FRAME_PIXELS, max_sessions: int = DEFAULT_MAX_SESSIONS,
          velocity: str = DEFAULT_VELOCITY, log_level: str = "info") -> None:
    """Run the RobotServer with uvicorn until interrupted (models are checked before it listens)."""
    import uvicorn

    app = create_app(policy_dir, perception_dir, api_key=api_key, max_body_bytes=max_body_bytes,
                     max_frame_pixels=max_frame_pixels, max_sessions=max_sessions, velocity=velocity)
    # No per-request access log: at hundreds of requests/s it costs more than inference.
    uvicorn.run(app, host=host, port=port, log_level=log_level, access_log=False)
