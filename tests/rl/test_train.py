"""Training: the run folder, restoring a policy, resume after an interruption, and bad inputs."""

from __future__ import annotations

import hashlib
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from tests.support.rl_runs import TINY

from dualtwin.errors import DualtwinError
from dualtwin.rl.policy import load_policy
from dualtwin.rl.ppo_config import DEFAULT_CONFIG, load_config
from dualtwin.rl.train import train


def test_bundled_config_is_the_papers() -> None:
    config = load_config(None)
    assert config == load_config(DEFAULT_CONFIG)
    assert config.learning_rate == pytest.approx(3e-4) and config.gamma == pytest.approx(0.99)
    assert config.n_steps * config.n_envs == 4096
    assert config.policy_kwargs.net_arch == {"pi": [64, 64], "vf": [64, 64]}
    assert config.policy_kwargs.activation_fn == "relu"
    assert config.normalize_config is not None and config.normalize_config.norm_obs


def test_run_folder(discrete_run: Path) -> None:
    for name in ("model.zip", "vecnormalize.json", "config.yaml", "run.json", "evaluations.npz", "best_model.zip",
                 "best_vecnormalize.json"):
        assert (discrete_run / name).is_file(), name
    assert list((discrete_run / "checkpoints").glob("rl_model_*_steps.zip"))
    assert list((discrete_run / "checkpoints").glob("rl_model_vecnormalize_*_steps.json"))
    assert list((discrete_run / "tb").rglob("events.out.tfevents.*"))
    assert list((discrete_run / "monitor").glob("*.monitor.csv"))
    record = json.loads((discrete_run / "run.json").read_text())
    assert record["status"] == "complete" and record["seed"] == 0
    assert record["env_id"] == "dualtwin/CartPole-MuJoCo-v0" and record["num_timesteps"] >= 2048
    assert "stable-baselines3" in record["versions"] and "torch" in record["versions"]
    assert record["timings"]["train_seconds"] > 0 and record["evaluations"]
    assert record["io"]["observation"]["terms"][2]["name"] == "pole_angle"
    resolved = yaml.safe_load((discrete_run / "config.yaml").read_text())
    assert resolved["n_timesteps"] == 2048 and resolved["n_envs"] == TINY["n_envs"]
    with np.load(discrete_run / "evaluations.npz") as data:
        assert len(data["timesteps"]) == len(record["evaluations"])


def test_load_policy_in_one_line(discrete_run: Path) -> None:
    policy = load_policy(discrete_run)
    env = policy.make_env()
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(int(policy.predict(obs)))
    assert policy.predict(np.stack([obs, obs])).shape == (2,)
    assert load_policy(discrete_run, "best").vec_normalize is not None


def test_resume_after_interruption(tmp_path: Path) -> None:
    # A real Ctrl-C: training runs in its own process and gets SIGINT once its first checkpoint is on disk.
    out = tmp_path / "run"
    ranges = {"knobs": {"body.pole.mass": {"low": 0.18, "high": 0.22}}}
    script = (f"from dualtwin.rl.train import train\n"
              f"train('dualtwin/CartPole-MuJoCo-v0', {TINY!r}, {str(out)!r}, seed=1, total_timesteps=10**7, "
              f"dr_ranges={ranges!r}, progress_bar=False)\n")
    process = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        for _ in range(1200):
            if list((out / "checkpoints").glob("rl_model_*_steps.zip")) or process.poll() is not None:
                break
            time.sleep(0.05)
        assert process.poll() is None, "training ended before its first checkpoint"
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode != 0 and b"KeyboardInterrupt" in stderr
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and not (out / "model.zip").exists()
    assert (out / "dr_ranges.json").is_file()
    interrupted_at = record["num_timesteps"]
    # What was learned up to the signal is kept, not only the last periodic checkpoint.
    assert (out / "checkpoints" / f"rl_model_{interrupted_at}_steps.zip").is_file() and interrupted_at >= 1024

    with pytest.raises(DualtwinError, match="not empty"):
        train("dualtwin/CartPole-MuJoCo-v0", TINY, out, seed=1, total_timesteps=2048, progress_bar=False)
    with pytest.raises(DualtwinError, match="seed"):
        train("dualtwin/CartPole-MuJoCo-v0", TINY, out, seed=2, total_timesteps=2048, resume=True,
              dr_ranges=ranges, progress_bar=False)

    total = interrupted_at + 1024
    train("dualtwin/CartPole-MuJoCo-v0", TINY, out, seed=1, total_timesteps=total, resume=True,
          dr_ranges=ranges, progress_bar=False)
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "complete" and record["num_timesteps"] >= total
    assert record["resumed_from_steps"] == interrupted_at
    assert (out / "model.zip").is_file() and (out / "vecnormalize.json").is_file()
    # The evaluation history before the interruption is kept.
    assert record["evaluations"][0]["timesteps"] == 1024


