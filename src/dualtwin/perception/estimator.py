"""Run an exported perception model (ONNX Runtime, no PyTorch): frames in, state estimate out.

A :class:`StateEstimator` holds the model; each robot (or server client) gets an :class:`EstimatorSession` that
keeps its own last-k frame history and filter state. Models exported with the two parts (``perception_frame.onnx``:
one frame to its mask moments; ``perception_head.onnx``: k frames' moments to the state) segment each new frame
once and keep the last k moments, a third of the work of running the whole model on k frames every period;
older models run ``perception.onnx`` on the frame stack. Velocity options:

* ``kalman`` (default): a constant-velocity Kalman filter per (position, velocity) pair (cart, pole). Its
  measurements are the CNN's positions from the newest frame alone (the frame repeated k times, as at an
  episode start in training), because the k-frame head smooths its positions over time: measured on the
  PPO cart-pole, its pole angle lagged the truth by 0.5 control periods in the MuJoCo twin and 0.9 in the Webots
  twin, against 0.02-0.10 for the newest frame alone. Measurement noise is the model's held-out error (the
  std of a zero-mean Gaussian with the contract's validation MAE); process noise is white acceleration of
  std :data:`ACCEL_STD` (the balancing loops measured 1.4-3.6 rad/s² at the pole). The filter this replaces,
  a fixed α-β filter (α = 0.6, β = 0.15) on the k-frame positions, delayed the pole rate by about three
  control periods (96 ms): enough to make the trained PPO policy lose the pole in the Webots twin, whose
  closed loop moves the pole 2.5 times faster than MuJoCo's.
* ``frame-stack``: the CNN's own velocity outputs. At 64x64 the motion over k = 3 frames is a fraction of a
  pixel (0.3 rad/s moves the pole tip by 0.4 px a period), so these stay close to the training mean.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field, Strict, ValidationError, field_validator, model_validator

from dualtwin.artifacts import confined_file, sha256_file
from dualtwin.errors import DualtwinError
from dualtwin.models import validation_message
from dualtwin.onnx_models import run_session
from dualtwin.perception.onnx_policy import onnx_session, read_contract

MODEL_FILE = "perception.onnx"
CONTRACT_FILE = "perception_contract.json"
VELOCITY_MODES = ("kalman", "frame-stack")
DEFAULT_VELOCITY = "kalman"
#: (position index, velocity index) pairs of the state vector the filter links.
FILTER_PAIRS = ((0, 1), (2, 3))
#: Process noise: std of the white acceleration the filter expects, per position index (m/s², rad/s²).
ACCEL_STD = {0: 1.0, 2: 3.0}


@dataclass
class StateEstimator:
    """A loaded perception model folder (``perception.onnx`` + ``perception_contract.json``)."""

    directory: Path
    contract: dict[str, Any]
    onnx: Any
    #: The model's two parts (frame -> moments, moments -> state), if it was exported with them.
    parts: tuple[Any, Any] | None = None

    @staticmethod
    def load(path: Path | str) -> StateEstimator:
        """A model folder; its contract is validated and its ONNX files must lie inside the folder.

        Raises:
            DualtwinError: naming the contract's field, or the ONNX file, that is wrong.
        """
        folder = Path(path)
        contract = read_contract(folder / CONTRACT_FILE, "perception")
        checked = check_contract(contract, folder / CONTRACT_FILE)
        shape = checked.onnx.inputs[0].shape
        model = confined_file(folder, checked.onnx.file, f"{folder / CONTRACT_FILE}: $.onnx.file")
        session = onnx_session(model, "perception")
        expected = checked.onnx.sha256
        if expected and sha256_file(model) != expected:
            raise DualtwinError(f"{model}: sha256 differs from {CONTRACT_FILE} (the model was replaced or modified)")
        inputs, outputs = session.get_inputs(), session.get_outputs()
        if len(inputs) != 1 or inputs[0].type != "tensor(uint8)" or list(inputs[0].shape[1:]) != list(shape[1:]):
            raise DualtwinError(f"{model}: ONNX input {[(i.name, i.type, i.shape) for i in inputs]} does not match "
                                f"the contract (uint8 {list(shape)})")
        # Every request zips the output with the contract's state names: they must agree here, not per request.
        # A scalar or rank-less output has no last axis to compare: refused here, not an IndexError.
        if not outputs or len(outputs[0].shape or []) != 2 or outputs[0].shape[-1] != len(checked.state):
            raise DualtwinError(f"{model}: ONNX output {[(o.name, o.shape) for o in outputs]} does not give the "
                                f"contract's {len(checked.state)} state quantities")
        loaded = None
        if checked.onnx.parts is not None:
            loaded = tuple(_checked_session(confined_file(folder, part.file, f"{folder / CONTRACT_FILE}: "
                                                          f"$.onnx.parts.{key}.file"), part.sha256, key)
                           for key, part in (("frame", checked.onnx.parts.frame), ("head", checked.onnx.parts.head)))
        return StateEstimator(folder, contract, session, loaded)  # type: ignore[arg-type]

    @property
    def stack(self) -> int:
        return int(self.contract["onnx"]["inputs"][0]["shape"][1])

    @property
    def height(self) -> int:
        return int(self.contract["onnx"]["inputs"][0]["shape"][2])

    @property
    def width(self) -> int:
        return int(self.contract["onnx"]["inputs"][0]["shape"][3])

    @property
    def resolution(self) -> tuple[int, int]:
        return self.width, self.height

    @property
    def frame_period(self) -> float:
        return float(self.contract["frame_period_s"])

    @property
    def names(self) -> list[str]:
        return [str(s["name"]) for s in self.contract["state"]]

    def measurement_std(self, index: int) -> float:
        """Std of the model's error on one quantity: the Gaussian std for its held-out MAE (MAE × √(π/2))."""
        name = self.names[index]
        mae = (self.contract.get("validation") or {}).get(f"val_mae_{name}")
        if not isinstance(mae, (int, float)) or not mae > 0:
            raise DualtwinError(f"{self.directory / CONTRACT_FILE}: no validation MAE for {name!r}, which the "
                                "Kalman filter needs as its measurement noise (use velocity 'frame-stack')")
        return float(mae) * math.sqrt(math.pi / 2)

    def prior_std(self, index: int) -> float:
        """Spread of a quantity in the training labels: the filter's initial velocity uncertainty."""
        return float(self.contract["normalization"]["std"][index])

    def predict_stacks(self, stacks: np.ndarray, batch: int = 256) -> np.ndarray:
        """Frame stacks uint8 [B, k, H, W, 3] -> state [B, n] (no filtering)."""
        name = self.onnx.get_inputs()[0].name
        model = str(self.directory / self.contract["onnx"]["file"])
        out = [_checked_rows(run_session(self.onnx, {name: np.ascontiguousarray(part, dtype=np.uint8)}, model)[0],
                             len(part), len(self.names), model)
               for part in (stacks[i:i + batch] for i in range(0, len(stacks), batch))]
        return np.concatenate(out).astype(np.float32)

    def predict_single(self, frames: np.ndarray) -> np.ndarray:
        """Frames uint8 [B, H, W, 3] -> state [B, n] from each frame alone (repeated k times)."""
        if self.parts is not None:
            return self.head(np.repeat(self.moments(frames)[:, None], self.stack, axis=1))
        return self.predict_stacks(np.repeat(np.asarray(frames)[:, None], self.stack, axis=1))

    def moments(self, frames: np.ndarray) -> np.ndarray:
        """Frames uint8 [n, H, W, 3] -> per-frame mask moments [n, m] (models exported with parts)."""
        assert self.parts is not None
        model = str(self.directory / self.contract["onnx"]["parts"]["frame"]["file"])
        out = run_session(self.parts[0], {"frames": np.ascontiguousarray(frames, dtype=np.uint8)}, model)[0]
        return _checked_rows(out, len(frames), None, model)

    def head(self, moments: np.ndarray) -> np.ndarray:
        """Moments [B, k, m] of k frames, oldest first -> state [B, n] (models exported with parts)."""
        assert self.parts is not None
        model = str(self.directory / self.contract["onnx"]["parts"]["head"]["file"])
        out = run_session(self.parts[1], {"features": np.ascontiguousarray(moments, dtype=np.float32)}, model)[0]
        return _checked_rows(out, len(moments), len(self.names), model)

    def session(self, velocity: str = DEFAULT_VELOCITY) -> EstimatorSession:
        if velocity not in VELOCITY_MODES:
            raise DualtwinError(f"unknown velocity mode {velocity!r} (available: {', '.join(VELOCITY_MODES)})")
        if velocity == "kalman":
            for p, _ in FILTER_PAIRS:
                self.measurement_std(p)  # fail now, not at the first frame
        return EstimatorSession(self, velocity)


