"""Reading and writing a training run's model and normalisation files without unpickling anything.

A run folder is untrusted data once it is shared. Two of its files are pickles in Stable-Baselines3's own
formats, and loading either would run any code a malicious author put in it:

* ``vecnormalize.pkl`` (``VecNormalize.save``). We write the statistics as JSON instead
  (``vecnormalize.json``: running mean, variance and count of observations and returns, and the settings) and
  rebuild a ``VecNormalize`` from it. An old run's ``.pkl`` is read only when the user says so explicitly
  (``trust_pickles=True``, ``--trust-pickles`` on the command line).
* ``model.zip``: SB3 stores its weights as ``.pth`` tensors (which SB3 >= 2.3 reads with
  ``torch.load(weights_only=True)``, refusing pickled objects) and everything else in a JSON ``data`` entry in
  which the values JSON cannot hold (the policy class and its keyword arguments, the observation and action
  spaces, the rollout-buffer class, the learning-rate and clip-range schedules, and after training the last
  observations and episode buffers) are base64 cloudpickles. SB3's ``custom_objects`` replaces an entry before
  it is unpickled, so :func:`load_model` supplies one for *every* cloudpickled entry of the zip, rebuilt from the
  run's ``run.json`` (the PPO config and the I/O contract) and checked against the readable summary SB3 writes
  next to each pickle. An entry it cannot rebuild (a zip from another tool, a tampered one) is refused unless
  the user trusts the file.

:func:`trusting_pickles` sets the default for code that loads runs on the user's behalf without a parameter of
its own (lockstep, dataset collection), so the CLI's ``--trust-pickles`` reaches them.
"""

from __future__ import annotations

import contextlib
import json
import math
import pickle
import zipfile
from collections.abc import Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.artifacts import write_json
from dualtwin.errors import DualtwinError

if TYPE_CHECKING:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnv, VecNormalize

STATS_FORMAT = "dualtwin-vecnormalize/1"
TRUST_HINT = "pass --trust-pickles (trust_pickles=True) only if you trust whoever wrote it"
# Cloudpickled entries of a model zip that only matter while a run is in progress: SB3 recreates them when
# training starts (it resets the envs when there is no last observation, and makes new episode buffers).
_TRANSIENT = ("_last_obs", "_last_original_obs", "_last_episode_starts", "ep_info_buffer", "ep_success_buffer",
              "action_noise")
_trust: ContextVar[bool] = ContextVar("dualtwin_trust_pickles", default=False)


@contextlib.contextmanager
def trusting_pickles(trust: bool = True) -> Iterator[None]:
    """Within this block, loaders called without ``trust_pickles`` use ``trust`` (the CLI's ``--trust-pickles``)."""
    token = _trust.set(bool(trust))
    try:
        yield
    finally:
        _trust.reset(token)


def resolve_trust(trust_pickles: bool | None) -> bool:
    return _trust.get() if trust_pickles is None else bool(trust_pickles)


# --- normalisation statistics -------------------------------------------------------------------------------


def stats_path(folder: Path, stem: str) -> Path | None:
    """``stem.json`` if present, else a legacy ``stem.pkl``, else None."""
    for suffix in (".json", ".pkl"):
        path = folder / f"{stem}{suffix}"
        if path.is_file():
            return path
    return None


def save_normalization(stats: VecNormalize, path: Path) -> None:
    """Write ``stats`` as JSON (floats round-trip exactly), atomically."""

    def rms(r: Any) -> dict[str, Any]:
        return {"mean": np.asarray(r.mean, dtype=np.float64).tolist(),
                "var": np.asarray(r.var, dtype=np.float64).tolist(), "count": float(r.count)}

    if getattr(stats, "norm_obs_keys", None):
        raise DualtwinError("dict observations are not supported by the JSON normalisation format")
    write_json(path, {"format": STATS_FORMAT, "norm_obs": bool(stats.norm_obs), "norm_reward": bool(stats.norm_reward),
                      "clip_obs": float(stats.clip_obs), "clip_reward": float(stats.clip_reward),
                      "gamma": float(stats.gamma), "epsilon": float(stats.epsilon),
                      # Without observation normalisation VecNormalize keeps no observation statistics.
                      "obs_rms": rms(stats.obs_rms) if stats.norm_obs else None, "ret_rms": rms(stats.ret_rms)})


def _read_rms(data: Any, where: str, shape: tuple[int, ...] | None) -> Any:
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    if not isinstance(data, dict):
        raise DualtwinError(f"{where}: expected an object with mean, var and count")
    try:
        mean = np.asarray(data["mean"], dtype=np.float64)
        var = np.asarray(data["var"], dtype=np.float64)
        count = float(data["count"])
    except (KeyError, TypeError, ValueError) as exc:
        raise DualtwinError(f"{where}: mean, var and count must be numbers ({exc})") from None
    if mean.shape != var.shape or (shape is not None and mean.shape != shape):
        raise DualtwinError(f"{where}: mean {list(mean.shape)} and var {list(var.shape)} must have shape "
                            f"{list(shape) if shape is not None else 'equal'}")
    if not (np.isfinite(mean).all() and np.isfinite(var).all() and (var >= 0).all() and count > 0):
        raise DualtwinError(f"{where}: needs finite means, finite non-negative variances and a positive count")
    rms = RunningMeanStd(shape=mean.shape)
    rms.mean, rms.var, rms.count = mean, var, count
    return rms


