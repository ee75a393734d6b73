"""A trained run restored in one line (model + VecNormalize statistics), and the I/O contract check.

``policy = load_policy("runs/ppo")``; ``action = policy.predict(obs)`` takes a raw env observation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from dualtwin.artifacts import read_json
from dualtwin.errors import DualtwinError

if TYPE_CHECKING:
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize


@dataclass
class LoadedPolicy:
    """A trained policy with the observation normalisation it was trained with."""

    run_dir: Path
    model: PPO
    vec_normalize: VecNormalize | None
    env_id: str
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    contract: dict[str, Any] = field(default_factory=dict)
    max_episode_steps: int | None = None

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """Raw env observation(s) -> what the network sees (VecNormalize's clip((obs - mean) / std))."""
        if self.vec_normalize is None:
            return np.asarray(obs, dtype=np.float32)
        return np.asarray(self.vec_normalize.normalize_obs(np.asarray(obs, dtype=np.float32)))

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> Any:
        """The env action for a raw observation (or a batch of them)."""
        action, _ = self.model.predict(self.normalize(obs), deterministic=deterministic)
        return action

    def make_env(self, **overrides: Any) -> gym.Env[Any, Any]:
        """The env the policy was trained in (same id and arguments), without domain randomisation."""
        from dualtwin.rl import make_env

        kwargs = dict(self.env_kwargs)
        if self.max_episode_steps is not None:
            kwargs.setdefault("max_episode_steps", self.max_episode_steps)
        kwargs.update(overrides)
        return make_env(self.env_id, **kwargs)


def load_policy(run_dir: Path | str, which: Literal["final", "best"] = "final", *,
                trust_pickles: bool | None = None) -> LoadedPolicy:
    """Restore a training run's policy: ``model.zip`` + ``vecnormalize.json`` (``best_*`` with ``which="best"``).

    Nothing is unpickled (:mod:`dualtwin.rl.runfiles`); an old run's ``vecnormalize.pkl``, or a model zip whose
    pickled entries its ``run.json`` cannot rebuild, is refused unless ``trust_pickles`` (default: the
    CLI's ``--trust-pickles``, :func:`dualtwin.rl.runfiles.trusting_pickles`).
    """
    from dualtwin.rl.runfiles import load_model, load_normalization, stats_path

    run = Path(run_dir)
    record_path = run / "run.json"
    if not record_path.is_file():
        raise DualtwinError(f"{run}: not a training run (no run.json)")
    # strict JSON (our writer never writes NaN): a NaN in the I/O contract went on into the exported files,
    # whose writer refused it with a traceback, after policy.onnx was written
    record = read_json(record_path, "run record")
    if not isinstance(record, dict) or not isinstance(record.get("env_id"), str):
        raise DualtwinError(f"{record_path}: not a training run record (no env_id)")
    env_kwargs, io = _checked_record(record, record_path)
    prefix = "" if which == "final" else "best_"
    model_path = run / f"{prefix}model.zip"
    if not model_path.is_file():
        hint = " (the run did not finish; resume it)" if which == "final" else ""
        raise DualtwinError(f"{run}: no {model_path.name}{hint}")
    found = stats_path(run, f"{prefix}vecnormalize")
    stats: VecNormalize | None = None
    if found is not None:
        shape = tuple((record.get("io") or {}).get("observation", {}).get("shape") or ()) or None
        stats = load_normalization(found, trust_pickles=trust_pickles, obs_shape=shape)
        stats.training = False
        stats.norm_reward = False
    elif record.get("config", {}).get("normalize") not in (False, None):
        raise DualtwinError(f"{run}: {prefix}vecnormalize.json is missing; the policy needs its normalisation "
                            "statistics")
    model = load_model(model_path, record, trust_pickles=trust_pickles)
    return LoadedPolicy(run, model, stats, record["env_id"], env_kwargs, io, record.get("max_episode_steps"))


def _checked_record(record: dict[str, Any], path: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """The env arguments and I/O contract of a run record, checked before anything is built from them: a run
    folder is untrusted data, and an unregistered ``env_id`` was a Gymnasium traceback, ``env_kwargs: "abc"``
    a TypeError in ``dict()`` (found by fuzzing ``dualtwin transfer`` and ``dualtwin lockstep``)."""
    from dualtwin.rl import check_env_id
    from dualtwin.rl.ppo_config import check_env_kwargs

    try:
        check_env_id(record["env_id"])
    except DualtwinError as exc:
        raise DualtwinError(f"{path}: {exc}") from None
    env_kwargs = check_env_kwargs(record.get("env_kwargs"), str(path))
    io = record.get("io") or {}
    if not isinstance(io, dict):
        raise DualtwinError(f"{path}: io must be a JSON object, got {type(io).__name__}")
    # the observation's shape sizes the normalisation and its terms are compared with the target env's by
    # name (_signature): io.observation: 5 was an AttributeError there
    observation, action = io.get("observation", {}), io.get("action", {})
    shape = observation.get("shape") or [] if isinstance(observation, dict) else None
    terms = observation.get("terms") or [] if isinstance(observation, dict) else None
    if not (isinstance(shape, list) and all(type(n) is int and n >= 0 for n in shape)
            and isinstance(terms, list) and all(isinstance(t, dict) for t in terms)):
        raise DualtwinError(f"{path}: io.observation must be an object with a shape (a list of whole numbers) "
                            "and terms (a list of objects)")
    if not isinstance(action, dict):
        raise DualtwinError(f"{path}: io.action must be a JSON object, got {type(action).__name__}")
    steps = record.get("max_episode_steps")
    # the time limit the training env had (EnvOptions' bounds): each transfer episode runs up to it
    if steps is not None and (type(steps) is not int or not 1 <= steps <= 10**9):
        raise DualtwinError(f"{path}: max_episode_steps must be a whole number from 1 to {10**9}, got {steps!r}")
    return env_kwargs, io


def _signature(contract: dict[str, Any]) -> dict[str, Any]:
    obs = contract.get("observation", {})
    action = dict(contract.get("action", {}))
    # The actuator wiring may differ between twins; what the policy emits may not.
    for key in ("actuators", "to_actuator", "wheel_radius_m"):
        action.pop(key, None)
    return {
        "observation names": [t.get("name") for t in obs.get("terms", [])],
        "observation units": [t.get("unit") for t in obs.get("terms", [])],
        "observation sources": [f"{t.get('source')}:{t.get('channel')}" for t in obs.get("terms", [])],
        "observation shape": obs.get("shape"),
        "observation dtype": obs.get("dtype"),
        "action": action,
        "control period": contract.get("control_period_s"),
    }


def contract_mismatches(policy: dict[str, Any], env: dict[str, Any]) -> list[str]:
    """What differs between a policy's I/O contract and an env's (empty if the policy can run there)."""
    a, b = _signature(policy), _signature(env)
    return [f"{key}: policy {a[key]!r} vs env {b[key]!r}" for key in a if a[key] != b[key]]


def check_contract(policy: dict[str, Any], env: dict[str, Any], env_id: str) -> None:
    """Raise a :class:`DualtwinError` naming every mismatch between the policy's and the env's I/O."""
    problems = contract_mismatches(policy, env)
    if problems:
        raise DualtwinError(f"policy trained on {policy.get('env_id')!r} does not match {env_id!r}: "
                            + "; ".join(problems))
