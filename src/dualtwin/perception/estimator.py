"""Run an exported perception model (ONNX Runtime, no PyTorch): frames in, state estimate out.

A :class:`StateEstimator` holds the model; each robot (or server client) gets an :class:`EstimatorSession` that
keeps its own last-k frame history and filter state. Velocity options:

* ``alpha-beta`` (default): an α-β filter on the CNN's positions (cart position, pole angle). Per period
  ``dt``: predict ``p += v dt``; residual ``r = z - p``; correct ``p += α r``, ``v += β r / dt`` (α = 0.6,
  β = 0.15). It trades a little lag for much less noise than a finite difference (α = β = 1).
* ``frame-stack``: the CNN's own velocity outputs. At 64x64 the motion over k = 3 frames is a fraction of a
  pixel (0.3 rad/s moves the pole tip by 0.4 px a period), so these stay close to the training mean: with them
  the reference policy lost the pole in the Webots twin, with the α-β filter it balanced in both twins.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import sha256_file
from dualtwin.errors import DualtwinError
from dualtwin.perception.onnx_policy import onnx_session, read_contract

MODEL_FILE = "perception.onnx"
CONTRACT_FILE = "perception_contract.json"
VELOCITY_MODES = ("alpha-beta", "frame-stack")
DEFAULT_VELOCITY = "alpha-beta"
ALPHA, BETA = 0.6, 0.15
#: (position index, velocity index) pairs of the state vector the α-β filter links.
FILTER_PAIRS = ((0, 1), (2, 3))


@dataclass
class StateEstimator:
    """A loaded perception model folder (``perception.onnx`` + ``perception_contract.json``)."""

    directory: Path
    contract: dict[str, Any]
    onnx: Any

    @staticmethod
    def load(path: Path | str) -> StateEstimator:
        folder = Path(path)
        contract = read_contract(folder / CONTRACT_FILE, "perception")
        try:
            spec = contract["onnx"]["inputs"][0]
            shape = spec["shape"]
            if contract.get("kind") != "dualtwin-perception" or spec["dtype"] != "uint8" or len(shape) != 5:
                raise KeyError("kind/input")
            _ = contract["frame_period_s"], contract["state"]
        except (KeyError, IndexError, TypeError) as exc:
            raise DualtwinError(f"{folder / CONTRACT_FILE}: not a dualtwin perception contract ({exc})") from None
        model = folder / str(contract["onnx"].get("file", MODEL_FILE))
        session = onnx_session(model, "perception")
        expected = contract["onnx"].get("sha256")
        if expected and sha256_file(model) != expected:
            raise DualtwinError(f"{model}: sha256 differs from {CONTRACT_FILE} (the model was replaced or modified)")
        inputs = session.get_inputs()
        if len(inputs) != 1 or inputs[0].type != "tensor(uint8)" or list(inputs[0].shape[1:]) != list(shape[1:]):
            raise DualtwinError(f"{model}: ONNX input {[(i.name, i.type, i.shape) for i in inputs]} does not match "
                                f"the contract (uint8 {shape})")
        return StateEstimator(folder, contract, session)

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

    def predict_stacks(self, stacks: np.ndarray, batch: int = 256) -> np.ndarray:
        """Frame stacks uint8 [B, k, H, W, 3] -> state [B, n] (no filtering)."""
        name = self.onnx.get_inputs()[0].name
        out = [self.onnx.run(None, {name: np.ascontiguousarray(stacks[i:i + batch], dtype=np.uint8)})[0]
               for i in range(0, len(stacks), batch)]
        return np.concatenate(out).astype(np.float32)

    def session(self, velocity: str = DEFAULT_VELOCITY) -> EstimatorSession:
        if velocity not in VELOCITY_MODES:
            raise DualtwinError(f"unknown velocity mode {velocity!r} (available: {', '.join(VELOCITY_MODES)})")
        return EstimatorSession(self, velocity)


@dataclass
class EstimatorSession:
    """One camera stream: its frame history and filter state."""

    estimator: StateEstimator
    velocity: str = DEFAULT_VELOCITY
    frames: deque[np.ndarray] = field(default_factory=deque)
    _filtered: np.ndarray | None = None
    steps: int = 0

    def reset(self) -> None:
        self.frames.clear()
        self._filtered = None
        self.steps = 0

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Add the newest frame (uint8 [H, W, 3]) and return the state estimate."""
        est = self.estimator
        if frame.shape != (est.height, est.width, 3) or frame.dtype != np.uint8:
            raise DualtwinError(f"frame must be uint8 [{est.height}, {est.width}, 3], got {frame.dtype} "
                                f"{list(frame.shape)}")
        k = est.stack
        if not self.frames:
            self.frames.extend([frame] * k)  # repeat the first frame, as the model was trained
        else:
            self.frames.append(frame)
            while len(self.frames) > k:
                self.frames.popleft()
        raw = est.predict_stacks(np.stack(self.frames)[None])[0]
        self.steps += 1
        return self.filter(raw) if self.velocity == "alpha-beta" else raw

    def filter(self, raw: np.ndarray) -> np.ndarray:
        """α-β filter one raw prediction (positions from ``raw``; velocities re-estimated)."""
        dt = self.estimator.frame_period
        if self._filtered is None:
            self._filtered = np.asarray(raw, dtype=np.float64).copy()
            for _, v in FILTER_PAIRS:
                self._filtered[v] = 0.0  # at rest after a reset, as every episode starts
            return self._filtered.astype(np.float32)
        state = self._filtered
        for p, v in FILTER_PAIRS:
            predicted = state[p] + state[v] * dt
            residual = float(raw[p]) - predicted
            state[p] = predicted + ALPHA * residual
            state[v] = state[v] + BETA * residual / dt
        return state.astype(np.float32)
