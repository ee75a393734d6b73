"""Well-formed but semantically mutated inputs (found by a seeded mutation fuzz of the files the project itself
writes: run folders, recordings, mappings): each is exit code 2 and one ``error:`` line naming the file, never a
traceback, a silent success or a folder left behind -- the promise of docs/getting-started.md ("The promise").

Each case here is one the fuzz found breaking that promise, reduced to the smallest input that shows it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from dualtwin.cli import main
from tests.support.rundirs import cartpole_like, fabricate_run


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[str]]:
    capsys.readouterr()
    code = main(list(argv))
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    return code, [line for line in err.splitlines() if line.strip()]


def two_runs(tmp_path: Path) -> tuple[Path, Path]:
    t = np.arange(1, 33) * 0.032
    return (fabricate_run(tmp_path / "ref", {"00_fall": cartpole_like(t)}),
            fabricate_run(tmp_path / "tgt", {"00_fall": cartpole_like(t, gain=1.1)}))


def rewrite_line(path: Path, lineno: int, time_cell: str) -> None:
    """Replace the time stamp of line ``lineno`` (1-based, the header is line 1)."""
    lines = path.read_text().splitlines()
    cells = lines[lineno - 1].split("\t")
    cells[0] = time_cell
    lines[lineno - 1] = "\t".join(cells)
    path.write_text("\n".join(lines) + "\n")


def assert_one_error(code: int, lines: list[str], *expected: str) -> None:
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), lines
    for text in expected:
        assert text in lines[0], lines


# ------------------------------------------------------------------ run logs
# Every writer of run logs stamps rows on a clock that only moves forward (the runner: k * control period; the
# importers refuse stamps that do not increase). A NaN stamp used to pass silently into the metrics (compare
# exited 0 with NaN-derived numbers); a repeated or backward stamp was refused only by the metric, as "series A:
# time must be strictly increasing", naming neither the run nor the file.
@pytest.mark.parametrize(("cell", "message"), [
    ("nan", "ground_truth.tsv:4: time_s nan is not a finite number"),
    ("inf", "ground_truth.tsv:4: time_s inf is not a finite number"),
    # line 4 repeats line 3's stamp (row 2: 2 * 0.032 = 0.064 s)
    ("0.064", "ground_truth.tsv:4: time_s must increase: 0.064 s after 0.064 s"),
    ("-5", "ground_truth.tsv:4: time_s must increase: -5.0 s after 0.064 s"),
])
def test_a_run_log_time_stamp_that_is_not_finite_or_does_not_increase(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], cell: str, message: str) -> None:
    ref, tgt = two_runs(tmp_path)
    rewrite_line(ref / "scenarios/00_fall/ground_truth.tsv", 4, cell)
    code, lines = run_cli(capsys, "compare", "--reference-run", str(ref), "--target-run", str(tgt),
                          "--out", str(tmp_path / "report"))
    assert_one_error(code, lines, message, str(ref))
    assert not (tmp_path / "report").exists()


def test_a_run_log_with_bytes_that_are_not_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Was a UnicodeDecodeError traceback (compare) or a line naming no file (analyze)."""
    ref, tgt = two_runs(tmp_path)
    log = ref / "scenarios/00_fall/ground_truth.tsv"
    data = log.read_bytes()
    log.write_bytes(data[:40] + b"\xff\xfe" + data[40:])
    for command in ("compare", "analyze"):
        code, lines = run_cli(capsys, command, "--reference-run", str(ref), "--target-run", str(tgt),
                              "--out", str(tmp_path / command))
        assert_one_error(code, lines, f"{log}: not a UTF-8 text run log (binary data at byte 40)")
        assert not (tmp_path / command).exists()


# ------------------------------------------------------------------ symbolic link loops
# Python 3.11's Path.resolve() raises RuntimeError("Symlink loop ...") where a link leads back to itself: every
# confinement check of a path read from a document (a manifest's logs, a mapping's files) was a traceback.
def self_link(path: Path) -> Path:
    path.unlink(missing_ok=True)
    os.symlink(path.name, path)
    return path


