"""Policies for lockstep runs: an exported ONNX policy folder or a training run, acting on a task's observation.

Both kinds carry the env id and arguments they were trained with, so the task (observation, action scaling,
episode start) is rebuilt from them and bound to each twin. Imports of ONNX Runtime and of
:mod:`dualtwin.rl` (Gymnasium, and PyTorch/SB3 for runs) are lazy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import sha256_file
from dualtwin.errors import DualtwinError


@dataclass
class LockstepPolicy:
    """``act(observation) -> env action`` plus what is needed to rebuild its task."""

    path: Path
    kind: str  # "onnx" | "run"
    env_id: str
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    contract: dict[str, Any] = field(default_factory=dict)
    _session: Any = None
    _loaded: Any = None

    def act(self, observation: np.ndarray) -> Any:
        obs = np.asarray(observation, dtype=np.float32).reshape(1, -1)
        if self.kind == "onnx":
            action = self._session.run(None, {self._session.get_inputs()[0].name: obs})[0]
            action = np.asarray(action)
            discrete = self.contract.get("action", {}).get("type") == "discrete"
            return int(action.reshape(-1)[0]) if discrete else action.reshape(-1).astype(np.float32)
        return self._loaded.predict(obs[0])

    def task_arguments(self) -> dict[str, Any]:
        """``TwinEnv`` keyword arguments (minus the twin) of the env the policy was trained in."""
        from dualtwin.rl import ENV_IDS

        base = dict(ENV_IDS.get(self.env_id, {}))
        base.update(self.env_kwargs)
        base.pop("twin", None)
        base.pop("max_episode_steps", None)
        return base

    def digest(self) -> str:
        model = self.path / "policy.onnx" if self.kind == "onnx" else self.path / "model.zip"
        return sha256_file(model) if model.is_file() else ""


def load_policy(path: Path | str) -> LockstepPolicy:
    """An exported folder (``policy.onnx`` + ``policy_contract.json``) or a training run (``run.json``)."""
    folder = Path(path)
    if (folder / "policy.onnx").is_file():
        import onnxruntime as ort

        contract_path = folder / "policy_contract.json"
        if not contract_path.is_file():
            raise DualtwinError(f"{folder}: policy.onnx without policy_contract.json")
        from dualtwin.artifacts import read_json_object

        contract = read_json_object(contract_path, what="policy contract")  # names file, line and column
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        try:
            session = ort.InferenceSession(str(folder / "policy.onnx"), sess_options=options,
                                           providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises several private exception types
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise DualtwinError(f"{folder / 'policy.onnx'}: not a valid ONNX policy ({first[:200]})") from None
        return LockstepPolicy(folder, "onnx", str(contract.get("env_id", "")), dict(contract.get("env_kwargs") or {}),
                              contract, _session=session)
    if (folder / "run.json").is_file():
        from dualtwin.rl.policy import load_policy as load_run

        loaded = load_run(folder)
        return LockstepPolicy(folder, "run", loaded.env_id, dict(loaded.env_kwargs), dict(loaded.contract),
                              _loaded=loaded)
    raise DualtwinError(f"{folder}: not a policy (no policy.onnx) and not a training run (no run.json)")
