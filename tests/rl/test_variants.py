"""The paper's task variants as bundled configs, episodes that end when the pole falls, and learning curves."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from tests.support.rl_runs import TINY

from dualtwin.errors import DualtwinError
from dualtwin.rl.curves import read_learning_curve
from dualtwin.rl.ppo_config import bundled_configs, load_config
from dualtwin.rl.train import train

PAPER_VARIANTS = ("ppo_cartpole_text", "ppo_cartpole_code", "ppo_cartpole_continuous")


def test_bundled_configs_are_found_by_name_from_any_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert set(PAPER_VARIANTS) | {"ppo_cartpole"} <= set(bundled_configs())
    for name in bundled_configs():
        assert load_config(name) == load_config(Path(__file__).parents[2] / "src/dualtwin/rl/configs" / f"{name}.yaml")
    # A bare word is a bundled name even beside a file of that name (as --robot and --scenarios); ./ means the file.
    (tmp_path / "ppo_cartpole").write_text("n_envs: 2\nn_steps: 64\nbatch_size: 64\n")
    assert load_config("ppo_cartpole").n_envs == load_config(None).n_envs != 2
    assert load_config("./ppo_cartpole").n_envs == 2
    with pytest.raises(DualtwinError, match="not a bundled config.*ppo_cartpole_text.*write ./ppo_cartpol$"):
        load_config("ppo_cartpol")


def test_cli_names_an_unknown_config_in_one_line(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "dualtwin.cli", "train", "--env", "dualtwin/CartPole-MuJoCo-v0",
                             "--config", "nope", "--out", str(tmp_path / "run")], capture_output=True, text=True,
                            timeout=120, cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "--config nope" in result.stderr
    assert not (tmp_path / "run").exists()


def _variant_env(name: str, env_id: str) -> gym.Env:  # type: ignore[type-arg]
    return gym.make(env_id, **load_config(name).env_kwargs)


@pytest.mark.parametrize(("name", "env_id", "cap", "speeds"), [
    ("ppo_cartpole_text", "dualtwin/CartPole-MuJoCo-v0", 2000, [-1.5, 1.5]),
    ("ppo_cartpole_code", "dualtwin/CartPole-MuJoCo-v0", 1000, [-0.2, 0.2]),  # 5 rad/s x 0.04 m
    ("ppo_cartpole_continuous", "dualtwin/CartPole-MuJoCo-Continuous-v0", 2000, None),
])
def test_paper_variants_end_when_the_pole_falls(name: str, env_id: str, cap: int, speeds: list[float] | None) -> None:
    env = _variant_env(name, env_id)
    assert env.spec is not None and env.spec.max_episode_steps == cap
    contract = env.unwrapped.io_contract()  # type: ignore[attr-defined]
    if speeds is not None:
        assert contract["action"]["speed_table"] == pytest.approx(speeds)
    else:
        assert contract["action"]["scale"] == 1.5 and contract["action"]["low"] == [-1.0]
    assert contract["task"]["terminate_on_fall"] and contract["task"]["balance_angle_rad"] == 0.3
    env.reset(seed=0)
    push = 1 if speeds is not None else np.array([1.0], dtype=np.float32)
    steps = 0
    for _ in range(cap):  # pushing one way only: the pole falls backwards
        steps += 1
        obs, reward, terminated, truncated, info = env.step(push)
        if name == "ppo_cartpole_code":
            assert np.all(np.abs(obs) <= 1.0)  # fixed ranges, clipped
        if terminated:
            break
    assert terminated and not truncated and steps < 300
    assert abs(info["true_pole_angle"]) > 0.3 and abs(info["true_cart_position"]) < 2.4
    env.close()


def test_the_code_variant_scales_observations_by_fixed_ranges() -> None:
    plain = gym.make("dualtwin/CartPole-MuJoCo-v0", task_kwargs={"max_wheel_speed": 5.0})
    scaled = _variant_env("ppo_cartpole_code", "dualtwin/CartPole-MuJoCo-v0")
    a, _ = plain.reset(seed=3)
    b, _ = scaled.reset(seed=3)
    for _ in range(5):
        a, *_ = plain.step(1)
        b, *_ = scaled.step(1)
    np.testing.assert_allclose(b, np.clip(a / np.array([0.4, 0.2, 0.23, 1.5]), -1, 1), rtol=1e-5, atol=1e-6)
    terms = scaled.unwrapped.io_contract()["observation"]["terms"]  # type: ignore[attr-defined]
    assert terms[2]["unit"] == "rad / 0.23"
    plain.close()
    scaled.close()


def test_train_writes_the_learning_curve_and_reports_each_evaluation(tmp_path: Path) -> None:
    lines: list[str] = []
    out = train("dualtwin/CartPole-MuJoCo-v0", {**TINY, "eval_freq": 512,
                                                "env_kwargs": {"max_episode_steps": 60,
                                                               "task_kwargs": {"terminate_on_fall": True}}},
                tmp_path / "run", seed=0, total_timesteps=1024, progress_bar=False, report=lines.append)
    import json

    record = json.loads((out / "run.json").read_text())
    # Set-up lines (loading, building the environments) come first; then one line per evaluation.
    evaluations = [line for line in lines if line.startswith("eval at ")]
    assert len(evaluations) == len(record["evaluations"]) >= 2
    assert lines[-len(evaluations):] == evaluations
    assert evaluations[0].startswith("eval at 512/1,024 steps: mean reward")
    with open(out / "learning_curve.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert rows and list(rows[0]) == ["episode", "env_steps", "episode_length_steps", "episode_reward",
                                      "rolling_mean_length_steps"]
    lengths = [float(r["episode_length_steps"]) for r in rows]
    assert [int(r["env_steps"]) for r in rows] == list(np.cumsum(lengths).astype(int))
    assert max(lengths) <= 60 and sum(lengths) <= 1024
    assert (out / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    curve = read_learning_curve(out)
    assert curve.control_period_s == pytest.approx(0.032)
    assert curve.steps_to(1e9) is None and curve.steps_to(0) == curve.env_steps[0]


def test_training_stops_when_the_rolling_episode_length_reaches_its_goal(tmp_path: Path) -> None:
    out = train("dualtwin/CartPole-MuJoCo-v0", {**TINY, "eval_freq": 0, "checkpoint_freq": 0, "stop_episode_length": 1,
                                                "env_kwargs": {"max_episode_steps": 10}},
                tmp_path / "run", seed=0, total_timesteps=20_000, progress_bar=False)
    import json

    steps = json.loads((out / "run.json").read_text())["num_timesteps"]
    # Every episode lasts >= 1 step, so the goal holds once 100 episodes (about 1,000 steps) have finished.
    assert 1000 <= steps < 2000
    assert read_learning_curve(out).steps_to(1) is not None
