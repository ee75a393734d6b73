"""Alignment against a recording: shared channels and scenarios only, and nuisance knobs (issue 15.2, 15.3).

The recording is made by a twin we control, so every true value is known: the MuJoCo twin with a pole
damping, an initial kick of the pole in the fall scenario, and logging that starts one control period late
in every scenario (the first sample dropped, the clock restarted). Its manifest then looks like an import:
``kind: recorded``, no twin, two channels, and one scenario fewer than the suite.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from dualtwin.align import AlignConfig, AlignResult, run_align
from dualtwin.align.nuisance import SHARED_TIME_OFFSET, apply_to_suite, registry, time_offsets
from dualtwin.align.objective import event_difference
from dualtwin.align.patch import patch_mjcf
from dualtwin.divergence.metrics import Threshold
from dualtwin.divergence.runs import Series
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.loader import load_suite
from tests.support.align_runs import SUITE3, TRUE_DAMPING, record, write_suite

DAMPING = "joint.pole_hinge.damping"
KICK = "scenario.00_fall.initial_angular_velocity"
TRUE_KICK = 0.3
LATE = 0.032  # one control period
CHANNELS = ("pole_angle_rad", "cart_pos_m")
SCENARIOS = ("00_fall", "02_drive")


def make_recording(robot: RobotBinding, folder: Path) -> Path:
    """A recorded-looking run: kicked fall, late logging, two channels, two of the suite's three scenarios."""
    kicked = json.loads(json.dumps(SUITE3))
    kicked["scenarios"][0]["initial_angular_velocity"] = TRUE_KICK
    run = record(robot, write_suite(folder / "kicked.json", kicked), folder / "recording", {DAMPING: TRUE_DAMPING})
    for sid in SCENARIOS:
        for log in ("ground_truth", "onboard"):
            path = run / "scenarios" / sid / f"{log}.tsv"
            header, _first, *rows = path.read_text().splitlines()
            shifted = ["\t".join([repr(round(float(r.split("\t")[0]) - LATE, 9)), *r.split("\t")[1:]]) for r in rows]
            path.write_text("\n".join([header, *shifted]) + "\n")
    manifest = json.loads((run / "manifest.json").read_text())
    for key in ("logs", "twin"):
        manifest.pop(key, None)
    manifest["kind"] = "recorded"
    manifest["channels"] = {k: v for k, v in manifest["channels"].items() if k in CHANNELS}
    manifest["scenarios"] = [s for s in manifest["scenarios"] if s["id"] in SCENARIOS]
    (run / "manifest.json").write_text(json.dumps(manifest))
    return run


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding) -> Path:
    return make_recording(robot, tmp_path_factory.mktemp("recording"))


@pytest.fixture(scope="module")
def with_nuisance(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding, suite3: Path,
                  recording: Path) -> AlignResult:
    return run_align(AlignConfig(reference=str(recording), target="mujoco", robot=str(robot.path),
                                 suite=str(suite3), knobs=[DAMPING, KICK, SHARED_TIME_OFFSET],
                                 optimizer="lsq", budget=120, executor="serial"),
                     tmp_path_factory.mktemp("nuisance") / "out")


def test_align_fits_the_shared_channels_and_scenarios_and_says_what_it_left_out(with_nuisance: AlignResult) -> None:
    left = with_nuisance.left_out
    assert left["scenarios"] == {"01_sine": "not in the reference: simulated, not fitted"}
    assert set(left["channels"]) == {"pole_velocity_rad_s", "cart_vel_m_s", "onboard/pole_angle_rad",
                                     "onboard/cart_pos_m"}
    assert all(why == "not logged by the reference" for why in left["channels"].values())
    assert any("left out: scenario 01_sine" in w for w in with_nuisance.warnings)
    record = json.loads((with_nuisance.out_dir / "align_record.json").read_text())
    assert record["result"]["left_out"] == left
    # The report has the nuisance knobs in their own section, after the physics knobs.
    report = (with_nuisance.out_dir / "report.html").read_text()
    assert report.index("<h2>Knobs</h2>") < report.index("Nuisance knobs") < report.index(KICK)