def load_normalization(path: Path, venv: VecEnv | None = None, *, trust_pickles: bool | None = None,
                       obs_shape: tuple[int, ...] | None = None) -> VecNormalize:
    """A ``VecNormalize`` from ``vecnormalize.json`` (wrapping ``venv`` if given, else for ``normalize_obs`` only).

    A legacy ``.pkl`` is unpickled only with ``trust_pickles`` (or inside :func:`trusting_pickles`).
    """
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecNormalize

    if path.suffix == ".pkl":
        if not resolve_trust(trust_pickles):
            raise DualtwinError(f"{path}: refusing to unpickle a normalisation file (pickles can run code); "
                                f"{TRUST_HINT}. New runs write vecnormalize.json instead")
        if venv is not None:
            return VecNormalize.load(str(path), venv)
        with open(path, "rb") as handle:
            loaded: VecNormalize = pickle.load(handle)  # noqa: S301 - the user said they trust this file
        return loaded
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DualtwinError(f"{path}: cannot read normalisation statistics: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != STATS_FORMAT:
        raise DualtwinError(f"{path}: not a normalisation file (\"format\" must be {STATS_FORMAT!r})")
    ret_rms = _read_rms(data.get("ret_rms"), f"{path}: ret_rms", ())
    settings: dict[str, Any] = {}
    for key, kind in (("norm_obs", bool), ("norm_reward", bool), ("clip_obs", float), ("clip_reward", float),
                      ("gamma", float), ("epsilon", float)):
        value = data.get(key)
        if kind is bool and not isinstance(value, bool):
            raise DualtwinError(f"{path}: {key} must be true or false")
        if kind is float and (isinstance(value, bool) or not isinstance(value, int | float)
                              or not math.isfinite(value) or value <= 0):
            raise DualtwinError(f"{path}: {key} must be a positive number")
        settings[key] = value
    obs_rms = _read_rms(data.get("obs_rms"), f"{path}: obs_rms", obs_shape) if settings["norm_obs"] else None
    if venv is not None:
        stats = VecNormalize(venv, training=True, norm_obs=settings["norm_obs"], norm_reward=settings["norm_reward"],
                             clip_obs=settings["clip_obs"], clip_reward=settings["clip_reward"],
                             gamma=settings["gamma"], epsilon=settings["epsilon"])
        if obs_rms is not None:
            current: Any = stats.obs_rms
            if current.mean.shape != obs_rms.mean.shape:
                raise DualtwinError(f"{path}: statistics of shape {list(obs_rms.mean.shape)}, the env's "
                                    f"observations have shape {list(current.mean.shape)}")
            stats.obs_rms = obs_rms
        stats.ret_rms = ret_rms
        return stats
    # No env to wrap: the statistics only normalise observations (LoadedPolicy, export). This is the state
    # VecNormalize.load restores before set_venv(), built from plain numbers.
    shape = obs_rms.mean.shape if obs_rms is not None else (obs_shape or ())
    state = {"num_envs": 1, "observation_space": spaces.Box(-np.inf, np.inf, shape=shape, dtype=np.float32),
             "action_space": spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32), "reset_infos": [{}],
             "_seeds": [None], "_options": [{}], "render_mode": None, "metadata": {}, "norm_obs_keys": None,
             **({"obs_rms": obs_rms} if obs_rms is not None else {}), "ret_rms": ret_rms, "training": False, "old_reward": np.array([]),
             "class_attributes": {}, "returns": np.zeros(1), **settings}
    stats = VecNormalize.__new__(VecNormalize)
    stats.__setstate__(state)
    return stats


# --- SB3 model zips -----------------------------------------------------------------------------------------


def _zip_data(path: Path) -> dict[str, Any]:
    try:
        with zipfile.ZipFile(path) as archive:
            raw = archive.read("data")
        data = json.loads(raw)
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DualtwinError(f"{path}: not a Stable-Baselines3 model ({exc})") from None
    if not isinstance(data, dict):
        raise DualtwinError(f"{path}: not a Stable-Baselines3 model (its data entry is not an object)")
    return data


def serialized_entries(path: Path) -> list[str]:
    """The keys of a model zip's ``data`` whose values are cloudpickles (what ``PPO.load`` would unpickle)."""
    return sorted(k for k, v in _zip_data(path).items() if isinstance(v, dict) and ":serialized:" in v)


