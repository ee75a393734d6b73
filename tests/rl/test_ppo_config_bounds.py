"""A PPO config is untrusted input: every number that sizes memory or work, or that PyTorch turns into float32,
is bounded where the config is read, so a hostile or mistyped one is one line and exit 2 before any run folder.

Found by fuzzing ``dualtwin train --config``: n_steps 1e12 tried to allocate 14.6 TiB, n_envs 1e6 built
environments until memory ran out, net_arch [1e9] allocated 16 GB, n_epochs 1e9 never ended, learning_rate -1
and clip_range 1e308 were tracebacks after training had started, each leaving a run folder behind.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from tests.support.rl_runs import TINY

from dualtwin.errors import DualtwinError
from dualtwin.rl.ppo_config import load_config

HOSTILE = [
    ({"n_steps": 10**12}, "n_steps"),
    ({"n_steps": 2**21, "n_envs": 4, "batch_size": 64}, "n_steps x n_envs"),
    ({"n_envs": 10**6}, "n_envs"),
    ({"n_epochs": 10**9}, "n_epochs"),
    ({"eval_episodes": 10**9}, "eval_episodes"),
    ({"learning_rate": -1}, "learning_rate"),
    ({"learning_rate": 0}, "learning_rate"),
    ({"learning_rate": "lin_-1"}, "learning_rate"),
    ({"learning_rate": "lin_1e999"}, "learning_rate"),
    ({"clip_range": 1e308}, "clip_range"),
    ({"ent_coef": 1e308}, "ent_coef"),
    ({"vf_coef": -1e308}, "vf_coef"),
    ({"max_grad_norm": -1}, "max_grad_norm"),
    ({"sde_sample_freq": -5}, "sde_sample_freq"),
    ({"torch_threads": 10**6}, "torch_threads"),
    ({"policy_kwargs": {"net_arch": {"pi": [10**9], "vf": [64]}}}, "net_arch"),
    ({"policy_kwargs": {"net_arch": {"pi": [-5], "vf": [64]}}}, "net_arch"),
    ({"policy_kwargs": {"net_arch": {"pi": [0], "vf": [64]}}}, "net_arch"),
    ({"policy_kwargs": {"net_arch": {"pi": [64] * 10_000, "vf": [64]}}}, "net_arch"),
    ({"policy_kwargs": {"net_arch": {"pi": [8192, 8192, 8192], "vf": [64]}}}, "hidden weights"),
    ({"policy_kwargs": {"log_std_init": 800}}, "log_std_init"),
]


@pytest.mark.parametrize(("change", "named"), HOSTILE, ids=[str(c)[:40] for c, _ in HOSTILE])
def test_hostile_numbers_are_refused_where_the_config_is_read(tmp_path: Path, change: dict[str, object],
                                                              named: str) -> None:
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump({**TINY, **change}))
    with pytest.raises(DualtwinError, match="invalid PPO config") as info:
        load_config(path)
    assert named in str(info.value) and str(path) in str(info.value)


ENV_KWARGS = [
    ({"bogus": 1}, "env_kwargs.bogus"),  # TypeError from TwinEnv.__init__, a traceback
    ({"max_episode_steps": 0}, "env_kwargs.max_episode_steps"),  # gymnasium's ValueError
    ({"max_episode_steps": -1}, "env_kwargs.max_episode_steps"),  # accepted: episodes never truncated
    ({"render_mode": "human"}, "env_kwargs.render_mode"),  # gymnasium asked for pygame
    ({"knobs": "../../etc/passwd"}, "env_kwargs.knobs"),  # ValueError: dictionary update sequence
    ({"task_kwargs": "x"}, "env_kwargs.task_kwargs"),  # "argument after ** must be a mapping", after the folder
    ({"task_kwargs": {"balance_angle": float("nan")}}, "must be finite"),  # JSON error writing run.json
    ({"control_period": "0.032"}, "env_kwargs.control_period"),
]


@pytest.mark.parametrize(("env_kwargs", "named"), ENV_KWARGS, ids=[str(c)[:40] for c, _ in ENV_KWARGS])
def test_env_kwargs_are_checked_where_the_config_is_read(tmp_path: Path, env_kwargs: dict[str, object],
                                                         named: str) -> None:
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump({**TINY, "env_kwargs": env_kwargs}))
    with pytest.raises(DualtwinError, match="invalid PPO config") as info:
        load_config(path)
    assert named in str(info.value) and "\n" not in str(info.value)


def test_env_options_are_gym_makes_and_twin_envs() -> None:
    import inspect

    from dualtwin.rl.env import TwinEnv
    from dualtwin.rl.ppo_config import EnvOptions

    declared = {name for name in inspect.signature(TwinEnv.__init__).parameters if name != "self"}
    assert set(EnvOptions.model_fields) == declared | {"max_episode_steps", "disable_env_checker"}


def test_bundled_configs_are_within_the_bounds() -> None:
    from dualtwin.rl.ppo_config import bundled_configs

    for name in bundled_configs():
        load_config(name)


def _train_refused(tmp_path: Path, config: dict[str, object]) -> tuple[Path, list[str], Path]:
    """``dualtwin train`` with ``config`` written to a file: (the file, the non-empty stderr lines, the run folder);
    the command must exit 2."""
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config))
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "train", "--env", "dualtwin/CartPole-MuJoCo-v0",
                           "--out", str(out), "--config", str(path), "--steps", "32"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    return path, [line for line in done.stderr.splitlines() if line.strip()], out


def test_cli_refuses_before_the_run_folder(tmp_path: Path) -> None:
    # learning_rate -1 used to pass validation and fail in SB3's Adam once training had started: exit 1, a
    # traceback, and a run folder left behind
    path, lines, out = _train_refused(tmp_path, {**TINY, "learning_rate": -1})
    assert len(lines) == 1 and "learning_rate" in lines[0] and str(path) in lines[0], lines
    assert not out.exists()


def test_cli_refuses_an_unknown_env_option_before_the_run_folder(tmp_path: Path) -> None:
    # was "TypeError: TwinEnv.__init__() got an unexpected keyword argument" once the envs were built: exit 1
    _, lines, out = _train_refused(tmp_path, {**TINY, "env_kwargs": {"model_path": "/etc/passwd"}})
    assert len(lines) == 1 and "env_kwargs.model_path" in lines[0], lines
    assert not out.exists()
