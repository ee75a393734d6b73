"""Divergence metrics on real suite runs of the fake twin (tests/support/fake_twin.py): runs written by the
real runner, compared by the real comparison, in well under a second, with the physics known in closed form."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from dualtwin.divergence import compare_runs, rmse
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin
from tests.support.fake_twin import NAME, SUITE, fake_robot, registered


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def run(out: Path, knobs: dict[str, float] | None = None, seed: int = 0) -> Path:
    robot = fake_robot()
    twin = make_twin(NAME, robot)
    twin.set_knobs(knobs or {})
    SuiteRun(SUITE, NAME, robot, out, seed=seed, twin=twin).run()
    return out


def test_same_twin_same_inputs_no_divergence(tmp_path: Path) -> None:
    a, b = run(tmp_path / "a"), run(tmp_path / "b")
    for log in sorted((a / "scenarios").rglob("*.tsv")):
        assert log.read_bytes() == (b / log.relative_to(a)).read_bytes()
    comparison = compare_runs(a, b)
    assert len(comparison.scenarios) == 5
    for sc in comparison.scenarios:
        for name, ch in sc.channels.items():
            assert ch.rmse == 0.0 and ch.max_abs_error == 0.0 and ch.lag_s == 0.0, (sc.id, name)
            assert not ch.sign_inverted


def test_a_damping_change_diverges_only_on_its_joint(tmp_path: Path) -> None:
    """The control: j2's channels in a scenario where only j1 moves do not diverge at all."""
    comparison = compare_runs(run(tmp_path / "nominal"), run(tmp_path / "damped", {"joint.j1.damping": 1.6}))
    by_id = {sc.id: sc for sc in comparison.scenarios}
    release_1 = by_id["00_release_1"].channels
    assert release_1["q1"].rmse > 0.02 and release_1["qd1"].rmse > 0.05
    assert release_1["q2"].rmse == 0.0 and release_1["x2"].rmse == 0.0
    release_2 = by_id["01_release_2"].channels
    assert release_2["q1"].rmse == 0.0 and release_2["q2"].rmse == 0.0
    # More damping only shrinks the swing: the damped run is the nominal one scaled down, not inverted.
    assert release_1["q1"].correlation is not None and release_1["q1"].correlation > 0.5
    assert not release_1["q1"].sign_inverted
    assert by_id["00_release_1"].score is not None and by_id["01_release_2"].score is not None
    assert by_id["00_release_1"].score > by_id["01_release_2"].score


def test_rmse_on_the_logs_matches_the_comparison(tmp_path: Path) -> None:
    """The comparison's RMSE on identical time grids is the plain RMSE of the two logged columns."""
    a, b = run(tmp_path / "a"), run(tmp_path / "b", {"joint.j2.stiffness": 12.0})
    comparison = compare_runs(a, b)
    sc = next(s for s in comparison.scenarios if s.id == "01_release_2")
    col_a = np.loadtxt(a / "scenarios" / sc.id / "ground_truth.tsv", skiprows=1)[:, 2]
    col_b = np.loadtxt(b / "scenarios" / sc.id / "ground_truth.tsv", skiprows=1)[:, 2]
    assert sc.channels["q2"].rmse == pytest.approx(rmse(col_a, col_b), rel=1e-9)
    assert sc.channels["q2"].rmse > 0.01


# The rows logged before the first non-finite one hold values near 1e300, whose squares overflow in the MSE.
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_a_blow_up_in_one_run_scores_the_maximum(tmp_path: Path) -> None:
    comparison = compare_runs(run(tmp_path / "a"), run(tmp_path / "b", {"joint.j1.stiffness": 1e12}))
    release_1 = next(s for s in comparison.scenarios if s.id == "00_release_1")
    assert release_1.status_a == "completed" and release_1.status_b == "unstable"
    assert release_1.score == 1.0


def test_a_scenario_that_fails_in_its_first_period_is_noted_and_the_rest_compared(tmp_path: Path) -> None:
    """A failure threshold crossed in the first control period leaves one logged row: that scenario is "not
    compared" (with the reason), the others are compared as usual. It used to refuse the whole comparison."""
    import json

    suite = json.loads(SUITE.read_text())
    suite["global_settings"]["failure_q1"] = 0.45  # release_1 starts at q1 = 0.5: over it at once
    path = tmp_path / "suite.json"
    path.write_text(json.dumps(suite))
    runs = []
    for name in ("a", "b"):
        robot = fake_robot()
        SuiteRun(path, NAME, robot, tmp_path / name, seed=0, twin=make_twin(NAME, robot)).run()
        runs.append(tmp_path / name)
    by_id = {sc.id: sc for sc in compare_runs(*runs).scenarios}
    first = by_id["00_release_1"]
    assert first.status_a == first.status_b == "failed"
    assert first.channels == {} and first.score is None
    assert first.note is not None and "not compared: q1 (series A needs at least 2 samples, got 1)" in first.note
    assert by_id["01_release_2"].channels and by_id["01_release_2"].score == 0.0  # the control: still compared
