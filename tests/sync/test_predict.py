"""Short-horizon prediction error and the prediction alignment objective."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualtwin.align import AlignConfig, run_align
from dualtwin.divergence.prediction import PredictionSettings, predict, prediction_error
from dualtwin.divergence.trajectories import load_trajectories, record_trajectories, save_trajectories
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.loader import load_suite
from dualtwin.twins import make_twin
from tests.support.sync_helpers import NOMINAL_DAMPING

DAMPING = "joint.pole_hinge.damping"


def test_identical_models_predict_each_other_exactly(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    result = prediction_error("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "p")
    assert max(result.normalized_rms().values()) < 1e-12
    for name in ("prediction.json", "prediction.tsv", "prediction.png", "trajectories.npz"):
        assert (tmp_path / "p" / name).is_file()
    record = json.loads((tmp_path / "p" / "prediction.json").read_text())
    assert record["settings"]["horizons"] == [1, 5, 25] and record["table"]["by_horizon"]["25"]["rollouts"] > 0


def test_a_mismatch_grows_with_the_horizon(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    result = prediction_error("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "p",
                              primary_knobs={DAMPING: 0.1})
    rms = result.normalized_rms()
    assert 0 < rms[1] < rms[5] < rms[25]
    row = result.table["by_horizon"]["5"]
    # The pole carries the mismatch; the chassis height does not move at all.
    assert row["rms"]["joint/pole_hinge/qd"] > 100 * row["rms"]["body/cart/z"]


def test_trajectories_round_trip_and_replay(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    twin = make_twin("webots", cartpole)
    try:
        recorded = record_trajectories(twin, cartpole, load_suite(suite), ["01_sine"])
    finally:
        twin.close()
    save_trajectories(tmp_path / "t.npz", recorded, {"twin": "webots"})
    loaded, meta = load_trajectories(tmp_path / "t.npz")
    assert meta == {"twin": "webots"} and loaded[0].id == "01_sine" and len(loaded[0]) == 32
    assert np.array_equal(loaded[0].states, recorded[0].states) and loaded[0].active(5) == recorded[0].active(5)
    mujoco = make_twin("mujoco", cartpole)
    try:
        samples = predict(mujoco, loaded, PredictionSettings((1, 5), stride=8))
    finally:
        mujoco.close()
    assert samples.errors[1].shape[0] == 4 and not samples.failed[5].any()
    with pytest.raises(DualtwinError, match="not found"):
        load_trajectories(tmp_path / "missing.npz")


@pytest.mark.parametrize("optimizer", ["lsq", "cma"])
def test_prediction_objective_recovers_doubled_damping(tmp_path: Path, damped_cartpole: RobotBinding, suite: Path,
                                                       optimizer: str) -> None:
    """Nominal damping 0.05, the reference has 0.1 (x2): the fit finds it within 5 %."""
    truth = 2 * NOMINAL_DAMPING
    kwargs = {"budget": 40, "popsize": 6} if optimizer == "cma" else {}
    result = run_align(AlignConfig(reference="mujoco", target="mujoco", robot=str(damped_cartpole.path),
                                   suite=str(suite), knobs=[DAMPING], optimizer=optimizer,
                                   reference_knobs={DAMPING: truth}, objective="prediction",
                                   executor="serial", stride=4, **kwargs), tmp_path / "fit")
    assert abs(result.fitted[DAMPING] - truth) / truth < 0.05
    assert result.objective_after < 0.01 * result.objective_before
    assert result.condition_number == pytest.approx(1.0)
    out = tmp_path / "fit"
    for name in ("knobs.json", "dr_ranges.json", "align_record.json", "report.html", "cartpole_aligned.xml",
                 "reference_trajectories.npz", "prediction.png"):
        assert (out / name).is_file(), name
    record = json.loads((out / "align_record.json").read_text())
    assert record["objective"] == "prediction" and record["evaluations"] == result.evaluations
    assert json.loads((out / "knobs.json").read_text())["values"] == result.fitted


def test_prediction_objective_from_a_lockstep_recording(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    """A lockstep run's trajectories are a reference; inapplicable options are refused."""
    from dualtwin.sync import run_lockstep

    run_lockstep("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "ls", primary_knobs={DAMPING: 0.08})
    result = run_align(AlignConfig(reference=str(tmp_path / "ls"), target="mujoco", robot=str(cartpole.path),
                                   suite=str(suite), knobs=[DAMPING], optimizer="lsq", objective="prediction",
                                   executor="serial", budget=40), tmp_path / "fit")
    assert result.fitted[DAMPING] == pytest.approx(0.08, rel=0.05)
    with pytest.raises(DualtwinError, match="does not take holdout"):
        run_align(AlignConfig(reference=str(tmp_path / "ls"), target="mujoco", robot=str(cartpole.path),
                              suite=str(suite), knobs=[DAMPING], objective="prediction", holdout=["00_fall"]),
                  tmp_path / "x")