# --- the contract, validated where it is read (a model folder is untrusted input once it is shared) ------------

_Size = Annotated[int, Strict(), Field(ge=1, le=4096)]
_Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]


class _Input(BaseModel):
    dtype: Literal["uint8"]
    #: [batch, k frames, height, width, 3 channels]; the batch axis is a name or a number.
    shape: tuple[Any, Annotated[int, Strict(), Field(ge=1, le=64)], _Size, _Size, Literal[3]]


class _Part(BaseModel):
    file: str
    sha256: str


class _Parts(BaseModel):
    frame: _Part
    head: _Part


class _Onnx(BaseModel):
    file: str = MODEL_FILE
    sha256: str | None = None
    inputs: list[_Input] = Field(min_length=1)
    parts: _Parts | None = None

    @field_validator("parts", mode="before")
    @classmethod
    def _no_parts(cls, value: Any) -> Any:
        return value or None  # older exports write no parts, or an empty object


class _StateTerm(BaseModel):
    name: str


class _Normalization(BaseModel):
    mean: list[_Finite]
    std: list[Annotated[float, Strict(), Field(gt=0, allow_inf_nan=False)]]


class PerceptionContract(BaseModel):
    """The fields of ``perception_contract.json`` the estimator, the server and evaluation compute with (other
    fields are descriptive and kept as they are)."""

    kind: Literal["dualtwin-perception"]
    onnx: _Onnx
    frame_period_s: Annotated[float, Strict(), Field(gt=0, allow_inf_nan=False)]
    state: list[_StateTerm] = Field(min_length=1)
    normalization: _Normalization
    validation: dict[str, Any] | None = None
    trained_on: dict[str, Any] | None = None

    @model_validator(mode="after")
    def _one_entry_per_quantity(self) -> PerceptionContract:
        n = len(self.state)
        if len(self.normalization.mean) != n or len(self.normalization.std) != n:
            raise ValueError(f"normalization: mean and std need one entry per state quantity ({n})")
        return self


