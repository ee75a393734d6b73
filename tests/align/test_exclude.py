"""Scenarios the twins cannot share (issue 24): every fit judges each scenario against the target's
reproducibility floor and names those beyond it, without dropping them; ``exclude`` (``--exclude``) leaves one
out of the objective only when the user asks, and the record, report and terminal say so and why."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.align import AlignResult
from dualtwin.align.floor_check import ScenarioFloor, beyond_floor, within_resolution
from tests.support.fake_twin import fit_fake, registered

#: j2's spring differs in the reference; only j1's damping is fitted, so the j2 scenario stays apart.
TRUTH = {"joint.j1.damping": 0.9, "joint.j2.stiffness": 6.5}
KNOBS = ["joint.j1.damping"]


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def fit(out: Path, **settings: object) -> AlignResult:
    return fit_fake(out, KNOBS, TRUTH, **{"budget": 40, **settings})


def test_a_scenario_beyond_its_floor_is_named_and_kept_without_consent(tmp_path: Path) -> None:
    result = fit(tmp_path / "named")
    beyond = result.floor_check["beyond"]
    assert "01_release_2" in beyond and "reproducibility floor" in beyond["01_release_2"], beyond
    assert "00_release_1" not in beyond  # the scenario the fitted knob explains is within its floor
    assert any("01_release_2 is beyond its reproducibility floor" in w and "--exclude 01_release_2" in w
               and "stays in the objective" in w for w in result.warnings), result.warnings
    assert result.excluded == {}
    record = json.loads((tmp_path / "named" / "align_record.json").read_text())
    assert record["result"]["floor_check"]["beyond"] == beyond and record["result"]["excluded"] == {}
    assert "exclude" not in record["config"]  # nothing excluded: the saved config keeps its old format


def test_exclude_leaves_the_scenario_out_of_the_objective_and_says_why(tmp_path: Path) -> None:
    kept = fit(tmp_path / "kept")
    dropped = fit(tmp_path / "dropped", exclude=["01_release_2"])
    why = dropped.excluded["01_release_2"]
    assert why.startswith("excluded by the user; measured after the fit: ") and "floor" in why, why
    assert any(w.startswith("scenario 01_release_2 excluded by the user") for w in dropped.warnings)
    # Out of the objective: the nominal mismatch is the mean over the other scenarios only.
    assert dropped.objective_before != pytest.approx(kept.objective_before)
    record = json.loads((tmp_path / "dropped" / "align_record.json").read_text())
    assert record["config"]["exclude"] == ["01_release_2"] and "01_release_2" in record["result"]["excluded"]
    assert "01_release_2 excluded by the user" in (tmp_path / "dropped" / "report.html").read_text()


@pytest.mark.parametrize(("settings", "message"), [
    ({"exclude": ["09_nothing"]}, "exclude names unknown scenarios ['09_nothing']"),
    ({"exclude": ["01_release_2"], "holdout": ["01_release_2"]}, "both held out and excluded"),
])
def test_bad_exclusions_are_refused_before_anything_is_written(tmp_path: Path, settings: dict[str, object],
                                                                message: str) -> None:
    from dualtwin.errors import DualtwinError

    with pytest.raises(DualtwinError, match=message.replace("[", r"\[").replace("]", r"\]")):
        fit(tmp_path / "bad", **settings)
    assert not (tmp_path / "bad").exists()


def test_the_cli_takes_exclude_and_reports_it(tmp_path: Path) -> None:
    out = tmp_path / "out"
    base = [sys.executable, "-m", "dualtwin.cli", "align", "--reference", "mujoco", "--target", "mujoco", "--robot",
            "cartpole", "--scenarios", "cartpole", "--knobs", "joint.pole_hinge.damping", "--optimizer", "lsq",
            "--budget", "4", "--executor", "serial", "--out", str(out)]
    bad = subprocess.run([*base, "--exclude", "99_none"], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "exclude names unknown scenarios" in bad.stderr and "Traceback" not in bad.stderr
    assert not out.exists()
    done = subprocess.run([*base, "--exclude", "04_Impulse", "--json"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["excluded"]["04_Impulse"].startswith("excluded by the user")
    assert json.loads((out / "align_config.json").read_text())["exclude"] == ["04_Impulse"]


def _row(sid: str, channel: str, ratio: float | None, rms: float, resolution: float = 1e-3) -> ScenarioFloor:
    floor = 0.0 if ratio is None else 0.01
    return ScenarioFloor(sid, channel, 0.01 * (ratio or 1.0), floor, ratio, 0.5, rms, resolution)


def test_a_scenario_above_the_limit_only_within_resolution_is_named_apart() -> None:
    """Every scenario more than FLOOR_LIMIT x its floor is in the record: beyond it (the twins cannot share it),
    or above it by differences no log of its channels can show. Below the limit, or with a zero floor and a
    difference within the resolution, nothing is named."""
    rows = [_row("a_within", "pole", 3.0, 0.5e-3), _row("b_beyond", "pole", 3.0, 2e-3),
            _row("c_below_limit", "pole", 1.2, 0.5e-3), _row("d_zero_floor", "pole", None, 0.5e-3),
            _row("e_both", "pole", 3.0, 0.5e-3), _row("e_both", "cart", 2.0, 5e-3)]
    assert sorted(beyond_floor(rows)) == ["b_beyond", "e_both"]
    unseen = within_resolution(rows)
    assert sorted(unseen) == ["a_within"], unseen
    assert "3× the target's reproducibility floor" in unseen["a_within"]
    assert "RMS difference 0.0005 is within the channel's resolution 0.001" in unseen["a_within"]
    assert rows[0].to_dict()["within_resolution"] and not rows[1].to_dict()["within_resolution"]


def test_the_record_and_warnings_carry_the_scenarios_within_resolution(tmp_path: Path) -> None:
    result = fit(tmp_path / "named")
    unseen = result.floor_check["within_resolution"]
    record = json.loads((tmp_path / "named" / "align_record.json").read_text())
    assert record["result"]["floor_check"]["within_resolution"] == unseen
    assert not set(unseen) & set(result.floor_check["beyond"])
    for sid in unseen:
        assert any(w.startswith(f"scenario {sid} is more than 1.5x its reproducibility floor") for w in result.warnings)