def test_bad_inputs(tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="registered dualtwin ids: .*CartPole-MuJoCo-v0"):
        train("dualtwin/NoSuchEnv-v0", TINY, tmp_path / "a", progress_bar=False)
    with pytest.raises(DualtwinError, match="batch_size"):
        train("dualtwin/CartPole-MuJoCo-v0", {**TINY, "batch_size": 100}, tmp_path / "b", progress_bar=False)
    bad = tmp_path / "bad.yaml"
    bad.write_text("n_envs: [1\n")
    with pytest.raises(DualtwinError, match="invalid YAML"):
        load_config(bad)
    with pytest.raises(DualtwinError, match="unknown_key"):
        load_config({"unknown_key": 1})
    with pytest.raises(DualtwinError, match="not found"):
        load_config(tmp_path / "missing.yaml")
    with pytest.raises(DualtwinError, match="no run.json"):
        load_policy(tmp_path)


def test_stop_reward_ends_training_and_is_recorded(tmp_path: Path) -> None:
    said: list[str] = []
    out = train("dualtwin/CartPole-MuJoCo-v0", {**TINY, "stop_reward": 0.0}, tmp_path / "run", total_timesteps=8192,
                progress_bar=False, report=said.append)
    # the set-up is not silent: what it loads and builds is said before the first evaluation line
    assert said[0] == "loading PyTorch and Stable-Baselines3"
    assert said[1].startswith("building ") and "dualtwin/CartPole-MuJoCo-v0" in said[1]
    assert said[2].startswith("training: steps 0 to 8192")
    record = json.loads((out / "run.json").read_text())
    # The first evaluation (after 1024 steps) crosses the threshold; it ends training and is in the timeline.
    assert record["status"] == "complete" and record["num_timesteps"] == 1024
    assert record["timings"]["threshold_reached"]["timesteps"] == 1024
    assert [e["timesteps"] for e in record["evaluations"]] == [1024]


def test_train_in_aligned_twin(aligned_run: Path) -> None:
    knobs_file = aligned_run.parent / "knobs.json"
    record = json.loads((aligned_run / "run.json").read_text())
    assert record["aligned"]["values"] == {"body.pole.mass": 0.3} and record["aligned"]["twin"] == "mujoco"
    assert record["aligned"]["file"] == str(knobs_file.resolve())
    assert record["aligned"]["sha256"] == hashlib.sha256(knobs_file.read_bytes()).hexdigest()
    assert json.loads((aligned_run / "aligned_knobs.json").read_text()) == record["aligned"]
    # The source env rebuilt from the run is the aligned twin, at every reset.
    env = load_policy(aligned_run).make_env()
    for seed in (0, 1):
        env.reset(seed=seed)
        twin = env.unwrapped.twin
        pole = mujoco.mj_name2id(twin.model, mujoco.mjtObj.mjOBJ_BODY, "pole")
        assert twin.model.body_mass[pole] == pytest.approx(0.3)


def test_train_aligned_rejects_foreign_knobs(tmp_path: Path) -> None:
    env_id = "dualtwin/CartPole-MuJoCo-v0"
    webots = tmp_path / "webots_knobs.json"
    webots.write_text(json.dumps({"twin": "webots", "knobs": {"body.pole.mass": {"fitted": 0.3}}}))
    with pytest.raises(DualtwinError, match="fitted for the webots twin, but .*CartPole-MuJoCo-v0 runs the mujoco"):
        train(env_id, TINY, tmp_path / "a", total_timesteps=512, aligned=webots, progress_bar=False)
    with pytest.raises(DualtwinError, match="has no knobs named body.nope.mass"):
        train(env_id, TINY, tmp_path / "b", total_timesteps=512, aligned={"body.nope.mass": 1.0},
              progress_bar=False)
    with pytest.raises(DualtwinError, match="outside the knob's bounds"):
        train(env_id, TINY, tmp_path / "c", total_timesteps=512, aligned={"body.pole.mass": -1.0},
              progress_bar=False)
    # Nothing was trained or written.
    assert not any((tmp_path / name).exists() for name in "abc")


def test_fine_tune_from_a_run(discrete_run: Path, tmp_path: Path) -> None:
    out = train("dualtwin/CartPole-MuJoCo-v0", {**TINY, "learning_rate": 1e-5}, tmp_path / "tuned",
                total_timesteps=512, init_from=discrete_run, aligned={"body.pole.mass": 0.3}, progress_bar=False)
    record = json.loads((out / "run.json").read_text())
    start = discrete_run / "best_model.zip"
    assert record["init_from"]["model"] == str(start.resolve())
    assert record["init_from"]["sha256"] == hashlib.sha256(start.read_bytes()).hexdigest()
    assert record["num_timesteps"] == 512
    # The network comes from the initial run, the PPO settings from this config.
    tuned = load_policy(out).model
    assert tuned.learning_rate == pytest.approx(1e-5) and tuned.lr_schedule(1.0) == pytest.approx(1e-5)
    # The normalisation statistics carried on from the initial policy's rather than starting afresh
    # (512 steps plus the first reset of each env).
    before, after = load_policy(discrete_run, "best").vec_normalize, load_policy(out).vec_normalize
    assert before is not None and after is not None
    assert after.obs_rms.count == pytest.approx(before.obs_rms.count + 512 + int(TINY["n_envs"]))
    with pytest.raises(DualtwinError, match="can only be fine-tuned on that env"):
        train("dualtwin/CartPole-MuJoCo-Continuous-v0", TINY, tmp_path / "x", total_timesteps=512,
              init_from=discrete_run, progress_bar=False)
