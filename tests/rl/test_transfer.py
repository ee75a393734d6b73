"""Transfer: a MuJoCo policy evaluated in a perturbed MuJoCo env standing in for the other twin."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.rl.transfer import transfer

# The "other twin": same ids and spaces, heavier pole; the aligned run (conftest) trained with the same mass.
OTHER = {"knobs": {"body.pole.mass": 0.3}}


def test_transfer_report(discrete_run: Path, aligned_run: Path, dr_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "transfer"
    report = transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_aligned=aligned_run, policy_dr=dr_run,
                      episodes=2, seed=3, out_dir=out, target_kwargs=OTHER, max_episode_steps=80)
    labels = [r.label for r in report.rows]
    assert labels == ["source", "target (before alignment)", "source (aligned twin)", "target (after alignment)",
                      "source (trained with DR)", "target (with calibrated DR)"]
    source, before, aligned_source, after, dr_source, dr_target = report.rows
    assert len(source.rewards) == 2 and all(n <= 80 for n in source.lengths)
    if source.mean > 0:
        assert source.ratio == pytest.approx(1.0)
        assert after.ratio == pytest.approx(after.mean / source.mean)
    assert [r.policy_run for r in report.rows] == [str(discrete_run)] * 2 + [str(aligned_run)] * 2 + [str(dr_run)] * 2
    # The aligned policy's training env is the aligned twin (knobs from its run), here the same physics as the
    # target: same seeds, identical episodes. The DR policy's own env is the nominal one.
    assert aligned_source.knobs == {"body.pole.mass": 0.3} and dr_source.knobs is None and source.knobs is None
    assert after.rewards == aligned_source.rewards and after.lengths == aligned_source.lengths
    assert before.trajectory is not None and len(before.trajectory.time_s) == before.lengths[0]
    assert report.aligned is not None and report.aligned["values"] == {"body.pole.mass": 0.3}
    assert report.dr_ranges is not None and set(report.dr_ranges) == {"body.pole.mass"}
    for name in ("transfer.json", "report.md", "trajectory.png"):
        assert (out / name).is_file(), name
    data = json.loads((out / "transfer.json").read_text())
    assert [r["label"] for r in data["rows"]] == labels and len(data["rows"][3]["rewards"]) == 2
    assert data["aligned"]["sha256"] == report.aligned["sha256"] and len(data["aligned"]["sha256"]) == 64
    text = (out / "report.md").read_text()
    assert "± " in text and "`body.pole.mass` = 0.3" in text and "[0.15, 0.35]" in text
    assert dr_target.mean == pytest.approx(np.mean(dr_target.rewards))


def test_transfer_without_alignment(discrete_run: Path) -> None:
    report = transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, target_kwargs=OTHER,
                      max_episode_steps=30)
    assert [r.label for r in report.rows] == ["source", "target (before alignment)"]


def test_companion_policies_are_checked(discrete_run: Path, dr_run: Path, continuous_run: Path) -> None:
    # A run without aligned knobs as the aligned policy, a nominal run as the DR one, another env's run.
    with pytest.raises(DualtwinError, match="not trained in an aligned twin.*train --aligned"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_aligned=dr_run, episodes=1,
                 max_episode_steps=10)
    with pytest.raises(DualtwinError, match="not trained with domain randomisation"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_dr=discrete_run, episodes=1,
                 max_episode_steps=10)
    with pytest.raises(DualtwinError, match="trained on 'dualtwin/CartPole-MuJoCo-Continuous-v0'"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_dr=continuous_run, episodes=1,
                 max_episode_steps=10)


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


def test_a_policy_for_another_robot_is_named_not_a_type_error(continuous_run: Path) -> None:
    """A CartPole policy sent to the Pioneer env: one line naming both robots (it was an internal TypeError)."""
    with pytest.raises(DualtwinError, match=r"trained for robot 'cartpole'.*runs robot 'pioneer3at'"):
        transfer(continuous_run, "dualtwin/Pioneer-DriveToGoal-MuJoCo-v0", episodes=1, max_episode_steps=10)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("env_id", "abc", "unknown env id 'abc'"),
    ("env_kwargs", "abc", r"\$\.env_kwargs must be a JSON object"),
    ("env_kwargs", {"task_kwargs": [], "control_period": "x"},
     r"\$\.env_kwargs\.control_period: .*valid number \(1 more\)"),
    ("io", [1], "io must be a JSON object"),
    ("io", {"observation": 5}, "io.observation must be an object"),
    ("io", {"observation": {"shape": 4}}, "io.observation must be an object"),
    ("max_episode_steps", "abc", "max_episode_steps must be a whole number"),
])
def test_a_hostile_run_record_is_named(discrete_run: Path, tmp_path: Path, field: str, value: object,
                                       message: str) -> None:
    """run.json is untrusted: these were Gymnasium, TypeError or ValueError tracebacks (found by fuzzing)."""
    run = Path(shutil.copytree(discrete_run, tmp_path / "run"))
    record = json.loads((run / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({**record, field: value}))
    with pytest.raises(DualtwinError, match=f"run.json: {message}"):
        transfer(run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, out_dir=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_unknown_target(discrete_run: Path) -> None:
    with pytest.raises(DualtwinError, match="registered dualtwin ids"):
        transfer(discrete_run, "dualtwin/CartPole-Gazebo-v0", episodes=1)


def test_observation_source_mismatch_is_named(discrete_run: Path) -> None:
    # Same names and units, but the cart velocity would come from the supervisor instead of odometry.
    with pytest.raises(DualtwinError, match="observation sources"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", episodes=1, max_episode_steps=10,
                 target_kwargs={"task_kwargs": {"cart_velocity": "ground_truth"}})


def test_cli_table_1_and_foreign_knobs(discrete_run: Path, aligned_run: Path, dr_run: Path, tmp_path: Path) -> None:
    def dualtwin(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "dualtwin.cli", *args], capture_output=True, text=True,
                              timeout=300)

    result = dualtwin("transfer", "--policy", str(discrete_run), "--target-env", "dualtwin/CartPole-MuJoCo-v0",
                      "--policy-aligned", str(aligned_run), "--policy-dr", str(dr_run), "--episodes", "1",
                      "--out", str(tmp_path / "t"))
    assert result.returncode == 0, result.stderr
    for label in ("target (before alignment)", "target (after alignment)", "target (with calibrated DR)"):
        assert label in result.stdout
    knobs = tmp_path / "knobs.json"
    knobs.write_text(json.dumps({"twin": "webots", "knobs": {"body.pole.mass": {"fitted": 0.3}}}))
    result = dualtwin("train", "--env", "dualtwin/CartPole-MuJoCo-v0", "--out", str(tmp_path / "run"),
                      "--aligned", str(knobs))
    assert result.returncode != 0 and "Traceback" not in result.stderr
    assert "fitted for the webots twin" in result.stderr and not (tmp_path / "run").exists()


def test_the_control_row_repeats_the_fine_tuning_in_the_nominal_twin(discrete_run: Path, tmp_path: Path) -> None:
    from tests.support.rl_runs import ALIGNED_KNOBS, train_tiny

    knobs = tmp_path / "knobs.json"
    knobs.write_text(json.dumps(ALIGNED_KNOBS))
    tuned = train_tiny(tmp_path / "aligned", "dualtwin/CartPole-MuJoCo-v0", 512, init_from=discrete_run, aligned=knobs)
    control = train_tiny(tmp_path / "control", "dualtwin/CartPole-MuJoCo-v0", 512, init_from=discrete_run)
    out = tmp_path / "transfer"
    report = transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_aligned=tuned, policy_control=control,
                      episodes=2, seed=3, out_dir=out, target_kwargs=OTHER, max_episode_steps=60)
    labels = [r.label for r in report.rows]
    assert labels == ["source", "target (before alignment)", "source (aligned twin)", "target (after alignment)",
                      "source (fine-tuned, nominal twin)", "target (fine-tuned in the nominal twin)"]
    source, _, _, after, control_source, control_target = report.rows
    assert control_source.knobs is None and control_target.policy_run == str(control)
    assert report.episode_cap == 60 and report.source_converged == (source.mean >= 59.4)
    if source.mean > 0:
        assert control_target.ratio == pytest.approx(control_target.mean / source.mean)
        assert report.alignment_gain == pytest.approx(after.ratio - control_target.ratio)  # type: ignore[operator]
    data = json.loads((out / "transfer.json").read_text())
    assert data["alignment_gain"] == report.alignment_gain and data["episode_cap"] == 60
    text = (out / "report.md").read_text()
    if report.source_converged is False:
        assert "The source is not converged" in text
    if report.alignment_gain is not None:
        assert "What alignment adds beyond the same fine-tuning" in text
    # A control that is not a nominal fine-tuning, or not the same fine-tuning, is refused before any episode.
    with pytest.raises(DualtwinError, match="control must be fine-tuned in the nominal twin"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_control=discrete_run, episodes=1)
    with pytest.raises(DualtwinError, match="control must be fine-tuned in the nominal twin"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_control=tuned, episodes=1)
    longer = train_tiny(tmp_path / "longer", "dualtwin/CartPole-MuJoCo-v0", 1024, init_from=discrete_run)
    with pytest.raises(DualtwinError, match="not the same fine-tuning.*steps"):
        transfer(discrete_run, "dualtwin/CartPole-MuJoCo-v0", policy_aligned=tuned, policy_control=longer, episodes=1)