def check_contract(contract: dict[str, Any], path: Path) -> PerceptionContract:
    """``contract`` (read from ``path``) validated; a :class:`DualtwinError` naming the file and the field."""
    try:
        return PerceptionContract.model_validate(contract)
    except ValidationError as exc:
        raise DualtwinError(f"not a dualtwin perception contract: {validation_message(path, exc)}") from None


def _checked_rows(out: Any, rows: int, cols: int | None, model: str) -> np.ndarray:
    """An ONNX output as float32 [rows, cols]: the graph is untrusted and its declared shapes are not enforced by
    ORT, so another shape or type is one error here rather than a broadcast error in the filter."""
    array = np.asarray(out)
    if (not np.issubdtype(array.dtype, np.number) or array.ndim != 2 or array.shape[0] != rows
            or (cols is not None and array.shape[1] != cols)):
        raise DualtwinError(f"{model}: the ONNX output is {array.dtype} {list(array.shape)} for {rows} input(s), not "
                            f"float32 [{rows}, {cols if cols is not None else 'features'}]")
    return array.astype(np.float32)


def _checked_session(path: Path, sha256: str, what: str) -> Any:
    session = onnx_session(path, f"perception {what} part")
    if sha256_file(path) != sha256:
        raise DualtwinError(f"{path}: sha256 differs from {CONTRACT_FILE} (the model was replaced or modified)")
    return session