def test_nuisance_knobs_are_recovered_with_the_physics(with_nuisance: AlignResult) -> None:
    # Least squares stops a little short on the impacts' rough residuals: within 1 %, 3 % and 2 ms.
    assert with_nuisance.fitted[DAMPING] == pytest.approx(TRUE_DAMPING, rel=1e-2)
    assert with_nuisance.nuisance[KICK].fitted == pytest.approx(TRUE_KICK, rel=3e-2)
    assert with_nuisance.nuisance[SHARED_TIME_OFFSET].fitted == pytest.approx(LATE, abs=2e-3)
    assert with_nuisance.nuisance[KICK].half_width_95 is not None
    assert with_nuisance.objective_after < 1e-3 * with_nuisance.objective_before


def test_without_nuisance_knobs_the_physics_absorbs_the_kick(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                                             recording: Path, with_nuisance: AlignResult) -> None:
    """The control: the same fit without nuisance knobs ends farther from the true damping and the data."""
    physics_only = run_align(AlignConfig(reference=str(recording), target="mujoco", robot=str(robot.path),
                                         suite=str(suite3), knobs=[DAMPING], optimizer="lsq", budget=60,
                                         executor="serial"), tmp_path / "out")
    assert abs(physics_only.fitted[DAMPING] - TRUE_DAMPING) > 20 * abs(with_nuisance.fitted[DAMPING] - TRUE_DAMPING)
    assert physics_only.objective_after > 100 * with_nuisance.objective_after
    assert not physics_only.nuisance


def test_nuisance_never_reaches_the_aligned_model(with_nuisance: AlignResult, robot: RobotBinding) -> None:
    out = with_nuisance.out_dir
    assert set(with_nuisance.knobs) == set(with_nuisance.fitted) == {DAMPING}
    knobs = json.loads((out / "knobs.json").read_text())
    assert set(knobs["values"]) == set(knobs["knobs"]) == {DAMPING}
    assert set(json.loads((out / "dr_ranges.json").read_text())["knobs"]) == {DAMPING}
    model = (out / with_nuisance.files["model"]).read_text()
    assert "scenario." not in model and "initial_angular_velocity" not in model
    # The patched model is exactly the physics-only patch.
    assert model == patch_mjcf(robot.model_path("mujoco"), {DAMPING: with_nuisance.fitted[DAMPING]}, None,
                               0.032).text
    record = json.loads((out / "align_record.json").read_text())
    assert set(record["result"]["knobs"]) == {DAMPING}
    assert set(record["result"]["nuisance"]) == {KICK, SHARED_TIME_OFFSET}
    # The after run starts from the fitted initial conditions (what the fit matched); the suite file is separate.
    after_suite = json.loads((out / "runs" / "after" / "config" / "suite.json").read_text())
    assert after_suite["scenarios"][0]["initial_angular_velocity"] == with_nuisance.nuisance[KICK].fitted


def test_nothing_shared_is_one_clear_line(tmp_path: Path, robot: RobotBinding, suite3: Path, recording: Path) -> None:
    manifest = json.loads((recording / "manifest.json").read_text())
    changes: dict[str, dict[str, object]] = {"channel": {"channels": {"foo": {"source": "ground_truth", "unit": "m"}}},
               "scenario": {"scenarios": [{**manifest["scenarios"][0], "id": "07_other"}]}}
    for case, change in changes.items():
        bad = tmp_path / case
        bad.mkdir()
        (bad / "manifest.json").write_text(json.dumps({**manifest, **change}))
        with pytest.raises(DualtwinError) as err:
            run_align(AlignConfig(reference=str(bad), target="mujoco", robot=str(robot.path),
                                  suite=str(suite3), knobs=[DAMPING], executor="serial"),
                      tmp_path / f"out_{case}")
        assert f"shares no {case}" in str(err.value) and "\n" not in str(err.value)
        assert not (tmp_path / f"out_{case}").exists()


