"""Identifiability before and after the fit, tied knobs, mujoco.sysid parameter files and the advice of a fit that
cannot move (issues 24 and 28), on the fake twin (tests/support/fake_twin.py) and on synthetic Jacobians.

On the fake twin a released spring obeys ``q'' = -(k/m) q - (c/m) q'``: scaling mass, stiffness and damping
together changes nothing, so a suite of releases alone cannot separate them, while the driven scenarios (a known
torque) can. That is the trade-off the check must name before the fit and the correlation it must show after.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import yaml

from dualtwin.align import AlignConfig, AlignResult, run_align
from dualtwin.align.identifiability import check, common_glob, correlated_pairs
from dualtwin.align.knobs import KnobSpec, tie_knobs
from dualtwin.align.stuck import stuck_advice
from dualtwin.align.writers import KnobFit
from dualtwin.errors import DualtwinError
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered
from tests.support.noisy_runs import noisy_recording

J1 = ["joint.j1.mass", "joint.j1.stiffness", "joint.j1.damping"]
OTHERS = ["01_release_2", "02_push", "03_drive", "04_kick"]


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def fit(out: Path, **settings: Any) -> AlignResult:
    config = AlignConfig.model_validate({"reference": NAME, "target": NAME, "robot": str(ROBOT), "suite": str(SUITE),
                                         "executor": "serial", "optimizer": "lsq", **settings})
    return run_align(config, out)


def test_synthetic_parallel_gains_are_named_with_the_scenario_that_separates_them_and_a_tie() -> None:
    rng = np.random.default_rng(0)
    straight, turn = rng.normal(size=(50, 1)), rng.normal(size=(50, 2))
    # Both wheel gains move the cart identically when driving straight; only the turn tells them apart.
    jac = np.vstack([np.hstack([straight, straight * 1.0001, rng.normal(size=(50, 1))]),
                     np.hstack([0.05 * turn, rng.normal(size=(50, 1)) * 0.01])])
    specs = [KnobSpec("motor.left.gain", 1, -2, 2), KnobSpec("motor.right.gain", 1, -2, 2),
             KnobSpec("joint.pole.damping", 0.1, 0, 1)]
    report = check(jac, specs, {"straight": [(0, 50)], "turn": [(50, 100)]})
    assert [e["knobs"] for e in report.parallel] == [["motor.left.gain", "motor.right.gain"]]
    assert report.parallel[0]["separated_best_by"]["scenario"] == "turn"
    assert report.ties == ["motor.*.gain"]
    assert any("tie 'motor.*.gain'" in a for a in report.advice)
    assert any("command levels" in a for a in report.advice)  # the family that separates gains
    # The control: independent columns raise nothing.
    clean = check(rng.normal(size=(100, 3)), specs)
    assert not clean.parallel and not clean.tradeoffs and not clean.ties and clean.rank == 3
    assert common_glob(["joint.a.damping", "joint.b.mass"]) is None
    assert correlated_pairs(["a", "b", "c"], np.array([[1, 0.95, 0.2], [0.95, 1, -0.3], [0.2, -0.3, 1]])) == [
        {"knobs": ["a", "b"], "r": 0.95}]


def test_releases_alone_cannot_separate_mass_stiffness_and_damping(tmp_path: Path) -> None:
    truth = {"joint.j1.mass": 1.3, "joint.j1.stiffness": 5.2, "joint.j1.damping": 0.6}
    reference = noisy_recording(tmp_path / "ref", NAME, ROBOT, SUITE, truth, seed=4, noise=0.01)
    result = fit(tmp_path / "releases", reference=str(reference), knobs=J1, holdout=OTHERS, budget=80)
    before = result.identifiability["before"]
    named = [set(e["knobs"]) for e in before["parallel"]] + [set(g) for g in before["tradeoffs"]]
    assert {"joint.j1.mass", "joint.j1.stiffness"} in named or set(J1) in named, before
    assert any("driven steps" in a for a in before["advice"])  # the scenario family that separates a mass
    # After the fit: the hidden direction shows as correlations above 0.9, named in the record and the warnings,
    # and the intervals are wide (or the bounds) instead of the Jacobian's false precision.
    record = json.loads((tmp_path / "releases" / "align_record.json").read_text())
    correlated = record["result"]["identifiability"]["after"]["correlated"]
    assert correlated and all(abs(e["r"]) > 0.9 for e in correlated)
    assert any("correlated (r =" in w for w in record["result"]["warnings"])
    for name, value in truth.items():
        knob = result.knobs[name]
        lo, hi = knob.interval_95 or (knob.lower, knob.upper)
        assert lo <= value <= hi and hi - lo > 0.2 * value, (name, lo, hi, knob.method)
    # The control: with the driven scenarios the same knobs are identified, with narrow intervals.
    control = fit(tmp_path / "all", reference=str(reference), knobs=J1, holdout=["04_kick"], budget=120)
    assert control.identifiability["before"]["tradeoffs"] == []
    for name, value in truth.items():
        lo, hi = control.knobs[name].interval_95 or (0, 0)
        # Narrow, and near the truth (a single seeded fit: coverage itself is the coverage study's job).
        assert hi - lo < 0.1 * value and lo - (hi - lo) <= value <= hi + (hi - lo), (name, lo, hi)


def test_tied_knobs_from_a_sysid_parameter_file_fit_one_value_and_export_in_its_format(tmp_path: Path) -> None:
    params = {name: {"name": name, "nominal": [0.3], "min_value": [0.05], "max_value": [1.0], "value": [0.3],
                     "frozen": False} for name in ("joint.j1.damping", "joint.j2.damping")}
    params["joint.j1.mass"] = {"name": "joint.j1.mass", "nominal": [1.0], "min_value": [0.5], "max_value": [2.0],
                               "value": [1.0], "frozen": True}  # frozen: not fitted
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(params))
    truth = {"joint.j1.damping": 0.7, "joint.j2.damping": 0.7}
    result = fit(tmp_path / "tied", knobs=[], sysid_params=str(path), tie=["joint.*.damping"],
                 reference_knobs=truth, holdout=["04_kick"], budget=60)
    assert set(result.knobs) == set(truth)
    values = {n: k.fitted for n, k in result.knobs.items()}
    assert values["joint.j1.damping"] == values["joint.j2.damping"] == pytest.approx(0.7, rel=1e-3)
    assert {k.tied for k in result.knobs.values()} == {"joint.*.damping"}
    assert all((k.lower, k.upper) == (0.05, 1.0) for k in result.knobs.values())  # the file's bounds
    exported = yaml.safe_load((tmp_path / "tied" / "sysid_params.yaml").read_text())
    assert {n: e["value"] for n, e in exported.items()} == {n: [v] for n, v in values.items()}
    parameter_dict = getattr(pytest.importorskip("mujoco.sysid"), "ParameterDict", None)
    if parameter_dict is None:
        pytest.skip("mujoco.sysid is installed without its optional dependencies")
    loaded = parameter_dict.load_from_disk(tmp_path / "tied" / "sysid_params.yaml")
    assert float(loaded["joint.j1.damping"].value[0]) == values["joint.j1.damping"]


def test_a_tie_must_group_two_compatible_knobs() -> None:
    specs = [KnobSpec("joint.a.damping", 0.1, 0, 1), KnobSpec("joint.b.damping", 1.7, 1.5, 2),
             KnobSpec("joint.a.mass", 1, 0.5, 2, unit="kg")]
    with pytest.raises(DualtwinError, match="matches 1 of the selected knobs"):
        tie_knobs(specs, ["joint.*.mass"])
    with pytest.raises(DualtwinError, match="do not overlap"):
        tie_knobs(specs, ["joint.*.damping"])
    tied = tie_knobs([specs[0], KnobSpec("joint.b.damping", 0.3, 0.0, 0.5), specs[2]], ["joint.*.damping"])
    assert [s.name for s in tied] == ["joint.*.damping", "joint.a.mass"]
    assert (tied[0].lower, tied[0].upper, tied[0].members) == (0.0, 0.5, ("joint.a.damping", "joint.b.damping"))


def test_a_fit_that_cannot_move_says_what_the_analysis_suggests(tmp_path: Path) -> None:
    fits = {"k": KnobFit("k", "", 0.9, 0.5, 0.5, 0.9999, None, "lower")}
    findings = [SimpleNamespace(kind="sign_inversion", message="q1 is mirrored in 02_push")]
    run = tmp_path / "run"
    run.mkdir()
    (run / "manifest.json").write_text(json.dumps({"scenarios": [{"id": "02", "notes": [
        "starts at q1 = -0.153 where the suite sets initial_q1 = 0: the state may have carried over from the "
        "previous scenario (no reset)"]}]}))
    advice = stuck_advice(0.5161, 0.5161, fits, SimpleNamespace(findings=findings), run)  # type: ignore[arg-type]
    assert "could not move" in advice[0]
    assert any("sign flip" in a for a in advice) and any("carry state over" in a for a in advice)
    # The control: a fit that moved and lowered the criterion gets no advice.
    moved = {"k": KnobFit("k", "", 0.9, 0.7, 0.5, 0.9999)}
    assert stuck_advice(0.5, 0.1, moved, SimpleNamespace(findings=findings), run) == []  # type: ignore[arg-type]
