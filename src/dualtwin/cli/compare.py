"""``dualtwin compare`` and ``dualtwin analyze``: how two runs differ, and why."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import OutOption, Twin, app, check_runs, console, llm_proposer, report_progress
from dualtwin.errors import DualtwinError
from dualtwin.reporting import ProgressEvent, emit_json


@app.command("compare")
def compare(
    reference_run: Annotated[Path, typer.Option(help="run directory of the reference (its twin or recording)")],
    target_run: Annotated[Path, typer.Option(help="run directory of the twin compared with it")],
    out: Annotated[Path, OutOption("report directory")],
    as_json: Annotated[bool, typer.Option("--json", help="print metrics.json's comparison to stdout "
                                                         "instead of the table")] = False,
) -> None:
    """Compare two runs: metrics.json, PNG overlays and a self-contained report.html.

    Only the scenarios and channels both runs have are compared (what one side lacks is listed); with an
    ensemble run (suite run --ensemble) each channel is also judged against the reproducibility floor.
    """
    from dualtwin.divergence import compare_runs, print_summary, write_report

    check_output_dir(out, "compare")
    check_runs(reference_run, target_run)
    with report_progress() as progress:
        progress(ProgressEvent("compare", 0, 1, f"{reference_run} vs {target_run}"))
        comparison = compare_runs(reference_run, target_run)
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
    reference_run: Annotated[Path, typer.Option(help="run directory of the reference")],
    target_run: Annotated[Path, typer.Option(help="run directory of the twin to explain")],
    out: Annotated[Path, OutOption("analysis directory (analysis.json, analysis.html)")],
    robot: Annotated[str | None, typer.Option(help="robot, to compute knob sensitivities by re-simulation")] = None,
    target: Annotated[Twin | None, typer.Option(help="the twin of --target-run, for sensitivities")] = None,
    knobs: Annotated[list[str] | None, typer.Option(help="knob names or globs for sensitivities")] = None,
    llm: Annotated[bool, typer.Option(help="also ask the configured LLM (DUALTWIN_LLM_*) to explain the findings "
                                           "and propose knob changes, each re-simulated")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="print analysis.json to stdout instead of the "
                                                         "findings")] = False,
) -> None:
    """Explain why two runs diverge: dominant scenarios/channels, sign/lag/scale flags, knob sensitivities."""
    from dualtwin.align import analyze_runs, print_analysis, write_analysis

    check_output_dir(out, "analyze")
    if (knobs or target) and robot is None:
        raise DualtwinError("--knobs and --target compute sensitivities by re-simulation: give --robot too")
    check_runs(reference_run, target_run)
    if robot is not None:
        from dualtwin.robots.binding import resolve_robot

        resolve_robot(robot)
    proposer = llm_proposer(reference_run.name, target_run.name) if llm else None
    with report_progress() as progress:
        stage = "analyze" + (" (re-simulating knob sensitivities)" if robot and knobs else "")
        progress(ProgressEvent(stage, 0, 2, f"{reference_run} vs {target_run}"))
        analysis = analyze_runs(reference_run, target_run, robot=robot, twin_b=target.value if target else None, knobs=knobs, propose_fn=proposer)
        _refuse_unreachable_llm(proposer)
        progress(ProgressEvent(stage, 1, 2, "analysed; writing the reports"))
        write_analysis(analysis, out)
        progress(ProgressEvent(stage, 2, 2, "done"))
    if as_json:
        emit_json(analysis.to_dict())
        return
    print_analysis(analysis, console)
    console.print(f"wrote {out}")


def _refuse_unreachable_llm(proposer: object) -> None:
    """--llm asked for the LLM's explanation: when it could not be reached, that is the user's setting to fix
    (exit 2, nothing written), not an analysis without it."""
    error = getattr(getattr(proposer, "narrative", None), "error", None)
    if error and error.startswith("no narrative:"):
        raise DualtwinError(f"--llm: {error.removeprefix('no narrative:').strip()}")