def test_a_reference_the_comparisons_would_refuse_is_refused_before_anything_is_written(
        tmp_path: Path, robot: RobotBinding, suite3: Path, recording: Path) -> None:
    """A channel in another unit than the binding's, or declared by the manifest and missing from a fitted
    scenario's log: before, align wrote its configuration and simulated runs/before, then stopped there."""
    def broken(case: str) -> Path:
        bad = tmp_path / case
        shutil.copytree(recording, bad)
        manifest = json.loads((bad / "manifest.json").read_text())
        if case == "unit":
            manifest["channels"]["pole_angle_rad"]["unit"] = "deg"
        else:  # the cart position column dropped from the fall's ground-truth log
            log = bad / "scenarios" / "00_fall" / "ground_truth.tsv"
            rows = [line.split("\t") for line in log.read_text().splitlines()]
            keep = [i for i, name in enumerate(rows[0]) if name != "cart_pos_m"]
            log.write_text("\n".join("\t".join(r[i] for i in keep) for r in rows) + "\n")
        (bad / "manifest.json").write_text(json.dumps(manifest))
        return bad

    expected = {"unit": r"reference logs channels in other units than the robot binding: "
                        r"\[\"pole_angle_rad: 'deg' \(binding 'rad'\)\"\]",
                "column": r"scenario '00_fall' \(completed\) has no log data for channels \['cart_pos_m'\]"}
    for case, message in expected.items():
        out = tmp_path / f"out_{case}"
        with pytest.raises(DualtwinError, match=message):
            run_align(AlignConfig(reference=str(broken(case)), target="mujoco", robot=str(robot.path),
                                  suite=str(suite3), knobs=[DAMPING], executor="serial"), out)
        assert not out.exists()


def test_nuisance_registry_names_bounds_and_application(robot: RobotBinding, suite3: Path) -> None:
    suite = load_suite(suite3)
    knobs = registry(suite, robot, ["00_fall", "02_drive"])
    assert "scenario.01_sine.time_offset" not in knobs  # only fitted scenarios
    angle = knobs["scenario.00_fall.initial_angle"]
    assert (angle.nominal, angle.lower, angle.upper, angle.unit) == (0.2, pytest.approx(0.15), 0.25, "rad")
    assert knobs[KICK].nominal == 0.0 and knobs[KICK].unit == "rad/s"
    # A cart position the suite does not set has no known nominal value: not offered.
    assert "scenario.00_fall.initial_cart_position" not in knobs
    applied = apply_to_suite(suite, {KICK: 0.2, "scenario.02_drive.time_offset": 0.01})
    assert applied.scenarios[0].inputs["initial_angular_velocity"] == 0.2
    assert applied.scenarios[2] == suite.scenarios[2]
    offsets = time_offsets({SHARED_TIME_OFFSET: 0.02, "scenario.02_drive.time_offset": 0.01}, suite.scenario_ids())
    assert offsets == {"00_fall": 0.02, "01_sine": 0.02, "02_drive": pytest.approx(0.03)}
    with pytest.raises(DualtwinError, match="no scenario '09_x'"):
        apply_to_suite(suite, {"scenario.09_x.initial_angle": 0.1})


def test_a_series_starting_beyond_the_threshold_has_no_crossing_to_shift() -> None:
    """A pole resting on its stop starts beyond 0.99 rad; shifting the candidate earlier must not make an event."""
    t = (np.arange(1, 30) * 0.032).astype(np.float64)
    ref = Series(t, np.ones(t.size))
    shifted = Series(t - LATE, np.ones(t.size))
    assert event_difference(ref, shifted, Threshold(0.99)) == 0.0
    falling = Series(t, np.clip(0.5 + t, None, 1.0))
    assert event_difference(falling, Series(t - LATE, falling.y), Threshold(0.99)) == pytest.approx(-LATE)
    # A pole on its stop that bounces off it: a candidate shifted by a fraction of a period whose first kept
    # sample falls inside the bounce must not "cross" there (a jump in the criterion at every period).
    bouncing = np.where((t > 0.1) & (t < 0.2), 0.95, 1.0)
    assert event_difference(Series(t, bouncing), Series(t - 0.04, bouncing), Threshold(0.99)) == 0.0