@dataclass
class _Track:
    """Constant-velocity Kalman filter of one (position, velocity) pair; 2x2 algebra written out (it runs per
    request)."""

    r: float  # measurement variance
    q: float  # white-acceleration spectral density: acceleration variance × dt
    v0: float  # initial velocity variance
    x: tuple[float, float] | None = None
    P: tuple[float, float, float] = (0.0, 0.0, 0.0)  # p00, p01, p11

    def update(self, z: float, dt: float) -> tuple[float, float]:
        if self.x is None:
            self.x, self.P = (z, 0.0), (self.r, 0.0, self.v0)  # every episode starts at rest
            return self.x
        (p, v), (a, b, c), q = self.x, self.P, self.q
        # Predict: x = F x, P = F P Fᵀ + Q, with F = [[1, dt], [0, 1]] and the white-acceleration Q.
        p += v * dt
        a, b, c = (a + 2 * dt * b + dt * dt * c + q * dt ** 3 / 3, b + dt * c + q * dt * dt / 2, c + q * dt)
        # Correct with the position measurement.
        s = a + self.r
        k0, k1 = a / s, b / s
        residual = z - p
        self.x = (p + k0 * residual, v + k1 * residual)
        self.P = (a - k0 * a, b - k0 * b, c - k1 * b)
        return self.x


@dataclass
class EstimatorSession:
    """One camera stream: its frame history and filter state."""

    estimator: StateEstimator
    velocity: str = DEFAULT_VELOCITY
    frames: deque[np.ndarray] = field(default_factory=deque)
    tracks: dict[int, _Track] = field(default_factory=dict)
    steps: int = 0

    def reset(self) -> None:
        self.frames.clear()
        self.tracks.clear()
        self.steps = 0

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Add the newest frame (uint8 [H, W, 3]) and return the state estimate."""
        est = self.estimator
        if frame.shape != (est.height, est.width, 3) or frame.dtype != np.uint8:
            raise DualtwinError(f"frame must be uint8 [{est.height}, {est.width}, 3], got {frame.dtype} "
                                f"{list(frame.shape)}")
        self.steps += 1
        if self.velocity == "kalman":
            return self.filter(est.predict_single(frame[None])[0])
        # The history holds per-frame moments when the model has parts (each frame segmented once), else frames.
        item = est.moments(frame[None])[0] if est.parts is not None else frame
        k = est.stack
        if not self.frames:
            self.frames.extend([item] * k)  # repeat the first frame, as the model was trained
        else:
            self.frames.append(item)
            while len(self.frames) > k:
                self.frames.popleft()
        if est.parts is not None:
            return est.head(np.stack(self.frames)[None])[0]
        return est.predict_stacks(np.stack(self.frames)[None])[0]

    def filter(self, raw: np.ndarray) -> np.ndarray:
        """Kalman-filter one raw prediction: positions and velocities re-estimated from the positions."""
        est = self.estimator
        out = np.asarray(raw, dtype=np.float32).copy()
        for p, v in FILTER_PAIRS:
            track = self.tracks.get(p)
            if track is None:
                track = self.tracks[p] = _Track(est.measurement_std(p) ** 2,
                                                ACCEL_STD[p] ** 2 * est.frame_period, est.prior_std(v) ** 2)
            out[p], out[v] = track.update(float(raw[p]), est.frame_period)
        return out
