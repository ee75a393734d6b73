"""Lockstep and k-step prediction on two fake twins (tests/support/fake_twin.py): the sync machinery (state
transfer, re-sync policies, error by horizon, prediction rollouts) without physics engines, in about a second.
The two twins differ only by a knob, so every expected zero is exact and every divergence has a known cause."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.divergence.prediction import prediction_error
from dualtwin.sync import run_lockstep
from tests.support.fake_twin import NAME, SUITE, fake_robot, registered

DAMPED = {"joint.j1.damping": 1.2}


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def test_identical_twins_in_lockstep_never_drift(tmp_path: Path) -> None:
    result = run_lockstep(NAME, NAME, fake_robot(), out_dir=tmp_path / "same", suite=SUITE)
    assert [e.status for e in result.episodes] == ["completed"] * 5
    assert all(e.max_error == 0.0 and e.resyncs == 0 for e in result.episodes)
    assert (tmp_path / "same" / "episodes" / "00_release_1" / "state_diff.tsv").is_file()


def test_a_knob_difference_drifts_only_where_its_joint_moves_and_resync_bounds_it(tmp_path: Path) -> None:
    never = run_lockstep(NAME, NAME, fake_robot(), out_dir=tmp_path / "never", suite=SUITE, secondary_knobs=DAMPED)
    every = run_lockstep(NAME, NAME, fake_robot(), out_dir=tmp_path / "every", suite=SUITE, secondary_knobs=DAMPED,
                         resync="every:5")
    by_id = {e.id: e for e in never.episodes}
    assert by_id["00_release_1"].mean_error > 0.1
    assert by_id["01_release_2"].max_error == 0.0, "j1 never moves in release_2: the control"
    assert all(e.resyncs == 20 for e in every.episodes)  # 100 periods, a re-sync every 5
    for a, b in zip(never.episodes, every.episodes, strict=True):
        assert b.mean_error <= a.mean_error
    assert every.episodes[0].mean_error < 0.1 * by_id["00_release_1"].mean_error
    horizons = every.error_by_horizon()
    assert sorted(horizons) == [1, 2, 3, 4, 5]
    assert all(horizons[h] < horizons[h + 1] for h in range(1, 5)), "the error grows with time since a sync"


def test_prediction_error_is_zero_for_the_same_twin_and_grows_with_horizon_otherwise(tmp_path: Path) -> None:
    same = prediction_error(NAME, NAME, fake_robot(), suite=SUITE, out_dir=tmp_path / "same", horizons=(1, 5, 25))
    assert all(row["normalized_rms"] == 0.0 and row["failed"] == 0 for row in same.table["by_horizon"].values())
    damped = prediction_error(NAME, NAME, fake_robot(), suite=SUITE, out_dir=tmp_path / "damped",
                              horizons=(1, 5, 25), secondary_knobs=DAMPED)
    rows = damped.table["by_horizon"]
    assert 0 < rows["1"]["normalized_rms"] < rows["5"]["normalized_rms"] < rows["25"]["normalized_rms"]
    assert rows["25"]["rms"]["joint/j2/q"] == 0.0 and rows["25"]["rms"]["joint/j1/q"] > 0.01
    # The damped twin predicts better than assuming nothing changes: the comparison's built-in control.
    assert rows["5"]["rms"]["joint/j1/q"] < rows["5"]["no_change_rms"]["joint/j1/q"]
    assert sorted(p.name for p in (tmp_path / "damped").iterdir()) == [
        "prediction.json", "prediction.png", "prediction.tsv", "trajectories.npz"]
