"""``dualtwin compare`` and ``dualtwin analyze``: how two runs differ, and why."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import app, check_runs, console, llm_proposer, report_progress
from dualtwin.errors import DualtwinError
from dualtwin.reporting import ProgressEvent, emit_json


@app.command("compare")
def compare(
    run_a: Annotated[Path, typer.Argument(help="first run directory")],
    run_b: Annotated[Path, typer.Argument(help="second run directory")],
    out: Annotated[Path, typer.Option(help="report directory")],
    as_json: Annotated[bool, typer.Option("--json", help="print metrics.json's comparison to stdout "
                                                         "instead of the table")] = False,
) -> None:
    """Compare two runs: metrics.json, PNG overlays and a self-contained report.html.

    Only the scenarios and channels both runs have are compared (what one side lacks is listed); with an
    ensemble run (suite run --ensemble) each channel is also judged against the reproducibility floor.
    """
    from dualtwin.divergence import compare_runs, print_summary, write_report

    check_output_dir(out, "compare")
    check_runs(run_a, run_b)
    with report_progress() as progress:
        progress(ProgressEvent("compare", 0, 1, f"{run_a} vs {run_b}"))
        comparison = compare_runs(run_a, run_b)
        progress(ProgressEvent("compare", 1, 1, "runs compared"))
        # Labels are the twins named in the run manifests (folder names repeat).
        write_report(comparison, out, progress=progress)
    if as_json:
        emit_json(comparison.to_dict())
        return
    print_summary(comparison, console)
    for line in comparison.judgement_lines():
        console.print(f"  {line}", markup=False, highlight=False)
    console.print(f"wrote {out / 'report.html'}")


@app.command("analyze")
def analyze(
    run_a: Annotated[Path, typer.Argument(help="reference run directory")],
    run_b: Annotated[Path, typer.Argument(help="run directory of the twin to explain")],
    out: Annotated[Path, typer.Option(help="analysis directory (analysis.json, analysis.html)")],
    robot: Annotated[str | None, typer.Option(help="robot, to compute knob sensitivities by re-simulation")] = None,
    twin: Annotated[str | None, typer.Option(help="the twin of RUN_B, for sensitivities")] = None,
    knobs: Annotated[list[str] | None, typer.Option(help="knob names or globs for sensitivities")] = None,
    llm: Annotated[bool, typer.Option(help="also ask the configured LLM (DUALTWIN_LLM_*) to explain the findings "
                                           "and propose knob changes, each re-simulated")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="print analysis.json to stdout instead of the "
                                                         "findings")] = False,
) -> None:
    """Explain why two runs diverge: dominant scenarios/channels, sign/lag/scale flags, knob sensitivities."""
    from dualtwin.align import analyze_runs, print_analysis, write_analysis

    check_output_dir(out, "analyze")
    if (knobs or twin) and robot is None:
        raise DualtwinError("--knobs and --twin compute sensitivities by re-simulation: give --robot too")
    check_runs(run_a, run_b)
    if robot is not None:
        from dualtwin.robots.binding import resolve_robot

        resolve_robot(robot)
    proposer = llm_proposer(run_a.name, run_b.name) if llm else None
    with report_progress() as progress:
        stage = "analyze" + (" (re-simulating knob sensitivities)" if robot and knobs else "")
        progress(ProgressEvent(stage, 0, 2, f"{run_a} vs {run_b}"))
        analysis = analyze_runs(run_a, run_b, robot=robot, twin_b=twin, knobs=knobs, propose_fn=proposer)
        progress(ProgressEvent(stage, 1, 2, "analysed; writing the reports"))
        write_analysis(analysis, out)
        progress(ProgressEvent(stage, 2, 2, "done"))
    if as_json:
        emit_json(analysis.to_dict())
        return
    print_analysis(analysis, console)
    console.print(f"wrote {out}")
