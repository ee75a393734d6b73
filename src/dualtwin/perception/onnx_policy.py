"""An exported policy (``policy.onnx`` + ``policy_contract.json``) run with ONNX Runtime: no PyTorch, no pickle.

The contract is written by :func:`dualtwin.rl.export_policy`: the observation terms (name, unit, order,
``onboard``/``privileged`` source), the action (discrete speed table or continuous scaling) and the control
period. Normalisation and action scaling are inside the graph.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import sha256_file
from dualtwin.errors import DualtwinError

POLICY_FILE = "policy.onnx"
POLICY_CONTRACT = "policy_contract.json"


def onnx_session(path: Path, what: str) -> Any:
    """An ONNX Runtime CPU session, or a :class:`DualtwinError` saying the file is not a usable ONNX model."""
    import onnxruntime as ort

    if not path.is_file():
        raise DualtwinError(f"{path}: {what} model file not found")
    options = ort.SessionOptions()
    # Small models, many concurrent requests: one intra-op thread per run, concurrency across requests.
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    try:
        return ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises several private exception types
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DualtwinError(f"{path}: not a valid ONNX {what} model ({first[:200]})") from None


def read_contract(path: Path, what: str) -> dict[str, Any]:
    if not path.is_file():
        raise DualtwinError(f"{path}: {what} contract not found")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DualtwinError(f"{path}: {what} contract is not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise DualtwinError(f"{path}: {what} contract must be a JSON object")
    return data


@dataclass
class OnnxPolicy:
    """A policy folder loaded for inference."""

    directory: Path
    contract: dict[str, Any]
    session: Any

    @staticmethod
    def load(path: Path | str) -> OnnxPolicy:
        """An exported policy folder, or a training run (``run.json``) exported to a temporary folder first.

        Exporting a run loads its SB3 model and statistics (our own artifacts); the server never does this,
        it uses :meth:`load_exported`.
        """
        folder = Path(path)
        if not (folder / POLICY_FILE).is_file() and (folder / "run.json").is_file():
            from dualtwin.rl.export import export_policy

            tmp = Path(tempfile.mkdtemp(prefix="dualtwin-policy-"))
            export_policy(folder, tmp)
            folder = tmp
        return OnnxPolicy.load_exported(folder)

    @staticmethod
    def load_exported(path: Path | str) -> OnnxPolicy:
        """``policy.onnx`` + ``policy_contract.json`` only (ONNX Runtime; nothing is unpickled)."""
        folder = Path(path)
        if not folder.is_dir():
            raise DualtwinError(f"{folder}: policy folder not found")
        contract = read_contract(folder / POLICY_CONTRACT, "policy")
        for key in ("observation", "action", "control_period_s"):
            if key not in contract:
                raise DualtwinError(f"{folder / POLICY_CONTRACT}: policy contract has no {key!r}")
        if not isinstance(contract["observation"], list) or not all(
                isinstance(t, dict) and "name" in t and "source" in t for t in contract["observation"]):
            raise DualtwinError(f"{folder / POLICY_CONTRACT}: 'observation' must list terms with 'name' and 'source'")
        model = folder / POLICY_FILE
        session = onnx_session(model, "policy")
        expected = contract.get("onnx", {}).get("sha256")
        if expected and sha256_file(model) != expected:
            raise DualtwinError(f"{model}: sha256 differs from {POLICY_CONTRACT} (the model was replaced or modified)")
        inputs = session.get_inputs()
        n = len(contract["observation"])
        if len(inputs) != 1 or inputs[0].type != "tensor(float)" or inputs[0].shape[-1] != n:
            raise DualtwinError(f"{model}: ONNX input {[(i.name, i.type, i.shape) for i in inputs]} does not take "
                                f"the contract's {n} float observations")
        return OnnxPolicy(folder, contract, session)

    @property
    def terms(self) -> list[dict[str, Any]]:
        return list(self.contract["observation"])

    @property
    def names(self) -> list[str]:
        return [str(t["name"]) for t in self.terms]

    @property
    def onboard(self) -> list[str]:
        return [str(t["name"]) for t in self.terms if t.get("source") == "onboard"]

    @property
    def privileged(self) -> list[str]:
        return [str(t["name"]) for t in self.terms if t.get("source") != "onboard"]

    @property
    def control_period(self) -> float:
        return float(self.contract["control_period_s"])

    @property
    def discrete(self) -> bool:
        return self.contract["action"].get("type") == "discrete"

    def run(self, observation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw observations [batch, n] -> (env actions, physical commands [batch, one per contract name])."""
        obs = np.asarray(observation, dtype=np.float32).reshape(-1, len(self.terms))
        action, *commands = self.session.run(None, {self.session.get_inputs()[0].name: obs})
        return np.asarray(action), np.stack([np.asarray(c) for c in commands], axis=-1)

    def action(self, observation: np.ndarray) -> Any:
        """The env action for one raw observation (int for discrete policies, float32 [1] for continuous)."""
        action, _ = self.run(observation)
        return int(action[0]) if self.discrete else action[0].astype(np.float32)
