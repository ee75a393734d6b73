"""An exported policy (``policy.onnx`` + ``policy_contract.json``) run with ONNX Runtime: no PyTorch, no pickle.

The contract is written by :func:`dualtwin.rl.export_policy`: the observation terms (name, unit, order,
``onboard``/``privileged`` source), the action (discrete speed table or continuous scaling) and the control
period. Normalisation and action scaling are inside the graph.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field, Strict, ValidationError, model_validator

from dualtwin.artifacts import read_json_object, sha256_file
from dualtwin.errors import DualtwinError
from dualtwin.models import validation_message
from dualtwin.onnx_models import RUN_LIMIT_S, check_float_input, open_session, run_session

POLICY_FILE = "policy.onnx"
POLICY_CONTRACT = "policy_contract.json"


def onnx_session(path: Path, what: str) -> Any:
    """An ONNX Runtime CPU session, or a :class:`DualtwinError` saying the file is not a usable ONNX model."""
    return open_session(path, what)


def read_contract(path: Path, what: str) -> dict[str, Any]:
    """A contract file as a JSON object: strict JSON (no NaN or Infinity tokens, which the server could not send
    back in /v1/info, no duplicate keys, bounded size and depth), errors naming the file."""
    if not path.is_file():
        raise DualtwinError(f"{path}: {what} contract not found")
    return read_json_object(path, what=f"{what} contract")


_Name = Annotated[str, Strict(), Field(min_length=1)]


class _Term(BaseModel):
    name: _Name
    source: str


class _Action(BaseModel):
    type: Literal["discrete", "box"]
    names: list[_Name] = Field(default_factory=lambda: ["command"], min_length=1)
    unit: str | None = None
    actuators: list[str] | None = None
    wheel_radius_m: Annotated[float, Strict(), Field(gt=0, allow_inf_nan=False)] | None = None


class _PolicyOnnx(BaseModel):
    sha256: str | None = None


class PolicyContract(BaseModel):
    """The fields of ``policy_contract.json`` the policy, the server and camera-only deployment compute with
    (other fields are descriptive and kept as they are)."""

    observation: list[_Term] = Field(min_length=1)
    action: _Action
    control_period_s: Annotated[float, Strict(), Field(gt=0, allow_inf_nan=False)]
    onnx: _PolicyOnnx = Field(default_factory=_PolicyOnnx)

    @model_validator(mode="after")
    def _unique_names(self) -> PolicyContract:
        names = [t.name for t in self.observation]
        if len(set(names)) != len(names):
            # An observation is assembled by name: a repeated name would leave the policy an input short.
            raise ValueError(f"observation names must be unique, got {names}")
        return self


@dataclass
class OnnxPolicy:
    """A policy folder loaded for inference."""

    directory: Path
    contract: dict[str, Any]
    session: Any
    #: Seconds one inference may take before it is stopped (:func:`dualtwin.onnx_models.run_session`).
    run_limit_s: float = RUN_LIMIT_S

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
        try:
            checked = PolicyContract.model_validate(contract)
        except ValidationError as exc:
            raise DualtwinError(f"not a dualtwin policy contract: "
                                f"{validation_message(folder / POLICY_CONTRACT, exc)}") from None
        model = folder / POLICY_FILE
        session = onnx_session(model, "policy")
        expected = checked.onnx.sha256
        if expected and sha256_file(model) != expected:
            raise DualtwinError(f"{model}: sha256 differs from {POLICY_CONTRACT} (the model was replaced or modified)")
        n = len(checked.observation)
        check_float_input(session, model, f"does not take the contract's {n} float observations", width=n)
        outputs = session.get_outputs()
        # The outputs are the action and one command per action name: the server zips them per request.
        if len(outputs) != 1 + len(checked.action.names):
            raise DualtwinError(f"{model}: {len(outputs)} ONNX outputs, the contract's action needs the action and "
                                f"one command per name in {checked.action.names}")
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
        action, *commands = run_session(self.session, {self.session.get_inputs()[0].name: obs},
                                        str(self.directory / POLICY_FILE), self.run_limit_s)
        action, commands = np.asarray(action), [np.asarray(c) for c in commands]
        # The graph is untrusted: its outputs are checked against the contract before anyone zips or indexes them.
        rows = obs.shape[0]
        wrong = [a for a in (action, *commands) if not np.issubdtype(a.dtype, np.number) or a.shape[:1] != (rows,)]
        if wrong or any(c.shape != (rows,) for c in commands):
            got = [f"{a.dtype} {list(a.shape)}" for a in (action, *commands)]
            raise DualtwinError(f"{self.directory / POLICY_FILE}: the ONNX outputs are {got} for {rows} observation(s); "
                                f"the contract needs a numeric action and one number per command per observation")
        return action, np.stack(commands, axis=-1)

    def action(self, observation: np.ndarray) -> Any:
        """The env action for one raw observation (int for discrete policies, float32 [1] for continuous)."""
        action, _ = self.run(observation)
        return int(action[0]) if self.discrete else action[0].astype(np.float32)
