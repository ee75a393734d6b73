"""Tables stay complete when piped, never cut on a terminal, and ``--json`` keeps stdout clean (issue 14)."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from dualtwin.reporting import Column, ProgressEvent, fmt, print_table, report_progress


def dualtwin(*args: str) -> subprocess.CompletedProcess[str]:
    """The real CLI with stdout and stderr piped (not a terminal), as in CI logs and shell pipes."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "COLUMNS": "80"}
    return subprocess.run([sys.executable, "-m", "dualtwin.cli", *args], capture_output=True, text=True, env=env,
                          timeout=120, check=False)


def test_piped_compare_prints_every_number_and_name_whole(twin_runs: tuple[Path, Path], tmp_path: Path) -> None:
    webots, mujoco = twin_runs
    done = dualtwin("compare", "--reference-run", str(webots), "--target-run", str(mujoco),
                    "--out", str(tmp_path / "cmp"))
    assert done.returncode == 0, done.stderr
    assert "…" not in done.stdout and "Traceback" not in done.stderr
    metrics = json.loads((tmp_path / "cmp" / "metrics.json").read_text())["comparison"]
    lines = done.stdout.splitlines()
    checked = 0
    for scenario in metrics["scenarios"]:
        for channel, values in scenario["channels"].items():
            row = [line for line in lines if line.startswith(scenario["id"] + " ") and f" {channel} " in line]
            assert len(row) == 1, (scenario["id"], channel)
            for key in ("rmse", "dtw_rms", "score"):
                assert f" {fmt(values[key])}" in row[0], (key, row[0])
                checked += 1
    assert checked >= 30
    # Twin names from the manifests, not the folder name both runs share.
    assert "Divergence: webots vs mujoco" in done.stdout
    # Progress went to stderr, one line per stage.
    assert "compare: 1/1" in done.stderr and "report: 2/2" in done.stderr


def cli(*args: str) -> tuple[int, str, str]:
    """The typer app in process, stdout and stderr captured separately (neither is a terminal)."""
    from typer.testing import CliRunner

    from dualtwin.cli import app

    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_json_output_is_the_only_thing_on_stdout(twin_runs: tuple[Path, Path], tmp_path: Path) -> None:
    webots, mujoco = twin_runs
    code, out, err = cli("compare", "--reference-run", str(webots), "--target-run", str(mujoco),
                         "--out", str(tmp_path / "cmp"), "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["twin_a"] == "webots" and len(data["scenarios"]) == 2
    assert "report: 2/2" in err


def test_piped_lockstep_table_and_json(suite_file: Path, tmp_path: Path) -> None:
    code, out, err = cli("lockstep", "--robot", "cartpole", "--scenarios", str(suite_file), "--out",
                         str(tmp_path / "ls"))
    assert code == 0, err
    assert "…" not in out
    assert "00_a_rather_long_scenario_name_that_tables_must_keep_whole" in out
    manifest = json.loads((tmp_path / "ls" / "manifest.json").read_text())
    for episode in manifest["episodes"]:
        assert f"{episode['mean_error']:.4g}" in out
    code, out, err = cli("lockstep", "--robot", "cartpole", "--scenarios", str(suite_file), "--out",
                         str(tmp_path / "ls2"), "--json")
    assert code == 0, err
    assert json.loads(out)["manifest"]["episodes"][0]["id"].startswith("00_a_rather_long")


LONG = "joint.a_very_long_knob_or_channel_name_that_must_not_be_cut.damping"
ROWS = [[LONG, "0.0001234567", "-12345.678"], ["short", "1", "2"], None, ["x" * 90, "3.14159", "2.71828"]]
COLUMNS = [Column("name", False), Column("value"), Column("lag [s]")]


def test_plain_table_off_a_terminal_is_complete_and_unwrapped() -> None:
    out = io.StringIO()
    console = Console(file=out, width=40, force_terminal=False)
    print_table(console, COLUMNS, ROWS, title="t")
    text = out.getvalue()
    lines = text.splitlines()
    assert "…" not in text
    assert any(line.startswith(LONG) and line.rstrip().endswith("-12345.678") for line in lines)
    assert any(line.startswith("x" * 90) for line in lines)
    assert len(lines) == 1 + 2 + 3  # title, header, rule, rows: nothing wrapped onto extra lines


@pytest.mark.parametrize("width", [200, 60])
def test_terminal_table_folds_instead_of_cutting(width: int) -> None:
    out = io.StringIO()
    console = Console(file=out, width=width, force_terminal=True, color_system=None)
    print_table(console, COLUMNS, ROWS)
    text = out.getvalue()
    assert "…" not in text
    assert "lag [s]" in text  # titles are plain text, not rich markup ("[s]" is strike-through markup)
    # Numbers are never folded or cut, even when the terminal is narrower than the table (it wraps then).
    for cell in ("0.0001234567", "-12345.678", "3.14159", "2.71828"):
        assert cell in text
    if width == 200:
        assert LONG in text
    # Names fold: the first column, read down, holds every name whole.
    first = "".join(line.split("│")[1].strip() for line in text.splitlines() if line.startswith("│"))
    assert LONG in first and "x" * 90 in first


def test_progress_off_a_terminal_is_one_line_per_event() -> None:
    out = io.StringIO()
    with report_progress(out) as progress:
        progress(ProgressEvent("perception train", 1, 3, "loss 0.5"))
        progress(ProgressEvent("perception train", 2, 3, "loss 0.4"))
    assert out.getvalue().splitlines() == ["perception train: 1/3 loss 0.5", "perception train: 2/3 loss 0.4"]


@pytest.mark.parametrize("command", ["compare", "analyze", "align", "transfer", "lockstep", "predict-error",
                                     "suite run", "perception eval"])
def test_every_command_that_prints_results_has_json(command: str) -> None:
    import typer

    from dualtwin.cli import app

    group = typer.main.get_command(app)
    for part in command.split():
        group = group.commands[part]  # type: ignore[attr-defined]
    assert any("--json" in p.opts for p in group.params), command
