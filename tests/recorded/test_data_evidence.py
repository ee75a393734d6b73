"""What an import reads from the data itself: state carried over between scenarios, and wall-clock stamps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualtwin.recorded import import_paper
from dualtwin.recorded.clock import gap_statistics
from tests.support.paper_logs import PERIOD, SUITE, write_logs


def manifest(run: Path) -> dict:
    return json.loads((run / "manifest.json").read_text())


def test_state_carried_over_is_detected_on_a_channel_the_suite_does_not_set(tmp_path: Path) -> None:
    # The third file starts where the second ended (-0.153 m), the fourth where the third ended (1.81 m); the
    # suite sets no cart position, so only the data can tell.
    starts, ends = [0.0, 0.0, -0.153, 1.81, 0.0, 0.0], [0.0, -0.153, 1.81, 1.9, 0.0, 0.0]
    run = import_paper(write_logs(tmp_path / "logs", starts, ends), SUITE, "cartpole", tmp_path / "run")
    sc = manifest(run)["scenarios"]
    carried = [s["id"] for s in sc if "carried_over" in s.get("state_continuity", {})]
    assert carried == [sc[2]["id"], sc[3]["id"]]
    entry = sc[2]["state_continuity"]["carried_over"]
    assert entry["from"] == sc[1]["id"]
    assert entry["channels"]["cart_pos_m"]["first"] == pytest.approx(-0.153)
    assert entry["channels"]["cart_pos_m"]["reset"] == 0.0
    assert "pole_angle_rad" not in entry["channels"]  # at the suite's initial angle: reset as the twin would
    note = f"scenario {sc[2]['id']} starts where {sc[1]['id']} ended (cart_pos_m -0.153 m instead of 0): state carried over"
    assert any(n.startswith(note) for n in sc[2]["notes"])


def test_a_reset_recording_has_no_carry_over_note(tmp_path: Path) -> None:
    # Control: every scenario starts at its reset state, although the previous one ended elsewhere.
    starts, ends = [0.0] * 6, [0.0, -0.153, 1.81, 1.9, 0.3, 0.0]
    run = import_paper(write_logs(tmp_path / "logs", starts, ends), SUITE, "cartpole", tmp_path / "run")
    for s in manifest(run)["scenarios"]:
        assert "state_continuity" not in s
        assert not any("carried over" in n for n in s["notes"])


def test_a_start_away_from_reset_and_from_the_previous_end_is_reported_as_such(tmp_path: Path) -> None:
    starts, ends = [0.0, 0.0, 0.7, 0.0, 0.0, 0.0], [0.0] * 6
    run = import_paper(write_logs(tmp_path / "logs", starts, ends), SUITE, "cartpole", tmp_path / "run")
    sc = manifest(run)["scenarios"][2]
    assert set(sc["state_continuity"]) == {"away_from_reset"}
    assert any("starts away from the twin's reset state (cart_pos_m 0.7 m instead of 0)" in n for n in sc["notes"])


def test_wall_clock_stamps_are_labelled_with_their_jitter(tmp_path: Path) -> None:
    run = import_paper(write_logs(tmp_path / "logs", [0.0] * 6, [0.0] * 6, stamps="wall"), SUITE, "cartpole",
                       tmp_path / "run")
    m = manifest(run)
    assert m["time"]["clock"] == "wall-clock"
    first = m["scenarios"][0]
    assert first["timing"]["origin"] == "wall-clock"  # not "simulation": the stamps start at 0 but jitter
    clock = first["timing"]["clock"]
    assert clock["clock"] == "wall-clock" and clock["control_period_s"] == PERIOD
    assert set(clock["common_gaps_ms"]) <= {"31", "47", "62", "63"}
    assert clock["off_period_share"] > 0.5 and clock["max_dt_s"] == pytest.approx(0.0625, abs=1e-4)
    assert any(n.startswith("timing origin: wall-clock") for n in first["notes"])


def test_simulation_stamps_stay_simulation(tmp_path: Path) -> None:
    run = import_paper(write_logs(tmp_path / "logs", [0.0] * 6, [0.0] * 6), SUITE, "cartpole", tmp_path / "run")
    m = manifest(run)
    assert m["time"]["clock"] == "simulation"
    assert all(s["timing"]["origin"] == "simulation" and s["timing"]["clock"]["clock"] == "simulation"
               for s in m["scenarios"])
    # A log written at every 8 ms basic step is regular too, though its gaps are not whole control periods.
    assert gap_statistics(np.arange(1, 200) * 0.008, PERIOD)["clock"] == "simulation"
    # One dropped line is not a clock.
    t = np.delete(np.arange(1, 200) * PERIOD, 50)
    assert gap_statistics(t, PERIOD)["clock"] == "simulation"


def test_terminal_compare_and_analyze_say_the_state_carried_over(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin.cli import main

    reset = tmp_path / "reset_run"
    carried = tmp_path / "carried_run"
    ends = [0.0, -0.153, 1.81, 1.9, 0.0, 0.0]
    logs_a = write_logs(tmp_path / "a", [0.0] * 6, ends)
    logs_b = write_logs(tmp_path / "b", [0.0, 0.0, -0.153, 1.81, 0.0, 0.0], ends, stamps="wall")
    assert main(["import", "paper", str(logs_a), "--scenarios", str(SUITE), "--robot", "cartpole",
                 "--out", str(reset)]) == 0
    assert "carried over" not in capsys.readouterr().out  # control
    assert main(["import", "paper", str(logs_b), "--scenarios", str(SUITE), "--robot", "cartpole",
                 "--out", str(carried)]) == 0
    out = capsys.readouterr().out
    assert "starts where 01_Step_Response_2 ended (cart_pos_m -0.153 m instead of 0): state carried over" in out
    assert "timing origin: wall-clock" in out
    assert main(["compare", "--reference-run", str(reset), "--target-run", str(carried),
                 "--out", str(tmp_path / "cmp")]) == 0
    out = capsys.readouterr().out
    assert "run B (carried_run): scenario 02_Step_Response_3 starts where 01_Step_Response_2 ended" in out
    # Two recordings are labelled by their folders' names, not "recorded (A)"/"recorded (B)".
    assert "reset_run (recorded)" in out and "carried_run (recorded)" in out and "recorded (A)" not in out
    metrics = json.loads((tmp_path / "cmp" / "metrics.json").read_text())["comparison"]
    assert any("state carried over" in n for n in metrics["data_notes"])
    third = next(s for s in metrics["scenarios"] if s["id"] == "02_Step_Response_3")
    assert "B: scenario 02_Step_Response_3 starts where" in third["note"]
    assert main(["analyze", "--reference-run", str(reset), "--target-run", str(carried),
                 "--out", str(tmp_path / "an")]) == 0
    analysis = json.loads((tmp_path / "an" / "analysis.json").read_text())
    assert any("state carried over" in n for n in analysis["notes"])
