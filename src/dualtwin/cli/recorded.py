"""``dualtwin import``: recordings as run folders."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer

from dualtwin.cli.common import JsonOutput, OutOption, app, console
from dualtwin.reporting import Column, emit_json, print_table

import_app = typer.Typer(help="Import recordings (the paper's logs, CSV/TSV, ROS 2 bags) as run folders.",
                         no_args_is_help=True)
app.add_typer(import_app, name="import")
ImportSuite = Annotated[Path, typer.Option(help="the suite the recording was made from: a suite JSON file, "
                                                 "or a bundled robot's name for its suite")]
ImportRobot = Annotated[str, typer.Option(help="bundled robot name or path to a binding file")]
ImportOut = Annotated[Path, OutOption("run folder to write (empty, new, or an earlier import)")]


class Invalid(StrEnum):
    """How an import treats values no sensor produces (``dualtwin.recorded.build.INVALID_TREATMENTS``)."""

    error = "error"
    mask = "mask"
    unstable = "unstable"


ImportInvalid = Annotated[Invalid, typer.Option(
    "--invalid", help="values no sensor produces (infinite, or beyond ±1e9 in the binding's unit): error refuses "
    "the log naming file, line and column; mask drops them; unstable ends the scenario there (the manifest "
    "notes say what was done where)")]
ImportDataDir = Annotated[Path | None, typer.Option(help="folder the mapping's file names are relative to "
                                                         "(default: the mapping's folder)")]


def _import_with_progress(run: Any, json_out: bool) -> None:
    import json

    from dualtwin.reporting.progress import report_progress

    with report_progress() as progress:
        out = run(progress)
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    if json_out:
        emit_json({"out": str(out), "manifest": manifest})
        return
    print_table(console, [Column("scenario", False), Column("status", False), Column("samples"),
                          Column("notes", False)],
                [[r["id"], r["status"], r["steps"], "; ".join(r["notes"])] for r in manifest["scenarios"]])
    _print_data_evidence(manifest)
    console.print(f"wrote {out}")


def _print_data_evidence(manifest: dict[str, Any]) -> None:
    """State carried over and wall-clock stamps, each on its own line (the table may be cut to the terminal)."""
    for r in manifest["scenarios"]:
        for part in r.get("state_continuity", {}).values():
            console.print(part["note"], markup=False)
    wall = [r for r in manifest["scenarios"] if r.get("timing", {}).get("clock", {}).get("clock") == "wall-clock"]
    if wall:
        from dualtwin.recorded.clock import clock_note

        console.print(f"{len(wall)} of {len(manifest['scenarios'])} scenario(s): "
                      + clock_note(wall[0]["timing"]["clock"]), markup=False)


@import_app.command("paper")
def import_paper_cmd(
    log_dir: Annotated[Path, typer.Argument(help="folder of simulation_log_SUP_<i>.tsv files")],
    scenarios: ImportSuite, robot: ImportRobot, out: ImportOut, json_out: JsonOutput = False,
    invalid: ImportInvalid = Invalid.error,
) -> None:
    """The paper's TestOrchestrator logs (one TSV per scenario, paired with the suite by index)."""
    from dualtwin.recorded import import_paper

    _import_with_progress(lambda p: import_paper(log_dir, scenarios, robot, out, progress=p,
                                                 invalid=invalid.value), json_out)


@import_app.command("table")
def import_table_cmd(
    mapping: Annotated[Path, typer.Argument(help="YAML mapping: files, time column, channels")],
    scenarios: ImportSuite, robot: ImportRobot, out: ImportOut, data_dir: ImportDataDir = None,
    json_out: JsonOutput = False, invalid: ImportInvalid = Invalid.error,
) -> None:
    """CSV/TSV logs, one file per scenario, described by a YAML mapping."""
    from dualtwin.recorded import import_table

    _import_with_progress(lambda p: import_table(mapping, scenarios, robot, out, data_dir=data_dir, progress=p,
                                                 invalid=invalid.value), json_out)


@import_app.command("mcap")
def import_mcap_cmd(
    mapping: Annotated[Path, typer.Argument(help="YAML mapping: bags, topics and fields, scenario ranges")],
    scenarios: ImportSuite, robot: ImportRobot, out: ImportOut, data_dir: ImportDataDir = None,
    json_out: JsonOutput = False, invalid: ImportInvalid = Invalid.error,
) -> None:
    """ROS 2 bags in MCAP, described by a YAML mapping."""
    from dualtwin.recorded import import_mcap

    _import_with_progress(lambda p: import_mcap(mapping, scenarios, robot, out, data_dir=data_dir, progress=p,
                                                invalid=invalid.value), json_out)
