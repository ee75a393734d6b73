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
