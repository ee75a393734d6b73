"""The suite format: the published file loads unchanged; extensions; errors name file and JSON path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.suite.loader import load_suite
from dualtwin.suite.signals import Impulse, Ramp, Sine, Step, Table
from tests.support.suites import PAPER_SUITE


@pytest.fixture
def paper_suite(tmp_path: Path) -> Path:
    path = tmp_path / "test_scenarios.json"
    path.write_text(PAPER_SUITE)
    return path


def write(tmp_path: Path, data: object) -> Path:
    path = tmp_path / "suite.json"
    path.write_text(json.dumps(data))
    return path


def test_published_suite_loads_unchanged(paper_suite: Path) -> None:
    suite = load_suite(paper_suite)
    assert suite.suite_name == "Pole_Balancing_Stability_V1"
    assert suite.global_settings.control_period_s == pytest.approx(0.032)
    assert suite.global_settings.thresholds == {"failure_pole_angle_rad": 1.4, "failure_cart_position_m": 5.0}
    assert [s.inputs for s in suite.scenarios][2] == {"initial_angle": 1.0, "wheel_velocity": -10.0}
    ids = suite.scenario_ids()
    assert len(set(ids)) == 4, "repeated names must get distinct ids"
    assert ids[2] != ids[3] and ids[2].endswith("Step_Response_3")


def test_signals_evaluate() -> None:
    assert Step(kind="step", at_s=1.0, before=0.0, after=2.0)(0.99) == 0.0
    assert Step(kind="step", at_s=1.0, before=0.0, after=2.0)(1.0) == 2.0
    impulse = Impulse(kind="impulse", at_s=0.5, duration_s=0.1, value=3.0)
    assert [impulse(t) for t in (0.4, 0.5, 0.55, 0.6)] == [0.0, 3.0, 3.0, 0.0]
    ramp = Ramp(kind="ramp", start_s=1.0, end_s=3.0, start=0.0, end=4.0)
    assert [ramp(t) for t in (0.0, 2.0, 5.0)] == [0.0, 2.0, 4.0]
    assert Sine(kind="sine", amplitude=2.0, frequency_hz=0.25)(1.0) == pytest.approx(2.0)
    table = Table(kind="table", points=[(0.0, 1.0), (1.0, 3.0)], interpolation="linear")
    assert table(0.5) == pytest.approx(2.0)
    assert Table(kind="table", points=[(0.0, 1.0), (1.0, 3.0)])(0.5) == 1.0


def test_extensions_load(tmp_path: Path) -> None:
    suite = load_suite(write(tmp_path, {
        "suite_name": "ext", "scenarios": [
            {"name": "a", "duration_s": 1, "seed": 7, "reset": "fresh",
             "tolerances": {"pole_angle_rad": {"rmse": 0.05, "crossing_diff_s": 0.1}},
             "wheel_velocity": {"kind": "sine", "amplitude": 1, "frequency_hz": 2}},
            {"name": "b", "duration_s": 1, "reset": "continue",
             "wheel_velocity": {"kind": "table", "points": [[0, 0], [0.5, 1]]}}]}))
    assert suite.scenarios[0].seed == 7
    assert suite.scenarios[0].tolerances["pole_angle_rad"].rmse == 0.05
    assert isinstance(suite.scenarios[0].inputs["wheel_velocity"], Sine)
    assert suite.scenarios[1].reset == "continue"


@pytest.mark.parametrize(("data", "expected"), [
    ({"suite_name": "x", "scenarios": [{"name": "a"}]}, "$.scenarios[0].duration_s: Field required"),
    ({"suite_name": "x", "scenarios": [{"name": "a", "duration_s": -1}]}, "$.scenarios[0].duration_s"),
    ({"suite_name": "x", "scenarios": [{"name": "a", "duration_s": 1, "k": {"kind": "warp"}}]}, "$.scenarios[0]"),
    ({"suite_name": "x", "global_settings": {"TIME_STEP": 0}, "scenarios": [{"name": "a", "duration_s": 1}]},
     "$.global_settings.TIME_STEP"),
    ({"suite_name": "x", "scenarios": [{"name": "a", "duration_s": 1, "reset": "continue"}]}, "$.scenarios"),
    # names reach reports, plot titles and the terminal: one printable line, at most 256 characters (before, any)
    ({"suite_name": "x\x1b[2J", "scenarios": [{"name": "a", "duration_s": 1}]}, "$.suite_name: names are one line of printable text"),
    ({"suite_name": "x", "scenarios": [{"name": "a" * 300, "duration_s": 1}]}, "$.scenarios[0].name"),
])
def test_validation_errors_name_file_and_path(tmp_path: Path, data: object, expected: str) -> None:
    path = write(tmp_path, data)
    with pytest.raises(DualtwinError) as info:
        load_suite(path)
    assert str(path) in str(info.value)
    assert expected in str(info.value)


def test_invalid_json_gives_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{"suite_name": "x",\n  "scenarios": [}\n')
    with pytest.raises(DualtwinError, match=r"broken\.json:2:\d+: invalid JSON"):
        load_suite(path)


def test_overflowing_number_is_not_finite(tmp_path: Path) -> None:
    path = tmp_path / "big.json"
    path.write_text('{"suite_name": "x", "scenarios": [{"name": "a", "duration_s": 1e999}]}')
    with pytest.raises(DualtwinError, match=r"\$\.scenarios\[0\]\.duration_s: Input should be a finite number"):
        load_suite(path)


def test_nan_and_infinity_tokens_are_rejected(tmp_path: Path) -> None:
    for token in ("NaN", "Infinity", "-Infinity"):
        path = tmp_path / "nan.json"
        path.write_text('{"suite_name": "x", "scenarios": [{"name": "a", "duration_s": ' + token + "}]}")
        with pytest.raises(DualtwinError, match="not allowed"):
            load_suite(path)


@pytest.mark.parametrize("signal", [
    {"kind": "sine", "amplitude": 1, "frequency_hz": 1e308},  # 2*pi*f*t overflows: math.sin(inf) raised
    {"kind": "sine", "amplitude": 1e308, "frequency_hz": 1},
    {"kind": "step", "at_s": 0.05, "after": 1e308},
    {"kind": "table", "points": [[0, 1e308], [0.05, -1e308]], "interpolation": "linear"},
    {"kind": "impulse", "at_s": 1e308, "duration_s": 1e308, "value": 1},
])
def test_signal_numbers_keep_the_bounds_of_a_constant(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                      signal: dict[str, object]) -> None:
    # Found by fuzzing suite run: a constant action beyond ±1e6 was refused but the same number in a signal was
    # not, and a huge sine frequency was a traceback (ValueError: math domain error) mid-run, leaving config/.
    from dualtwin.cli import main

    path = tmp_path / "suite.json"
    path.write_text(json.dumps({"suite_name": "s", "scenarios": [
        {"name": "a", "duration_s": 0.1, "wheel_velocity": signal}]}))
    out = tmp_path / "run"
    capsys.readouterr()
    code = main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", str(path), "-o", str(out)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(err) == 1 and str(path) in err[0] and "less than or equal" in err[0], err
    assert not out.exists()
