"""The suite runner on the MuJoCo twin: logs, manifest, determinism, atomic resume, failures."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.runner import SuiteRun
from tests.support.fake_twin import SUITE as FAKE_SUITE
from tests.support.fake_twin import fake_robot, registered
from tests.support.suites import PAPER_SUITE


@pytest.fixture
def paper_suite(tmp_path: Path) -> Path:
    path = tmp_path / "test_scenarios.json"
    path.write_text(PAPER_SUITE)
    return path


def read_tsv(path: Path) -> tuple[list[str], list[list[float]]]:
    lines = path.read_text().splitlines()
    return lines[0].split("\t"), [[float(v) for v in line.split("\t")] for line in lines[1:]]


def test_published_suite_runs_and_pole_rests_on_stop(paper_suite: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    manifest = SuiteRun(paper_suite, "mujoco", resolve_robot("cartpole"), out).run()
    assert [s["status"] for s in manifest["scenarios"]] == ["completed"] * 4
    header, rows = read_tsv(out / "scenarios" / "00_Step_Response" / "ground_truth.tsv")
    assert header[:3] == ["time_s", "pole_angle_rad", "cart_pos_m"]
    assert rows[0][0] == pytest.approx(0.032), "sampled once per control period, after the step"
    assert rows[0][1] == pytest.approx(0.001, rel=0.05)
    assert rows[-1][0] == pytest.approx(5.024)  # Webots-style loop: step until t >= duration
    angles = [r[1] for r in rows]
    assert max(angles) < 1.1, "the stop at 1 rad holds"
    assert abs(angles[-1] - 1.0) < 0.02, "the pole ends resting on the +1 rad stop"
    onboard_header, onboard = read_tsv(out / "scenarios" / "00_Step_Response" / "onboard.tsv")
    assert onboard_header == ["time_s", "pole_angle_rad", "cart_pos_m"]
    assert len(onboard) == len(rows)
    # Moving backwards at 10 rad/s on 0.04 m wheels: about -0.4 m/s.
    _, run3 = read_tsv(out / "scenarios" / "02_Step_Response_3" / "ground_truth.tsv")
    assert run3[-1][2] / run3[-1][0] == pytest.approx(-0.4, rel=0.1)
    for key in ("versions", "inputs", "seed", "channels"):
        assert key in manifest
    assert manifest["inputs"]["suite"]["sha256"]
    assert (out / "config" / "suite.json").read_text() == PAPER_SUITE


def test_runs_are_byte_identical(paper_suite: Path, tmp_path: Path) -> None:
    robot = resolve_robot("cartpole")
    SuiteRun(paper_suite, "mujoco", robot, tmp_path / "a").run()
    SuiteRun(paper_suite, "mujoco", robot, tmp_path / "b").run()
    for sid in ("00_Step_Response", "03_Step_Response_3"):
        for log in ("onboard.tsv", "ground_truth.tsv"):
            a = (tmp_path / "a" / "scenarios" / sid / log).read_bytes()
            assert a == (tmp_path / "b" / "scenarios" / sid / log).read_bytes()


def test_resume_runs_only_what_is_missing(tmp_path: Path) -> None:
    # Runner logic only, so the fake twin serves (tests/support/fake_twin.py): no physics needed.
    with registered() as fake:
        robot = fake_robot()
        out = tmp_path / "run"
        SuiteRun(FAKE_SUITE, fake, robot, out).run()
        reference = (out / "scenarios" / "02_push" / "ground_truth.tsv").read_bytes()
        # Simulate a crash after two scenarios: the last three logs never got written.
        manifest = json.loads((out / "manifest.json").read_text())
        manifest["scenarios"] = manifest["scenarios"][:2]
        (out / "manifest.json").write_text(json.dumps(manifest))
        for sid in ("02_push", "03_drive", "04_kick"):
            shutil.rmtree(out / "scenarios" / sid)
        first_mtime = (out / "scenarios" / "00_release_1" / "ground_truth.tsv").stat().st_mtime_ns
        seen: list[tuple[str, str]] = []
        SuiteRun(FAKE_SUITE, fake, robot, out).run(resume=True, on_scenario=lambda s, st: seen.append((s, st)))
    assert seen[0] == ("00_release_1", "skipped (done)")
    assert [st for _, st in seen[2:]] == ["completed"] * 3
    assert (out / "scenarios" / "00_release_1" / "ground_truth.tsv").stat().st_mtime_ns == first_mtime
    assert (out / "scenarios" / "02_push" / "ground_truth.tsv").read_bytes() == reference
    assert len(json.loads((out / "manifest.json").read_text())["scenarios"]) == 5


def test_refuses_to_overwrite_and_resume_checks_inputs(tmp_path: Path) -> None:
    with registered() as fake:
        robot = fake_robot()
        out = tmp_path / "run"
        SuiteRun(FAKE_SUITE, fake, robot, out).run()
        with pytest.raises(DualtwinError, match="earlier suite-run output; use --resume"):
            SuiteRun(FAKE_SUITE, fake, robot, out).run()
        with pytest.raises(DualtwinError, match="cannot resume"):
            SuiteRun(FAKE_SUITE, fake, robot, out, seed=3).run(resume=True)


SMALL_SUITE = '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1}]}'


@pytest.mark.parametrize(("scenarios", "expected"), [
    ('"x"', "$.scenarios"),
    ("[1]", "$.scenarios[0]"),
    ('[{"id": ["00_a"], "status": "completed"}]', "$.scenarios[0].id"),
    ('[{"id": "00_a", "status": "bogus"}]', "$.scenarios[0].status"),
    ('[{"id": "00_a", "status": "completed", "onboard": "../../../../../etc/passwd", "ground_truth": "x.tsv"}]',
     "outside the run folder"),
])
def test_resume_refuses_a_manifest_of_the_wrong_shape(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], scenarios: str, expected: str,
) -> None:
    # The folder to resume is data: found by fuzzing `suite run --resume`, these records were read unchecked
    # (a traceback) or, with a bogus status, copied into the resumed run's manifest.
    suite = tmp_path / "suite.json"
    suite.write_text(SMALL_SUITE)
    out = tmp_path / "run"
    args = ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", str(suite), "-o", str(out)]
    assert main(args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["scenarios"] = json.loads(scenarios)
    (out / "manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    assert main([*args, "--resume"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert len(err) == 1 and str(out / "manifest.json") in err[0] and expected in err[0], err
    assert json.loads((out / "manifest.json").read_text())["scenarios"] == json.loads(scenarios)


def test_failure_threshold_stops_the_scenario(tmp_path: Path) -> None:
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({
        "suite_name": "fail", "global_settings": {"TIME_STEP": 32, "failure_pole_angle_rad": 0.5},
        "scenarios": [{"name": "falls", "duration_s": 5.0, "initial_angle": 0.01}]}))
    out = tmp_path / "run"
    manifest = SuiteRun(suite, "mujoco", resolve_robot("cartpole"), out).run()
    falls = manifest["scenarios"][0]
    assert falls["status"] == "failed"
    assert falls["failure"]["channel"] == "pole_angle_rad"
    assert 0.5 < falls["failure"]["time_s"] < 5.0
    _, rows = read_tsv(out / "scenarios" / "00_falls" / "ground_truth.tsv")
    assert rows[-1][0] == pytest.approx(falls["failure"]["time_s"]) and rows[-1][1] > 0.5


def test_continue_reset_and_step_signal(tmp_path: Path) -> None:
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({
        "suite_name": "continue", "scenarios": [
            {"name": "falls", "duration_s": 3.0, "initial_angle": 0.01},
            {"name": "drive", "duration_s": 1.5, "reset": "continue",
             "wheel_velocity": {"kind": "step", "at_s": 0.5, "before": 0.0, "after": 5.0}}]}))
    out = tmp_path / "run"
    manifest = SuiteRun(suite, "mujoco", resolve_robot("cartpole"), out).run()
    assert manifest["scenarios"][1]["reset"] == "continue"
    _, rows = read_tsv(out / "scenarios" / "01_drive" / "ground_truth.tsv")
    assert rows[0][0] == pytest.approx(0.032) and rows[0][1] > 0.9, "continues from the previous end state"
    speeds = [r[4] for r in rows]
    assert abs(speeds[10]) < 0.05, "wheels still held before the step"
    assert speeds[-1] == pytest.approx(0.2, rel=0.15), "5 rad/s on 0.04 m wheels after the step"


def test_unknown_key_is_rejected_before_writing(tmp_path: Path) -> None:
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({"suite_name": "x", "scenarios": [{"name": "a", "duration_s": 1, "warp": 2}]}))
    out = tmp_path / "run"
    with pytest.raises(DualtwinError, match=r"\$\.scenarios\[0\]\.warp: unknown robot-specific key 'warp'"):
        SuiteRun(suite, "mujoco", resolve_robot("cartpole"), out).run()
    assert not out.exists()


@pytest.mark.parametrize("twin_name", ["mujoco", "webots"])
def test_blow_up_is_an_unstable_scenario_and_the_next_one_recovers(tmp_path: Path, twin_name: str) -> None:
    from dualtwin.twins import make_twin

    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({"suite_name": "unstable", "scenarios": [
        {"name": "blowup", "duration_s": 0.5, "initial_angular_velocity": 10.0},
        {"name": "after", "duration_s": 0.5, "initial_angle": 0.1}]}))
    robot = resolve_robot("cartpole")
    twin = make_twin(twin_name, robot, 0.032)
    # An absurd physics knob makes the first scenario diverge (an absurd initial state is refused before any
    # run now); it is put back once that scenario ends, so the next one shows what the reset recovers.
    # (Webots resets a WorldInfo CFM <= 0 to its default, so the Webots twin's absurd knob is a bounce of 1e9)
    knob, absurd = ("joint.pole_hinge.damping", -1e9) if twin_name == "mujoco" else ("contact.default:default.bounce",
                                                                                     1e9)
    nominal = twin.knobs()[knob].nominal
    twin.set_knobs({knob: absurd})
    manifest = SuiteRun(suite, twin_name, robot, tmp_path / "run", twin=twin).run(
        on_scenario=lambda sid, status: twin.set_knobs({knob: nominal}))
    blowup, after = manifest["scenarios"]
    assert blowup["status"] == "unstable" and "time_s" in blowup["failure"]
    assert after["status"] == "completed"
    _, rows = read_tsv(tmp_path / "run" / "scenarios" / "01_after" / "ground_truth.tsv")
    assert rows[0][1] == pytest.approx(0.1, abs=0.01), "the reset after the blow-up recovered"
