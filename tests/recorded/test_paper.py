"""The paper's TestOrchestrator logs: import, leniency, pairing by index, byte-identical runs, compare."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from dualtwin.divergence.comparison import compare_runs
from dualtwin.divergence.runs import load_run, load_tsv
from dualtwin.errors import DualtwinError
from dualtwin.recorded import import_paper


def _manifest(run: Path) -> dict:
    return json.loads((run / "manifest.json").read_text())


def test_paper_logs_of_a_webots_run_compare_against_the_twin(
        tmp_path: Path, webots_run: Path, mujoco_run: Path, cartpole_suite: Path,
        write_paper_logs: Callable[..., Path]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs", decimals=3, jitter_s=0.002, late_periods=1)
    run = import_paper(logs, cartpole_suite, "cartpole", tmp_path / "imported")

    manifest = _manifest(run)
    assert manifest["kind"] == "recorded" and manifest["format"] == "paper"
    assert set(manifest["channels"]) == {"pole_angle_rad", "cart_pos_m"}
    # 3 decimals are the default resolution of rad and m already: recorded, not raised.
    assert manifest["channels"]["pole_angle_rad"]["recorded_rounding"] == pytest.approx(0.001)
    assert "resolution" not in manifest["channels"]["pole_angle_rad"]
    for source in manifest["sources"]:
        assert source["sha256"] == hashlib.sha256(Path(source["path"]).read_bytes()).hexdigest()
    assert manifest["mapping"]["time"]["column"] == "time_s"
    assert "linear interpolation" in manifest["resampling"]["method"]
    first = manifest["scenarios"][0]
    # Stamps that start at the scenario's start but jitter by 2 ms are not a simulation's: kept, and labelled.
    assert first["timing"]["origin"] == "wall-clock" and first["timing"]["clock"]["clock"] == "wall-clock"
    assert first["timing"]["rounded_to"]["pole_angle_rad"] == pytest.approx(0.001)
    assert first["timing"]["held_before_first_sample"]["pole_angle_rad"] >= 1  # logging started late
    assert all((run / rel).is_file() for sc in manifest["scenarios"] for rel in sc["raw"])

    # The grid is the twin's grid, so the fall of the pole lands where the twin logged it.
    twin = load_run(webots_run)
    imported = load_run(run)
    for entry in twin.scenarios:
        t_twin = twin.series(entry.id)["pole_angle_rad"].t
        t_imp = imported.series(entry.id)["pole_angle_rad"].t
        n = min(t_twin.size, t_imp.size)
        assert n >= t_twin.size - 1
        np.testing.assert_allclose(t_imp[:n], t_twin[:n], atol=1e-9)

    same = compare_runs(webots_run, run)
    other = compare_runs(mujoco_run, run)  # control: a different engine is further from the recording
    assert same.summary_score is not None and other.summary_score is not None
    assert same.summary_score < other.summary_score
    fall = same.scenarios[0].channels["pole_angle_rad"]
    assert fall.crossing_diff_s is not None and abs(fall.crossing_diff_s) <= 0.05
    assert fall.max_abs_error < 0.01  # 3 decimals and 2 ms jitter cost little on the grid


def test_same_logs_give_byte_identical_runs(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                            write_paper_logs: Callable[..., Path],
                                            snapshot: Callable[[Path], dict[str, bytes]]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs")
    a = snapshot(import_paper(logs, cartpole_suite, "cartpole", tmp_path / "a"))
    b = snapshot(import_paper(logs, cartpole_suite, "cartpole", tmp_path / "b"))
    assert a == b
    # Re-importing into its own earlier import replaces it with the same bytes.
    again = snapshot(import_paper(logs, cartpole_suite, "cartpole", tmp_path / "a"))
    assert again == a


def test_wall_clock_short_and_carried_over_logs_are_imported_and_reported(
        tmp_path: Path, webots_run: Path, cartpole_suite: Path, write_paper_logs: Callable[..., Path]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs", wall_clock=True, decimals=None, late_periods=0)
    # Scenario 1 ended early: keep its first 2 s.
    path = logs / "simulation_log_SUP_1.tsv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:63]) + "\n")
    # Scenario 2 starts where scenario 1 left the pole, not at the suite's initial_angle of 1.0 rad.
    path = logs / "simulation_log_SUP_2.tsv"
    header, *rows = path.read_text().splitlines()
    rows = ["\t".join([r.split("\t")[0], "0.4", r.split("\t")[2]]) for r in rows]
    path.write_text("\n".join([header, *rows]) + "\n")

    run = import_paper(logs, cartpole_suite, "cartpole", tmp_path / "run")
    manifest = _manifest(run)
    sc = manifest["scenarios"]
    assert all(s["timing"]["origin"] == "rebased" for s in sc)
    assert sc[0]["timing"]["first_stamp_s"] > 1e9
    assert sc[0]["timing"]["first_sample_s"] == pytest.approx(0.032)  # the orchestrator's first sample
    assert sc[1]["status"] == "completed" and sc[1]["steps"] == 62
    assert any("ended early" in note for note in sc[1]["notes"])
    assert sc[2]["initial_state"]["initial_angle"]["matches"] is False
    assert any("carried over" in note for note in sc[2]["notes"])
    assert "wall-clock" in manifest["time"]["rebased"]
    _, data = load_tsv(run / sc[0]["ground_truth"])
    assert data[0, 0] == pytest.approx(0.032)


def test_threshold_and_nan_give_failed_and_unstable(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                                   write_paper_logs: Callable[..., Path]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs", late_periods=0, jitter_s=0.0)
    path = logs / "simulation_log_SUP_0.tsv"
    header, *rows = path.read_text().splitlines()
    rows[40] = rows[40].split("\t")[0] + "\tnan\t0.0"
    path.write_text("\n".join([header, *rows]) + "\n")
    path = logs / "simulation_log_SUP_4.tsv"
    header, *rows = path.read_text().splitlines()
    rows[20] = rows[20].split("\t")[0] + "\t0.1\t6.0"  # past failure_cart_position_m = 5 m
    path.write_text("\n".join([header, *rows]) + "\n")
    sc = _manifest(import_paper(logs, cartpole_suite, "cartpole", tmp_path / "run"))["scenarios"]
    assert sc[0]["status"] == "unstable" and sc[0]["steps"] == 40
    assert "simulation_log_SUP_0.tsv:42" in sc[0]["failure"]["message"]
    assert sc[4]["status"] == "failed" and sc[4]["failure"]["key"] == "failure_cart_position_m"
    assert sc[4]["steps"] == 21


@pytest.mark.parametrize("case, message", [
    ("missing", "missing simulation_log_SUP_3.tsv"),
    ("extra", "extra simulation_log_SUP_6.tsv"),
    ("twice", "scenario 2 has more than one log"),
])
def test_missing_and_extra_files_are_named(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                           write_paper_logs: Callable[..., Path], case: str, message: str) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs")
    if case == "missing":
        (logs / "simulation_log_SUP_3.tsv").unlink()
    elif case == "extra":
        (logs / "simulation_log_SUP_6.tsv").write_text((logs / "simulation_log_SUP_0.tsv").read_text())
    else:
        (logs / "simulation_log_SUP_02.tsv").write_text((logs / "simulation_log_SUP_2.tsv").read_text())
    (logs / "README.txt").write_text("other files are ignored")
    with pytest.raises(DualtwinError, match=message):
        import_paper(logs, cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("case, message", [
    ("header", r"simulation_log_SUP_2.tsv:1: no column 'cart_pos_m'"),
    ("backwards", r"simulation_log_SUP_2.tsv:11: time stamps must increase"),
    ("nan_time", r"simulation_log_SUP_2.tsv:6: time stamp nan is not a finite number"),
    ("empty", r"simulation_log_SUP_2.tsv: empty file"),
    ("header_only", r"simulation_log_SUP_2.tsv: no data rows"),
    ("cell", r"simulation_log_SUP_2.tsv:8:2: 'abc' is not a number"),
    ("short_row", r"simulation_log_SUP_2.tsv:9: expected 3 cells"),
    ("binary", r"simulation_log_SUP_2.tsv: not a UTF-8 text"),
    ("directory", r"simulation_log_SUP_2.tsv: is a directory"),
])
def test_bad_paper_logs_name_file_and_line(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                           write_paper_logs: Callable[..., Path], case: str, message: str) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs")
    path = logs / "simulation_log_SUP_2.tsv"
    header, *rows = path.read_text().splitlines()
    if case == "header":
        header = "time_s\tpole_angle_rad\tcart_x"
    elif case == "backwards":
        rows[9] = "0.001" + rows[9][rows[9].index("\t"):]
    elif case == "nan_time":
        rows[4] = "nan" + rows[4][rows[4].index("\t"):]
    elif case == "cell":
        rows[6] = rows[6].split("\t")[0] + "\tabc\t0.0"
    elif case == "short_row":
        rows[7] = rows[7].split("\t")[0] + "\t0.0"
    if case == "empty":
        path.write_text("")
    elif case == "header_only":
        path.write_text(header + "\n")
    elif case == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    elif case == "directory":
        path.unlink()
        path.mkdir()
    else:
        path.write_text("\n".join([header, *rows]) + "\n")
    with pytest.raises(DualtwinError, match=message):
        import_paper(logs, cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_output_folder_policy(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                              write_paper_logs: Callable[..., Path]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs")
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(DualtwinError, match="not empty"):
        import_paper(logs, cartpole_suite, "cartpole", foreign)
    assert (foreign / "notes.txt").read_text() == "mine" and len(list(foreign.iterdir())) == 1
    with pytest.raises(DualtwinError, match="holds .*suite-run"):
        import_paper(logs, cartpole_suite, "cartpole", webots_run)
    # An earlier import with a file the import did not write is not replaced.
    run = import_paper(logs, cartpole_suite, "cartpole", tmp_path / "run")
    (run / "my_plot.png").write_bytes(b"user data")
    with pytest.raises(DualtwinError, match="my_plot.png"):
        import_paper(logs, cartpole_suite, "cartpole", run)
    assert (run / "my_plot.png").read_bytes() == b"user data"
    # An empty folder is used; no staging folder is left behind.
    empty = tmp_path / "empty"
    empty.mkdir()
    import_paper(logs, cartpole_suite, "cartpole", empty)
    assert (empty / "manifest.json").is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_robot_without_the_paper_channels_is_refused(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                                      write_paper_logs: Callable[..., Path]) -> None:
    logs = write_paper_logs(webots_run, tmp_path / "logs")
    with pytest.raises(DualtwinError, match="suite|pole_angle_rad"):
        import_paper(logs, cartpole_suite, "pioneer3at", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_cli_journey_import_compare_analyze(tmp_path: Path, webots_run: Path, mujoco_run: Path,
                                            cartpole_suite: Path, write_paper_logs: Callable[..., Path],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin.cli import main

    logs = write_paper_logs(webots_run, tmp_path / "logs")
    real = tmp_path / "real"
    assert main(["import", "paper", str(logs), "--scenarios", str(cartpole_suite), "--robot", "cartpole",
                 "--out", str(real)]) == 0
    assert main(["compare", "--reference-run", str(real), "--target-run", str(mujoco_run),
                 "--out", str(tmp_path / "cmp")]) == 0
    assert main(["analyze", "--reference-run", str(real), "--target-run", str(mujoco_run),
                 "--out", str(tmp_path / "an")]) == 0
    out = capsys.readouterr().out
    assert "left out channel pole_velocity_rad_s" in out
    assert (tmp_path / "cmp" / "report.html").is_file() and (tmp_path / "an" / "analysis.json").is_file()
    metrics = json.loads((tmp_path / "cmp" / "metrics.json").read_text())["comparison"]
    assert {c for s in metrics["scenarios"] for c in s["channels"]} == {"pole_angle_rad", "cart_pos_m"}
    assert metrics["twin_a"] == "recorded" and "pole_velocity_rad_s" in metrics["left_out"]["channels"]
    # A log edited after the import is refused by every reader (the manifest holds its SHA-256).
    log = real / "scenarios" / "00_Step_Response" / "ground_truth.tsv"
    log.write_text(log.read_text().replace("\n0.", "\n1.", 1))
    with pytest.raises(DualtwinError, match="ground_truth.tsv"):
        load_run(real)
    assert main(["import", "paper", str(tmp_path / "nowhere"), "--scenarios", str(cartpole_suite), "--robot",
                 "cartpole", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: ") and "nowhere: does not exist" in err[-1]


def test_align_takes_an_imported_recording_as_reference(tmp_path: Path, webots_run: Path, cartpole_suite: Path,
                                                       write_paper_logs: Callable[..., Path],
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin.cli import main

    real = import_paper(write_paper_logs(webots_run, tmp_path / "logs"), cartpole_suite, "cartpole",
                        tmp_path / "real")
    code = main(["align", "--reference-run", str(real), "--target", "mujoco", "--robot", "cartpole",
                 "--scenarios", str(cartpole_suite), "--knobs", "joint.pole_hinge.damping", "--budget", "4",
                 "--out", str(tmp_path / "aligned")])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "aligned" / "knobs.json").is_file()
    captured = capsys.readouterr()
    assert "not logged by the reference" in captured.out + captured.err  # the twin-only channels, left out
