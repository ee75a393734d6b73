"""The synchronisation report: prediction curves, drift over time, alarms and re-alignments."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dualtwin.divergence.prediction import prediction_error
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.sync import Monitor, MonitorConfig, run_lockstep, write_sync_report

DAMPING = "joint.pole_hinge.damping"


def test_report_from_lockstep_prediction_and_events(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    before = prediction_error("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "before",
                              primary_knobs={DAMPING: 0.1}, horizons=(1, 5))
    prediction_error("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "after",
                             primary_knobs={DAMPING: 0.1}, secondary_knobs={DAMPING: 0.09}, horizons=(1, 5))
    with Monitor(MonitorConfig(window=5, high=0.01, low=0.005, persist=1)) as monitor:
        lockstep = run_lockstep("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "ls",
                                resync="every:10", primary_knobs={DAMPING: 0.1}, monitor=monitor)
    path = write_sync_report(tmp_path / "report", lockstep=lockstep, prediction=[("before", before), ("after", tmp_path / "after")])
    page = path.read_text()
    for text in ("Short-horizon prediction error", "Drift over time", "Alarms and re-alignments", "alarm_raised",
                 "00_fall", "every:10", "joint/pole_hinge/qd"):
        assert text in page, text
    assert page.count("data:image/png;base64,") == 2
    record = json.loads((tmp_path / "report" / "report.json").read_text())
    assert record["prediction"]["after"]["1"] < record["prediction"]["before"]["1"]
    assert [e["episode"] for e in record["lockstep"]["episodes"]] == ["00_fall", "01_sine", "02_drive"]
    assert any(e["event"] == "alarm_raised" for e in record["events"]) and record["windows"]
    # A lockstep folder works as well as the result object.
    assert write_sync_report(tmp_path / "again", lockstep=tmp_path / "ls").is_file()
    with pytest.raises(DualtwinError, match="nothing to report"):
        write_sync_report(tmp_path / "none")
