"""``dualtwin align``: fit one twin's knobs to a reference."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import JsonOutput, app, console, int_list, llm_proposer, report_progress
from dualtwin.errors import DualtwinError
from dualtwin.reporting import ProgressEvent, emit_json


@app.command("align")
def align(
    target: Annotated[str, typer.Option(help="twin whose knobs are fitted")],
    robot: Annotated[str, typer.Option(help="bundled robot name or binding file")],
    scenarios: Annotated[Path, typer.Option(help="suite JSON file")],
    knobs: Annotated[list[str], typer.Option(help="knob names or globs (repeat the option)")],
    out: Annotated[Path, typer.Option(help="output directory")],
    reference: Annotated[str | None, typer.Option(help="reference twin (mujoco or webots), run once; always a twin "
                                                       "name, never a folder")] = None,
    reference_run: Annotated[Path | None, typer.Option(help="reference: a recorded or earlier run folder "
                                                            "(manifest.json), instead of --reference")] = None,
    optimizer: Annotated[str, typer.Option(help="cma or lsq")] = "cma",
    holdout: Annotated[list[str] | None, typer.Option(help="scenario ids held out for validation")] = None,
    budget: Annotated[int, typer.Option(help="maximum simulator evaluations")] = 600,
    seed: Annotated[int, typer.Option(help="optimiser seed")] = 0,
    resume: Annotated[bool, typer.Option(help="continue from the last checkpoint in OUT")] = False,
    executor: Annotated[str, typer.Option(help="process (default) or ray")] = "process",
    address: Annotated[str | None, typer.Option(help="Ray cluster address, with --executor ray")] = None,
    objective: Annotated[str, typer.Option(help="trajectory (suite runs) or prediction (short horizons)")]
    = "trajectory",
    horizons: Annotated[str, typer.Option(help="prediction horizons in control periods, e.g. 1,5")] = "1,5",
    ensemble: Annotated[str, typer.Option(help="off, or mean: fit the mean of the reference run's ensemble members "
                                               "(suite run --ensemble) against the target's, same shifts")] = "off",
    llm: Annotated[bool, typer.Option(help="ask the configured LLM to explain the findings and propose starting "
                                           "knob values; proposals are kept only if they lower the objective")]
    = False,
    json_out: JsonOutput = False,
) -> None:
    """Fit the target twin's knobs to the reference; write knobs, DR ranges, patched model and report."""
    from dualtwin.align import align as run_align
    from dualtwin.align import print_result

    if optimizer not in ("cma", "lsq"):
        raise DualtwinError(f"--optimizer must be cma or lsq, not {optimizer!r}")
    if executor not in ("process", "ray"):
        raise DualtwinError(f"--executor must be process or ray, not {executor!r}")
    if objective not in ("trajectory", "prediction"):
        raise DualtwinError(f"--objective must be trajectory or prediction, not {objective!r}")
    if ensemble not in ("off", "mean"):
        raise DualtwinError(f"--ensemble must be off or mean, not {ensemble!r}")
    horizon_list = int_list(horizons, "--horizons")  # checked even when unused, so a typo never passes
    check_output_dir(out, "align", resume=resume, resumable=True)
    # Explicit, so a folder that happens to be named like a twin never changes what --reference means.
    if (reference is None) == (reference_run is None):
        raise DualtwinError("give exactly one of --reference TWIN or --reference-run RUN_DIR")
    if reference is not None:
        from dualtwin.twins import TWINS

        if reference not in TWINS:
            raise DualtwinError(f"--reference must name a twin ({', '.join(sorted(TWINS))}), not {reference!r}; "
                                "for a run folder use --reference-run")
    else:
        from dualtwin.divergence.runs import load_run

        load_run(reference_run)  # type: ignore[arg-type]  # a folder that is not a run is one line, here
    ref: str | Path = reference if reference is not None else reference_run  # type: ignore[assignment]
    extra: dict[str, object] = (
        {"objective": objective, "horizons": horizon_list} if objective == "prediction" else {})
    if ensemble != "off":
        extra["ensemble"] = ensemble
    if llm:
        extra["propose_fn"] = llm_proposer(str(ref), target)
    with report_progress() as progress:
        best = [float("inf")]

        def on_generation(info: Any) -> None:
            # One event per CMA generation / least-squares iteration: evaluations so far and the best objective
            # seen (least squares reports its current iterate, which can be worse than an earlier one).
            best[0] = min(best[0], float(info.best_value))
            progress(ProgressEvent("align", int(info.evaluations), budget,
                                   f"iteration {info.iteration}, best objective so far {best[0]:.4g}"))

        result = run_align(ref, target, robot, scenarios, knobs, out, optimizer=optimizer,  # type: ignore[arg-type]
                           seed=seed, budget=budget, resume=resume, executor=executor,  # type: ignore[arg-type]
                           ray_address=address, holdout=holdout, callback=on_generation,
                           **extra)  # type: ignore[arg-type]
    if json_out:
        emit_json(_align_json(result))
        return
    print_result(result, console)
    from dualtwin.align.narrate import print_narrative

    print_narrative(result.narrative, console)
    console.print(f"wrote {out}")


def _align_json(result: Any) -> dict[str, Any]:
    """What ``align --json`` prints: the fit's summary, knobs and files (the same numbers as the report)."""
    return {"out": str(result.out_dir), "optimizer": result.optimizer, "stop_reason": result.stop_reason,
            "evaluations": result.evaluations, "iterations": result.iterations, "wall_time_s": result.wall_time_s,
            "objective_before": result.objective_before, "objective_after": result.objective_after,
            "holdout_before": result.holdout_before, "holdout_after": result.holdout_after,
            "knobs": {n: k.to_dict() for n, k in result.knobs.items()},
            "nuisance": {n: k.to_dict() for n, k in (getattr(result, "nuisance", None) or {}).items()},
            "left_out": dict(getattr(result, "left_out", None) or {}),
            "warnings": list(result.warnings), "files": dict(result.files)}
