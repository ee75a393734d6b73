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
from dualtwin.onnx_models import RUN_LIMIT_S, check_float_input, open_session, run_session


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
    #: Seconds one inference may take before it is stopped (:func:`dualtwin.onnx_models.run_session`).
    run_limit_s: float = RUN_LIMIT_S

    def act(self, observation: np.ndarray) -> Any:
        obs = np.asarray(observation, dtype=np.float32).reshape(1, -1)
        if self.kind == "onnx":
            model = str(self.path / "policy.onnx")
            action = np.asarray(run_session(self._session, {self._session.get_inputs()[0].name: obs}, model,
                                            self.run_limit_s)[0])
            if action.size == 0 or not np.issubdtype(action.dtype, np.number):
                raise DualtwinError(f"{model}: the ONNX model's action is {action.dtype} {list(action.shape)}, "
                                    "not a number per observation")
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


def check_task_arguments(policy: LockstepPolicy, origin: Path) -> None:
    """The task the policy's env arguments build, checked as every env's are (:func:`dualtwin.rl.env.check_task_kwargs`:
    the task constructor's options, strict types, finite numbers): they come from a file (``policy_contract.json``
    or ``run.json``), and a wrong one was a TypeError mid-run."""
    from dualtwin.rl.env import TASKS, check_task_kwargs

    args = policy.task_arguments()
    name = args.get("task", "cartpole_balance")
    if not isinstance(name, str) or name not in TASKS:
        raise DualtwinError(f"{origin}: $.env_kwargs.task: unknown task {name!r} (known: {sorted(TASKS)})")
    if not isinstance(args.get("continuous", False), bool):
        raise DualtwinError(f"{origin}: $.env_kwargs.continuous: Input should be a valid boolean (task {name!r})")
    check_task_kwargs(name, args.get("task_kwargs"), f"{origin}: $.env_kwargs.task_kwargs")


def _checked_contract(contract: dict[str, Any], path: Path) -> tuple[str, dict[str, Any]]:
    """The env id and ``env_kwargs`` of an export's contract, checked before the twins are built: the contract
    is untrusted data, and ``env_kwargs: "abc"``, ``action: 5`` or ``env_kwargs.control_period: "x"`` were
    tracebacks in ``dict()``, :meth:`LockstepPolicy.act` and ``float()`` (found by fuzzing ``dualtwin lockstep``)."""
    from dualtwin.rl.ppo_config import check_env_kwargs

    env_id = contract.get("env_id", "")
    if not isinstance(env_id, str):
        raise DualtwinError(f"{path}: $.env_id must be a string, got {type(env_id).__name__}")
    action = contract.get("action", {})
    if not isinstance(action, dict) or action.get("type", "box") not in ("discrete", "box"):
        raise DualtwinError(f"{path}: $.action must be an object whose type is 'discrete' or 'box'")
    return env_id, check_env_kwargs(contract.get("env_kwargs"), str(path))


def load_policy(path: Path | str) -> LockstepPolicy:
    """An exported folder (``policy.onnx`` + ``policy_contract.json``) or a training run (``run.json``)."""
    folder = Path(path)
    if (folder / "policy.onnx").is_file():
        contract_path = folder / "policy_contract.json"
        if not contract_path.is_file():
            raise DualtwinError(f"{folder}: policy.onnx without policy_contract.json")
        from dualtwin.artifacts import read_json_object

        contract = read_json_object(contract_path, what="policy contract")  # names file, line and column
        model = folder / "policy.onnx"
        session = open_session(model, "policy")
        check_float_input(session, model, "is not one float32 [batch, observations] tensor")
        env_id, env_kwargs = _checked_contract(contract, contract_path)
        policy = LockstepPolicy(folder, "onnx", env_id, env_kwargs, contract, _session=session)
        check_task_arguments(policy, contract_path)
        return policy
    if (folder / "run.json").is_file():
        from dualtwin.rl.policy import load_policy as load_run

        loaded = load_run(folder)
        policy = LockstepPolicy(folder, "run", loaded.env_id, dict(loaded.env_kwargs), dict(loaded.contract),
                                _loaded=loaded)
        check_task_arguments(policy, folder / "run.json")
        return policy
    raise DualtwinError(f"{folder}: not a policy (no policy.onnx) and not a training run (no run.json)")