def _spaces(contract: dict[str, Any]) -> tuple[Any, Any]:
    from gymnasium import spaces

    try:
        obs_shape = tuple(int(n) for n in contract["observation"]["shape"])
        action = contract["action"]
        observation = spaces.Box(-np.inf, np.inf, shape=obs_shape, dtype=np.float32)
        if action["type"] == "discrete":
            return observation, spaces.Discrete(int(action["n"]))
        shape = tuple(int(n) for n in action["shape"])
        return observation, spaces.Box(np.asarray(action["low"], dtype=np.float32),
                                       np.asarray(action["high"], dtype=np.float32), shape=shape, dtype=np.float32)
    except (KeyError, TypeError, ValueError) as exc:
        raise DualtwinError(f"run.json: the I/O contract does not describe the spaces ({exc})") from None


def _check_summary(path: Path, key: str, entry: dict[str, Any], rebuilt: Any) -> None:
    """The readable fields SB3 writes beside a pickled space must agree with the space rebuilt from run.json."""
    shape = entry.get("_shape")
    if shape is not None and list(shape) != list(rebuilt.shape):
        raise DualtwinError(f"{path}: {key} has shape {shape}, the run's I/O contract {list(rebuilt.shape)}")
    if "n" in entry and str(entry["n"]) != str(getattr(rebuilt, "n", None)):
        raise DualtwinError(f"{path}: {key} has {entry['n']} actions, the run's I/O contract "
                            f"{getattr(rebuilt, 'n', None)}")


def safe_objects(path: Path, record: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Values for the cloudpickled entries of ``path`` rebuilt from the run record, and the entries left over."""
    from stable_baselines3.common.buffers import RolloutBuffer
    from stable_baselines3.common.policies import ActorCriticPolicy

    from dualtwin.rl.ppo_config import PPOConfig, activation, learning_rate_schedule

    data = _zip_data(path)
    pickled = {k: v for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v}
    config_data, contract = record.get("config"), record.get("io")
    if not isinstance(config_data, dict) or not isinstance(contract, dict):
        return {}, sorted(pickled)
    try:
        config = PPOConfig.model_validate(config_data)
    except ValueError:
        return {}, sorted(pickled)
    observation, action = _spaces(contract)
    pk = config.policy_kwargs
    policy_kwargs: dict[str, Any] = {"net_arch": dict(pk.net_arch), "activation_fn": activation(pk.activation_fn),
                                     "ortho_init": pk.ortho_init}
    if contract["action"].get("type") == "box":
        policy_kwargs["log_std_init"] = pk.log_std_init
    rate = learning_rate_schedule(config.learning_rate)
    known: dict[str, Any] = {
        "policy_class": ActorCriticPolicy, "policy_kwargs": policy_kwargs, "observation_space": observation,
        "action_space": action, "rollout_buffer_class": RolloutBuffer, "learning_rate": rate,
        "lr_schedule": rate if callable(rate) else (lambda _progress: rate),
        "clip_range": config.clip_range, **dict.fromkeys(_TRANSIENT)}
    for key in ("observation_space", "action_space"):
        if key in pickled:
            _check_summary(path, key, pickled[key], known[key])
    summary = pickled.get("policy_kwargs", {})
    if summary.get("net_arch") not in (None, policy_kwargs["net_arch"]):
        raise DualtwinError(f"{path}: network {summary.get('net_arch')} differs from the run's config "
                            f"{policy_kwargs['net_arch']}")
    return {k: known[k] for k in pickled if k in known}, sorted(k for k in pickled if k not in known)


def load_model(path: Path, record: dict[str, Any], *, env: Any = None, trust_pickles: bool | None = None,
               custom_objects: dict[str, Any] | None = None, **kwargs: Any) -> PPO:
    """``PPO.load`` with every cloudpickled entry replaced by a value rebuilt from ``record`` (the run.json).

    ``custom_objects`` (fine-tuning settings) take precedence. Entries nothing can rebuild make this refuse,
    naming them, unless ``trust_pickles``. The weights load with ``torch.load(weights_only=True)`` either way.
    """
    from stable_baselines3 import PPO

    objects, unknown = safe_objects(path, record)
    objects.update(custom_objects or {})
    unknown = [k for k in unknown if k not in objects]
    if unknown and not resolve_trust(trust_pickles):
        raise DualtwinError(f"{path}: refusing to unpickle {', '.join(unknown)} from the model's data (pickles can "
                            f"run code, and this run's run.json does not describe them); {TRUST_HINT}")
    try:
        return PPO.load(str(path), env=env, device="cpu", custom_objects=objects, **kwargs)
    except pickle.UnpicklingError as exc:
        # torch.load(weights_only=True) met something other than tensors in a .pth entry.
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DualtwinError(f"{path}: refusing a weights file that is not plain tensors ({first})") from None
    except (KeyError, RuntimeError, zipfile.BadZipFile, AssertionError, ValueError, TypeError) as exc:
        # the zip's data entry is plain JSON anyone can edit, and SB3 checks what it reads with assertions
        # (clip_range_vf 0, a clip_range that is an object...): a traceback, before
        raise DualtwinError(f"{path}: cannot load the model: {type(exc).__name__}: {exc}") from None


__all__ = ["STATS_FORMAT", "load_model", "load_normalization", "resolve_trust", "safe_objects", "save_normalization",
           "serialized_entries", "stats_path", "trusting_pickles"]
