"""The optimisers recover known knobs of the fake twin (tests/support/fake_twin.py) from its suite runs.

The reference is the fake twin itself with hidden knob values; the target starts at nominal. With the physics
in closed form and no noise, the only error left is the optimiser's, so the tolerances below are the
optimiser's: least squares to 1 %, CMA-ES (fewer evaluations, stochastic) to 5 %. Each fit takes a couple of
seconds, because a suite run of the fake twin takes milliseconds; real-twin fits live in test_fit.py.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.align import AlignConfig, AlignResult, run_align
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered

TRUTH = {"joint.j1.damping": 0.9, "joint.j1.mass": 1.3, "joint.j2.stiffness": 6.5}


def fit(out: Path, knobs: list[str], truth: dict[str, float], **settings: object) -> AlignResult:
    """Fit ``knobs`` of the fake twin to the fake twin run with ``truth``, through the public entry point."""
    config = AlignConfig.model_validate({"reference": NAME, "target": NAME, "robot": str(ROBOT), "suite": str(SUITE),
                                         "knobs": knobs, "reference_knobs": truth, "executor": "serial", **settings})
    return run_align(config, out)


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def test_least_squares_recovers_three_knobs(tmp_path: Path) -> None:
    result = fit(tmp_path / "fit", sorted(TRUTH), TRUTH, optimizer="lsq", holdout=["04_kick"], budget=200)
    for name, truth in TRUTH.items():
        assert result.fitted[name] == pytest.approx(truth, rel=0.01), (name, result.fitted)
    nominal = {name: result.knobs[name].nominal for name in TRUTH}
    assert all(abs(nominal[n] - TRUTH[n]) > 0.1 * TRUTH[n] for n in TRUTH), "the fit starts away from the truth"
    assert result.objective_after < 1e-3 * result.objective_before
    # The held-out scenario was not fitted, and it agrees too: the knobs are right, not just the fit.
    assert result.holdout_before is not None and result.holdout_after is not None
    assert result.holdout_after < 1e-3 * result.holdout_before
    knobs = json.loads((tmp_path / "fit" / "knobs.json").read_text())
    assert {n: knobs["knobs"][n]["fitted"] for n in TRUTH} == result.fitted


def test_cma_recovers_two_knobs_and_a_wrong_family_cannot(tmp_path: Path) -> None:
    truth = {"joint.j1.damping": 0.9, "joint.j2.stiffness": 6.5}
    result = fit(tmp_path / "cma", sorted(truth), truth, optimizer="cma", budget=160, seed=1)
    for name, value in truth.items():
        assert result.fitted[name] == pytest.approx(value, rel=0.05), (name, result.fitted)
    # The control: fitting only masses cannot explain a damping and a stiffness difference.
    control = fit(tmp_path / "control", ["joint.*.mass"], truth, optimizer="lsq", budget=30)
    assert control.objective_after > 10 * result.objective_after, (control.objective_after, result.objective_after)


def test_a_fit_stopped_on_its_budget_moves_to_the_lower_point_its_profile_found(tmp_path: Path) -> None:
    # Seven simulations stop least squares short of the minimum; the interval checks (outside the budget) then
    # simulate points below it, so the fit had not converged: it moves there and says so.
    truth = {"joint.j1.damping": 0.9, "joint.j1.mass": 1.3}
    result = fit(tmp_path / "short", sorted(truth), truth, optimizer="lsq", global_search="off",
                 intervals="profile", budget=7)
    assert result.stop_reason.startswith("budget (7 of 7 evaluations used)")
    assert "moved to a lower point the intervals' profile found" in result.stop_reason
    for name, value in truth.items():
        assert result.fitted[name] == pytest.approx(value, rel=1e-3), (name, result.fitted)