def test_a_run_log_that_links_to_itself(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ref, tgt = two_runs(tmp_path)
    log = self_link(ref / "scenarios/00_fall/onboard.tsv")
    code, lines = run_cli(capsys, "compare", "--reference-run", str(ref), "--target-run", str(tgt),
                          "--out", str(tmp_path / "report"))
    assert_one_error(code, lines, f"{log}: a symbolic link loop")
    assert not (tmp_path / "report").exists()


def test_a_log_record_of_the_manifest_that_links_to_itself(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The manifest's ``logs`` records are verified (row count, SHA-256) before anything is read."""
    ref, tgt = two_runs(tmp_path)
    manifest = json.loads((ref / "manifest.json").read_text())
    manifest["logs"] = {"scenarios/00_fall/extra.tsv": {"rows": 1, "sha256": "0" * 64}}
    (ref / "manifest.json").write_text(json.dumps(manifest))
    log = self_link(ref / "scenarios/00_fall/extra.tsv")
    code, lines = run_cli(capsys, "analyze", "--reference-run", str(ref), "--target-run", str(tgt),
                          "--out", str(tmp_path / "analysis"))
    assert_one_error(code, lines, f"{log}: a symbolic link loop")
    assert not (tmp_path / "analysis").exists()


def test_a_recording_that_links_to_itself(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(yaml.safe_dump({"files": [f"log_{i}.csv" for i in range(6)],
                                       "time": {"column": "t", "unit": "s"},
                                       "channels": [{"name": "pole_angle_rad", "column": "a", "unit": "rad"}]}))
    log = self_link(tmp_path / "log_0.csv")
    code, lines = run_cli(capsys, "import", "table", str(mapping), "--scenarios", "cartpole", "--robot",
                          "cartpole", "--out", str(tmp_path / "run"))
    assert_one_error(code, lines, f"{log}: a symbolic link loop")
    assert not (tmp_path / "run").exists()


# ------------------------------------------------------------------ aligned knobs and DR ranges for training
# align writes knobs.json and dr_ranges.json with at least one knob (it fits at least one). A file whose knobs
# are all gone trained "aligned" or "with DR" in the nominal twin, exit 0, while the run recorded the file.
TRAIN = ("train", "--env", "dualtwin/CartPole-MuJoCo-Continuous-v0", "--steps", "64")
KNOBS = {"schema": "dualtwin.knobs/1", "twin": "mujoco", "robot": "cartpole", "values": {},
         "knobs": {"joint.pole_hinge.damping": {"nominal": 0.0, "fitted": 0.01}}}


@pytest.mark.parametrize(("option", "document", "message"), [
    ("--aligned", {**KNOBS, "knobs": {}}, "names no knob"),
    ("--aligned", {}, "names no knob"),
    # without its 'knobs' the file was read as a plain {name: value} mapping: "knob 'schema' needs a number"
    ("--aligned", {key: value for key, value in KNOBS.items() if key != "knobs"},
     "'knobs' must be an object of knob records, got None"),
    ("--dr", {"schema": "dualtwin.dr/1", "knobs": {}}, "knobs: Dictionary should have at least 1 item"),
])
def test_training_from_a_file_that_names_no_knob(tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str,
                                                 document: dict[str, object], message: str) -> None:
    path = tmp_path / "knobs.json"
    path.write_text(json.dumps(document))
    code, lines = run_cli(capsys, *TRAIN, option, str(path), "--out", str(tmp_path / "run"))
    assert_one_error(code, lines, str(path), message)
    assert not (tmp_path / "run").exists()


def test_training_with_a_dr_range_outside_the_knobs_bounds(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The bounds were checked only where the environment workers build their envs: inside a subprocess, after
    the run folder existed, as the worker's traceback. A damping below 0 is outside every twin's bounds."""
    path = tmp_path / "dr_ranges.json"
    path.write_text(json.dumps({"schema": "dualtwin.dr/1", "knobs": {
        "joint.pole_hinge.damping": {"nominal": 0.0, "fitted": 0.0, "low": -1, "high": 0.01}}}))
    code, lines = run_cli(capsys, *TRAIN, "--dr", str(path), "--out", str(tmp_path / "run"))
    assert_one_error(code, lines, str(path), "range of 'joint.pole_hinge.damping' [-1, 0.01] leaves the knob's bounds")
    assert not (tmp_path / "run").exists()


# ------------------------------------------------------------------ align's inputs
def align_args(tmp_path: Path, *extra: str) -> list[str]:
    suite = tmp_path / "suite.json"
    suite.write_text('{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1}]}')
    return ["align", "--reference", "webots", "--target", "mujoco", "--robot", "cartpole", "--scenarios", str(suite),
            "--budget", "6", "--executor", "serial", "--out", str(tmp_path / "aligned"), *extra]


SYSID = {"joint.pole_hinge.damping": {"name": "joint.pole_hinge.damping", "nominal": [0.0], "min_value": [0.0],
                                      "max_value": [1.0], "value": [0.0], "frozen": False}}


@pytest.mark.parametrize(("name", "message"), [
    # a name that is no knob was refused as "twin 'mujoco': knob 'no.such.knob' matches no knob", naming no file
    ("no.such.knob", "twin 'mujoco': knob 'no.such.knob' matches no knob of the twin"),
    # a number was turned into the text of its digits, then refused as a knob name, again naming no file
    (10**30, "parameter 'joint.pole_hinge.damping': name must be a knob name or glob, got 10000"),
])
def test_a_sysid_parameter_whose_name_is_no_knob(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 name: object, message: str) -> None:
    path = tmp_path / "sysid.yaml"
    path.write_text(yaml.safe_dump({key: {**entry, "name": name} for key, entry in SYSID.items()}))
    code, lines = run_cli(capsys, *align_args(tmp_path, "--sysid-params", str(path)))
    assert_one_error(code, lines, f"{path}: ", message)
    assert not (tmp_path / "aligned").exists()


def test_align_thresholds_for_a_channel_that_is_not_fitted(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The objective resolved the thresholds after align_config.json was written: the folder was left behind."""
    code, lines = run_cli(capsys, *align_args(tmp_path, "--knobs", "joint.pole_hinge.damping",
                                              "--thresholds", "no_such_channel=1"))
    assert_one_error(code, lines, "thresholds given for unknown channels ['no_such_channel']")
    assert not (tmp_path / "aligned").exists()


def test_resuming_from_a_checkpoint_whose_incumbent_has_another_residual_length(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A checkpointed point went back into the cache unchecked: a residual one entry longer than the objective's
    was resumed from (exit 0 here; where the incumbent was the fitted point, the fuzz got a NumPy broadcasting
    traceback from the interval estimate's finite differences)."""
    args = align_args(tmp_path, "--knobs", "joint.pole_hinge.damping")
    args[args.index("--budget") + 1] = "12"  # CMA needs a generation or two to checkpoint an incumbent
    code, lines = run_cli(capsys, *args)
    assert code == 0, lines
    checkpoint = tmp_path / "aligned" / "checkpoint.json"
    state = json.loads(checkpoint.read_text())
    state["incumbent"]["residual"].append(0.0)
    checkpoint.write_text(json.dumps(state))
    code, lines = run_cli(capsys, *args, "--resume")
    assert_one_error(code, lines, f"{checkpoint}: damaged CMA checkpoint", "is not a finite vector of")


# ------------------------------------------------------------------ robot bindings
def binding_with_model(tmp_path: Path, model: str) -> Path:
    from dualtwin.robots.binding import BUNDLED

    document = yaml.safe_load((BUNDLED / "cartpole" / "binding.yaml").read_text())
    document["twins"]["mujoco"]["model"] = model
    path = tmp_path / "binding.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def test_a_binding_whose_model_links_to_itself(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    binding = binding_with_model(tmp_path, "model.xml")
    link = self_link(tmp_path / "model.xml")
    code, lines = run_cli(capsys, "suite", "validate", "--scenarios", "cartpole", "--robot", str(binding))
    assert_one_error(code, lines, f"{link}: a symbolic link loop")


def test_a_binding_whose_model_has_no_extension(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """MuJoCo chooses its decoder by the extension; without one it printed "MuJoCo warning: Must provide
    extension or content_type" twice on stderr (from C, hence capfd) before the error line."""
    from dualtwin.robots.binding import BUNDLED

    (tmp_path / "cartpole").write_bytes((BUNDLED / "cartpole" / "cartpole.xml").read_bytes())
    binding = binding_with_model(tmp_path, "cartpole")
    code, lines = run_cli(capfd, "suite", "run", "--twin", "mujoco", "--robot", str(binding), "--scenarios",
                          "cartpole", "--out", str(tmp_path / "run"))
    assert_one_error(code, lines, f"{tmp_path / 'cartpole'}: a model file needs its extension (.xml)")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("value", ["0", "-1"])
def test_align_thresholds_that_are_not_positive(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                value: str) -> None:
    """A crossing threshold is a level |y| crosses (divergence.metrics.Threshold, mode 'abs'): 0 or below was
    Threshold's ValueError inside the objective, a traceback."""
    code, lines = run_cli(capsys, *align_args(tmp_path, "--knobs", "joint.pole_hinge.damping",
                                              "--thresholds", f"pole_angle_rad={value}"))
    assert_one_error(code, lines, "--thresholds pole_angle_rad: Input should be greater than 0")
    assert not (tmp_path / "aligned").exists()


# ------------------------------------------------------------------ recordings
def test_a_recorded_time_stamp_beyond_any_clock(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A last stamp of 1e308 s still increases, so it passed the import's checks; resampling overflowed to inf
    (several numpy warnings) and the manifest's JSON could not hold it: a ValueError traceback."""
    from tests.support.paper_logs import SUITE, write_logs

    logs = write_logs(tmp_path / "logs", starts=[0.0] * 6, ends=[0.1] * 6)
    log = logs / "simulation_log_SUP_0.tsv"
    lines = log.read_text().splitlines()
    lines[-1] = "1e308\t" + lines[-1].split("\t", 1)[1]
    log.write_text("\n".join(lines) + "\n")
    code, err = run_cli(capsys, "import", "paper", str(logs), "--scenarios", str(SUITE), "--robot", "cartpole",
                        "--out", str(tmp_path / "run"))
    # the logs are read (progress lines) before they are judged: the error is the one error line, the last
    # (tests/test_cli_robust.py holds the same for values)
    errors = [line for line in err if line.startswith("error:")]
    assert code == 2 and len(errors) == 1 and err[-1] == errors[0], err
    assert f"{log}:{len(lines)}: time stamp 1e+308 s is beyond ±9.2e+09 s" in errors[0], err
    assert not (tmp_path / "run").exists()
