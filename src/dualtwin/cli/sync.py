"""``dualtwin lockstep`` and ``dualtwin predict-error``: two twins side by side."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import JsonOutput, OutOption, TrustPickles, Twin, app, console
from dualtwin.errors import DualtwinError
from dualtwin.reporting import Column, emit_json, print_table


@app.command("lockstep")
def lockstep(
    robot: Annotated[str, typer.Option(help="bundled robot name or binding file")],
    out: Annotated[Path, OutOption("output directory")],
    reference: Annotated[Twin, typer.Option(help="twin whose state is the reference")] = Twin.webots,
    target: Annotated[Twin, typer.Option(help="twin re-seated in the reference's state")] = Twin.mujoco,
    scenarios: Annotated[Path | None, typer.Option(help="suite JSON file (commands)")] = None,
    policy: Annotated[Path | None, typer.Option(help="exported policy folder or training run (commands)")] = None,
    resync: Annotated[str, typer.Option(help="never | every:N | threshold:X")] = "never",
    episodes: Annotated[int | None, typer.Option(help="episodes to run with --policy")] = None,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    trust_pickles: TrustPickles = False,
    json_out: JsonOutput = False,
) -> None:
    """Run two twins side by side with the same commands; log the per-period state difference."""
    from dualtwin.sync import run_lockstep, write_sync_report

    if (scenarios is None) == (policy is None):
        raise DualtwinError("give exactly one of --scenarios or --policy")
    check_output_dir(out, "lockstep")
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles):
        result = run_lockstep(reference.value, target.value, robot, out_dir=out, suite=scenarios, policy=policy, resync=resync,
                              seed=seed, episodes=episodes)
    report = write_sync_report(out / "report", lockstep=result)
    if json_out:
        emit_json({"report": str(report), "manifest": result.manifest})
        return
    print_table(console, [Column("episode", False), Column("status", False), Column("periods"), Column("re-syncs"),
                          Column("mean normalised error"), Column("max normalised error")],
                [[e.id, e.status, str(e.steps), str(e.resyncs), f"{e.mean_error:.4g}", f"{e.max_error:.4g}"]
                 for e in result.episodes])
    console.print(f"report: {report}")


@app.command("predict-error")
def predict_error(
    robot: Annotated[str, typer.Option(help="bundled robot name or binding file")],
    scenarios: Annotated[Path, typer.Option(help="suite JSON file")],
    out: Annotated[Path, OutOption("output directory")],
    reference: Annotated[Twin, typer.Option(help="reference twin")] = Twin.webots,
    target: Annotated[Twin, typer.Option(help="predicting twin")] = Twin.mujoco,
    horizons: Annotated[list[int], typer.Option(help="horizon in control periods (repeatable)")] = [1, 5, 25],  # noqa: B006
    stride: Annotated[int, typer.Option(help="periods between synchronised start states")] = 5,
    json_out: JsonOutput = False,
) -> None:
    """Short-horizon prediction error from synchronised states: the chaos-insensitive model mismatch."""
    from dualtwin.divergence.prediction import prediction_error
    from dualtwin.sync import write_sync_report

    horizon_list = list(horizons)  # each >= 1 (cli.policy.OPTION_RANGES)
    check_output_dir(out, "predict-error")
    result = prediction_error(reference.value, target.value, robot, suite=scenarios, out_dir=out,
                              horizons=horizon_list, stride=stride)
    report = write_sync_report(out / "report", prediction=result)
    if json_out:
        emit_json({"report": str(report), "prediction": result.table})
        return
    by_h = result.table.get("by_horizon", {})
    print_table(console, [Column("horizon [periods]"), Column("normalised RMS error")],
                [[str(h), f"{row.get('normalized_rms', float('nan')):.4g}"] for h, row in by_h.items()])
    console.print(f"report: {report}")
