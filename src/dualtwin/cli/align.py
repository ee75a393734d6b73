"""``dualtwin align``: fit one twin's knobs to a reference.

Its options are :class:`dualtwin.align.AlignConfig`'s fields (:mod:`dualtwin.cli.model_options`), plus what
is not a setting of the fit: where to write (``--out``), ``--reference-run`` (a run folder, where
``--reference`` names a twin), ``--resume``, ``--llm`` and ``--json``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from dualtwin.align.config import AlignConfig
from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import (
    JsonOutput,
    OutOption,
    Twin,
    app,
    console,
    llm_proposer,
    on_interrupt,
    report_progress,
    resumable,
)
from dualtwin.cli.model_options import model_options, validate_model
from dualtwin.errors import DualtwinError
from dualtwin.reporting import ProgressEvent, emit_json


@app.command("align")
@resumable
@model_options(AlignConfig, optional={"reference"},
               choices={"reference": [t.value for t in Twin], "target": [t.value for t in Twin]})
def align(
    *,
    fields: dict[str, Any],
    out: Annotated[Path, OutOption("output directory")],
    reference_run: Annotated[Path | None, typer.Option(help="reference: a recorded or earlier run folder "
                                                            "(manifest.json), instead of --reference")] = None,
    resume: Annotated[bool, typer.Option(help="continue from the last checkpoint in OUT")] = False,
    llm: Annotated[bool, typer.Option(help="ask the configured LLM to explain the findings and propose starting "
                                           "knob values; proposals are kept only if they lower the objective")]
    = False,
    json_out: JsonOutput = False,
) -> None:
    """Fit the target twin's knobs to the reference; write knobs, DR ranges, patched model and report."""
    from dualtwin.align import print_result, run_align

    reference = fields.get("reference")
    # Explicit, so a folder that happens to be named like a twin never changes what --reference means.
    if (reference is None) == (reference_run is None):
        raise DualtwinError("give exactly one of --reference TWIN or --reference-run RUN_DIR")
    if reference is not None:
        from dualtwin.twins import TWINS

        if reference not in TWINS:
            raise DualtwinError(f"--reference must name a twin ({', '.join(sorted(TWINS))}), not {reference!r}; "
                                "for a run folder use --reference-run")
    config = validate_model(AlignConfig, {**fields, "reference": reference or str(reference_run)})
    check_output_dir(out, "align", resume=resume, resumable=True)
    if config.executor == "ray" and config.ray_address:
        from dualtwin.parallel import check_ray_address

        check_ray_address(config.ray_address, "--ray-address")  # seconds, not Ray's minutes of retries
    on_interrupt(lambda: "resume with --resume" if any(out.glob("*checkpoint*")) else "")
    if reference_run is not None:
        from dualtwin.divergence.runs import load_run

        load_run(reference_run)  # a folder that is not a run is one line, here
    propose_fn = llm_proposer(config.reference, config.target) if llm else None
    with report_progress() as progress:
        best = [float("inf")]

        def on_generation(info: Any) -> None:
            # One event per CMA generation / least-squares iteration: evaluations so far and the best objective
            # seen (least squares reports its current iterate, which can be worse than an earlier one).
            best[0] = min(best[0], float(info.best_value))
            progress(ProgressEvent("align", int(info.evaluations), config.budget,
                                   f"iteration {info.iteration}, best objective so far {best[0]:.4g}"))

        result = run_align(config, out, resume=resume, propose_fn=propose_fn, callback=on_generation)
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
            "excluded": dict(getattr(result, "excluded", None) or {}),
            "beyond_floor": dict((getattr(result, "floor_check", None) or {}).get("beyond", {})),
            "warnings": list(result.warnings), "files": dict(result.files)}
