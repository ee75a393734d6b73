"""Transfer: a MuJoCo policy evaluated in a perturbed MuJoCo env standing in for the other twin."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.rl.transfer import transfer

# The "other twin": same ids and spaces, heavier pole. Aligning it back to nominal must reproduce the source.
OTHER = {"knobs": {"body.pole.mass": 0.3}}


def test_transfer_report(discrete_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "transfer"
    report = transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", aligned={"body.pole.mass": 0.2}, episodes=2,
                      seed=3, out_dir=out, target_kwargs=OTHER, max_episode_steps=80)
    labels = [r.label for r in report.rows]
    assert labels == ["source", "target (before alignment)", "target (after alignment)"]
    source, before, after = report.rows
    assert len(source.rewards) == 2 and all(n <= 80 for n in source.lengths)
    if source.mean > 0:
        assert source.ratio == pytest.approx(1.0)
    # Same seeds and (after alignment) the same physics as the source: identical episodes.
    assert after.rewards == source.rewards and after.lengths == source.lengths
    assert before.trajectory is not None and len(before.trajectory.time_s) == before.lengths[0]
    for name in ("transfer.json", "report.md", "trajectory.png"):
        assert (out / name).is_file(), name
    data = json.loads((out / "transfer.json").read_text())
    assert data["rows"][1]["label"] == "target (before alignment)" and len(data["rows"][2]["rewards"]) == 2
    assert "± " in (out / "report.md").read_text()


def test_transfer_without_alignment(discrete_run: Path) -> None:
    report = transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, target_kwargs=OTHER,
                      max_episode_steps=30)
    assert [r.label for r in report.rows] == ["source", "target (before alignment)"]


def test_action_space_mismatch_is_named(discrete_run: Path) -> None:
    with pytest.raises(DualtwinError, match="action: policy .*discrete.* vs env .*box"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-Continuous-v0", episodes=1, max_episode_steps=10)


def test_observation_mismatch_is_named(discrete_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(discrete_run, run)
    record = json.loads((run / "run.json").read_text())
    terms = record["io"]["observation"]["terms"]
    terms[0], terms[2] = terms[2], terms[0]  # a policy that reads the pole angle first
    (run / "run.json").write_text(json.dumps(record))
    with pytest.raises(DualtwinError, match="observation names"):
        transfer(run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, max_episode_steps=10)


def test_unknown_target_and_bad_knobs(discrete_run: Path) -> None:
    with pytest.raises(DualtwinError, match="registered dualtwin ids"):
        transfer(discrete_run, "dualtwin/CartPole-Gazebo-v0", episodes=1)
    with pytest.raises(DualtwinError, match="no knobs named"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", aligned={"body.nope.mass": 1.0}, episodes=1,
                 max_episode_steps=10)


def test_observation_source_mismatch_is_named(discrete_run: Path) -> None:
    # Same names and units, but the cart velocity would come from the supervisor instead of odometry.
    with pytest.raises(DualtwinError, match="observation sources"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, max_episode_steps=10,
                 target_kwargs={"task_kwargs": {"cart_velocity": "ground_truth"}})
