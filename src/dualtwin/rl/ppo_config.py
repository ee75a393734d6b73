"""The PPO training config: hyperparameters, evaluation and checkpoint cadence, and how it is read.

It is its own module because both sides of a run folder need it: :mod:`dualtwin.rl.train` writes runs with
it, and :mod:`dualtwin.rl.runfiles` rebuilds a saved model's pickled entries (schedules, policy class) from
the ``config`` in ``run.json`` without unpickling anything.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, ValidationError, field_validator, model_validator

from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel, json_path

CONFIGS = Path(__file__).parent / "configs"
DEFAULT_CONFIG = CONFIGS / "ppo_cartpole.yaml"


class NormalizeConfig(FrozenModel):
    """VecNormalize settings (its statistics are saved with the model)."""

    norm_obs: bool = True
    norm_reward: bool = True
    clip_obs: float = Field(default=10.0, gt=0)
    clip_reward: float = Field(default=10.0, gt=0)


# Bounds on what a config may ask for. A config is a file from anywhere: every number that sizes memory or work
# (the rollout buffer, the network, the envs, the epochs) is bounded so that a typo or a hostile file is refused
# here, in one line, instead of allocating terabytes, building a million environments or never ending; every
# float that PyTorch turns into float32 is bounded so it cannot overflow (1e308 became 'value cannot be converted
# to type float without overflow' mid-training). The bounds are far above any published PPO setting (zoo's
# largest rollouts are ~2^17 steps, its widest nets 1024 units).
MAX_ENVS = 1024
MAX_ROLLOUT = 2**22  # n_steps x n_envs: the rollout buffer holds this many observations
MAX_LAYER_UNITS = 8192
MAX_LAYERS = 32
MAX_NET_WEIGHTS = 2**26  # per network, counting only hidden-to-hidden weights (the obs size is not known here)
MAX_EPOCHS = 1000
MAX_EVAL_EPISODES = 10_000
MAX_TIMESTEPS = 10**12
MAX_COEF = 1e6


def _paper_net_arch() -> dict[Literal["pi", "vf"], list[int]]:
    return {"pi": [64, 64], "vf": [64, 64]}


Units = Annotated[int, Field(ge=1, le=MAX_LAYER_UNITS)]


class PolicyKwargs(FrozenModel):
    net_arch: dict[Literal["pi", "vf"], Annotated[list[Units], Field(max_length=MAX_LAYERS)]] = Field(
        default_factory=_paper_net_arch)
    activation_fn: Literal["relu", "tanh", "elu", "leaky_relu"] = "relu"
    ortho_init: bool = True
    # the policy's std is exp(log_std): beyond +-20 it is 0 or huge in float32 (NaN actions)
    log_std_init: float = Field(default=0.0, ge=-20, le=20)

    @model_validator(mode="after")
    def _bounded_network(self) -> PolicyKwargs:
        for name, layers in self.net_arch.items():
            weights = sum(a * b for a, b in zip(layers, layers[1:], strict=False))
            if weights > MAX_NET_WEIGHTS:
                raise ValueError(f"net_arch.{name} {layers} has {weights} hidden weights, more than {MAX_NET_WEIGHTS}")
        return self


Positive = Annotated[int, Field(ge=1, le=8192)]


class EnvOptions(FrozenModel):
    """What ``env_kwargs`` may hold: ``gym.make``'s own options and ``TwinEnv``'s keyword arguments (every
    dualtwin id's entry point; tests/rl/test_ppo_config_bounds.py keeps the two lists in step).

    Checked where the config is read because these go to ``gym.make`` only once the envs are built: an unknown
    key was a TypeError traceback, ``max_episode_steps: 0`` a ValueError, ``render_mode: human`` a missing-pygame
    error and a NaN in ``task_kwargs`` a JSON error writing the run record, each after the run folder was made.
    Strict: a number written as text is a mistake in a config, not something to coerce. The task's own options
    (``task_kwargs``) are checked by the task when the env is built.
    """

    model_config = ConfigDict(strict=True)

    max_episode_steps: int = Field(default=1000, ge=1, le=10**9)
    disable_env_checker: bool = False
    twin: str = "mujoco"
    robot: str = "cartpole"
    task: str = "cartpole_balance"
    continuous: bool = False
    control_period: float = Field(default=0.032, gt=0, le=60)
    knobs: dict[str, float] = Field(default_factory=dict)
    render_mode: Literal["rgb_array"] | None = None
    camera: str = "side"
    render_size: list[Positive] = Field(default_factory=lambda: [480, 640], min_length=2, max_length=2)
    task_kwargs: dict[str, Any] = Field(default_factory=dict)

    @field_validator("task_kwargs")
    @classmethod
    def _finite(cls, value: dict[str, Any]) -> dict[str, Any]:
        def check(where: str, item: Any) -> None:
            if isinstance(item, float) and not math.isfinite(item):
                raise ValueError(f"{where} must be finite, got {item!r}")
            children = item.items() if isinstance(item, dict) else enumerate(item) if isinstance(item, list) else ()
            for key, child in children:
                check(f"{where}.{key}", child)

        check("task_kwargs", value)
        return value


def check_env_kwargs(value: Any, where: str) -> dict[str, Any]:
    """``env_kwargs`` read back from a file (a run's ``run.json``, an export's ``policy_contract.json``), checked
    as a config's are (:class:`EnvOptions`).

    Those files are untrusted data: ``env_kwargs: "abc"`` was a TypeError in ``dict()``, ``control_period: "x"``
    a ValueError in ``float()`` and ``task: []`` an unhashable-type error, each a traceback (found by fuzzing
    ``dualtwin lockstep --policy`` and ``dualtwin transfer``).
    """
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise DualtwinError(f"{where}: $.env_kwargs must be a JSON object, got {type(value).__name__}")
    try:
        EnvOptions.model_validate(value)
    except ValidationError as exc:
        first = exc.errors()[0]
        more = f" ({exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
        raise DualtwinError(f"{where}: $.env_kwargs{json_path(first['loc'])[1:]}: "
                            f"{first['msg'].removeprefix('Value error, ')}{more}") from None
    return dict(value)


class PPOConfig(FrozenModel):
    """PPO hyperparameters plus the run's evaluation and checkpoint cadence. Step counts are env steps."""

    algo: Literal["ppo"] = "ppo"
    policy: Literal["MlpPolicy"] = "MlpPolicy"
    n_timesteps: int = Field(default=400_000, gt=0, le=MAX_TIMESTEPS)
    n_envs: int = Field(default=8, ge=1, le=MAX_ENVS)
    n_steps: int = Field(default=512, ge=2, le=MAX_ROLLOUT)
    batch_size: int = Field(default=512, ge=2, le=MAX_ROLLOUT)
    n_epochs: int = Field(default=10, ge=1, le=MAX_EPOCHS)
    learning_rate: float | str = Field(default=3e-4, description="a number in (0, 1], or zoo's 'lin_<number>' "
                                       "(linear decay from that number)")
    gamma: float = Field(default=0.99, gt=0, le=1)
    gae_lambda: float = Field(default=0.95, gt=0, le=1)
    clip_range: float = Field(default=0.2, gt=0, le=MAX_COEF)
    ent_coef: float = Field(default=0.0, ge=-MAX_COEF, le=MAX_COEF)
    vf_coef: float = Field(default=0.5, ge=0, le=MAX_COEF)
    # SB3 scales gradients by max_grad_norm / norm: zero or less would stop or reverse learning
    max_grad_norm: float = Field(default=0.5, gt=0, le=MAX_COEF)
    use_sde: bool = Field(default=False, description="generalised state-dependent exploration (Box actions only)")
    sde_sample_freq: int = Field(default=-1, ge=-1, description="-1: the noise is drawn once per rollout")
    normalize: NormalizeConfig | bool = Field(default_factory=NormalizeConfig)
    policy_kwargs: PolicyKwargs = Field(default_factory=PolicyKwargs)
    env_kwargs: dict[str, Any] = Field(default_factory=dict, description="extra gym.make arguments")
    eval_freq: int = Field(default=20_480, ge=0, description="0 disables evaluation")
    eval_episodes: int = Field(default=5, ge=1, le=MAX_EVAL_EPISODES)
    checkpoint_freq: int = Field(default=40_960, ge=0, description="0 disables checkpoints (and resume)")
    stop_reward: float | None = None
    stop_episode_length: float | None = Field(
        default=None, gt=0, description="stop once the mean length of the last 100 training episodes reaches this "
        "(the rolling mean the paper's Figure 10 plots)")
    max_wall_seconds: float | None = Field(default=None, gt=0, description="stop after this much training time")
    vec_env: Literal["dummy", "subproc"] = "dummy"
    torch_threads: int = Field(default=1, ge=1, le=1024)

    @field_validator("env_kwargs")
    @classmethod
    def _env_options(cls, value: dict[str, Any]) -> dict[str, Any]:
        EnvOptions.model_validate(value)
        return value  # as written: it is recorded in run.json and passed on to gym.make unchanged

    @model_validator(mode="after")
    def _consistent(self) -> PPOConfig:
        rollout = self.n_steps * self.n_envs
        if rollout > MAX_ROLLOUT:
            raise ValueError(f"n_steps x n_envs ({rollout}) is more than {MAX_ROLLOUT} steps per rollout")
        if rollout % self.batch_size:
            raise ValueError(f"n_steps x n_envs ({rollout}) must be a multiple of batch_size ({self.batch_size})")
        start = self.learning_rate
        if isinstance(start, str):
            learning_rate_schedule(start)
            start = float(start.strip()[len("lin_"):])
        # SB3's Adam refuses a negative rate only once training starts (a traceback after the run folder was
        # made); lin_1e999 parses to inf
        if not 0 < start <= 1:
            raise ValueError(f"learning_rate {self.learning_rate!r}: the (initial) rate must be in (0, 1]")
        return self

    @property
    def normalize_config(self) -> NormalizeConfig | None:
        if isinstance(self.normalize, bool):
            return NormalizeConfig() if self.normalize else None
        return self.normalize


def learning_rate_schedule(value: float | str) -> float | Callable[[float], float]:
    if isinstance(value, int | float):
        return float(value)
    match = re.fullmatch(r"lin_([0-9.eE+-]+)", value.strip())
    if not match:
        raise ValueError(f"learning_rate {value!r}: use a number or 'lin_<number>'")
    start = float(match.group(1))
    return lambda progress_remaining: progress_remaining * start


def load_config(source: Path | str | Mapping[str, Any] | PPOConfig | None = None) -> PPOConfig:
    """Read a PPO config YAML (the bundled :data:`DEFAULT_CONFIG` if ``None``)."""
    if isinstance(source, PPOConfig):
        return source
    origin = "<config dict>"
    if source is None or not isinstance(source, Mapping):
        path = Path(source) if source is not None else DEFAULT_CONFIG
        text = str(source)
        if source is not None and not ("/" in text or "\\" in text or path.suffix or text in ("", ".", "..")):
            # A bare word is always a bundled config's name (``--config ppo_cartpole``), even when a file of that
            # name exists in the working folder, as ``--robot cartpole`` and ``--scenarios cartpole`` are; write
            # ``./name`` to mean such a file.
            path = CONFIGS / f"{text}.yaml"
            if not path.is_file():
                raise DualtwinError(f"--config {text}: not a bundled config ({', '.join(bundled_configs())}); "
                                    f"to use a file of that name, write ./{text}")
        if not path.is_file():
            raise DualtwinError(f"{path}: config file not found")
        origin = str(path)
        from dualtwin.artifacts import read_yaml

        data = read_yaml(path, "PPO config")
    else:
        data = dict(source)
    try:
        return PPOConfig.model_validate(data or {})
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'config'}: {e['msg']}" for e in exc.errors())
        raise DualtwinError(f"{origin}: invalid PPO config: {problems}") from None


def bundled_configs() -> list[str]:
    """Names of the bundled PPO configs (``--config NAME``)."""
    return sorted(p.stem for p in CONFIGS.glob("*.yaml"))


def activation(name: str) -> type[Any]:
    import torch.nn as nn

    return {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}[name]
