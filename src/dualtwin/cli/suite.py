"""``dualtwin suite``: validate and run scenario suites."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dualtwin.cli.common import (
    Executor,
    JsonOutput,
    OutOption,
    Twin,
    console,
    on_interrupt,
    report_progress,
    resumable,
    resume_note,
    suite_app,
)
from dualtwin.errors import DualtwinError
from dualtwin.reporting import Column, ProgressEvent, emit_json, print_table


@suite_app.command("validate")
def suite_validate(
    scenarios: Annotated[Path, typer.Option(help="suite JSON file, or a bundled robot's name for its suite")],
    robot: Annotated[str | None, typer.Option(help="also resolve robot-specific keys through this robot")] = None,
) -> None:
    """Check a suite file (and, with --robot, that the binding resolves every key)."""
    from dualtwin.suite.loader import load_suite, resolve_suite

    file = resolve_suite(scenarios)
    suite = load_suite(file)
    if robot is not None:
        from dualtwin.robots.binding import resolve_robot
        from dualtwin.suite.runner import check_against_binding

        check_against_binding(suite, file, resolve_robot(robot))
    console.print(f"[green]ok[/green] {file}: suite {suite.suite_name!r}, {len(suite.scenarios)} scenarios, "
                  f"control period {suite.global_settings.TIME_STEP:g} ms")


@suite_app.command("run")
@resumable
def suite_run(
    twin: Annotated[Twin, typer.Option(help="twin to run on")],
    robot: Annotated[str, typer.Option(help="bundled robot name (cartpole) or path to a binding file")],
    scenarios: Annotated[Path, typer.Option(help="suite JSON file, or a bundled robot's name for its suite")],
    out: Annotated[Path, OutOption("run directory to write")],
    resume: Annotated[bool, typer.Option(help="continue an interrupted run in OUT")] = False,
    seed: Annotated[int, typer.Option(help="seed for scenarios that give none")] = 0,
    ensemble: Annotated[int | None, typer.Option(help="run each scenario N times (N >= 2, the unperturbed member "
                                                      "included) with initial conditions moved by --perturb; "
                                                      "without it, each scenario runs once")] = None,
    perturb: Annotated[list[str] | None, typer.Option(help="KEY=EPS: move initial condition KEY by up to "
                                                           "±EPS in the ensemble members (repeatable)")] = None,
    executor: Annotated[Executor, typer.Option(help="where ensemble members run")] = Executor.process,
    workers: Annotated[int, typer.Option(help="process-pool size for ensemble members")] = 2,
    json_out: JsonOutput = False,
) -> None:
    """Run a suite on one twin, writing on-board and ground-truth logs per scenario (and ensemble members)."""
    # First: a Ctrl-C during the imports below already names what OUT holds (a finished run being resumed).
    on_interrupt(lambda: resume_note(out / "manifest.json", "scenarios", "scenarios"))
    from dualtwin.parallel import check_executor
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.suite.runner import SuiteRun

    try:  # even without --ensemble: ray may be missing
        check_executor(executor.value)
    except DualtwinError as exc:
        raise DualtwinError(f"--executor: {exc}") from None
    twin_name = twin.value
    binding = resolve_robot(robot)
    if ensemble is not None or perturb:
        from dualtwin.suite.ensemble import EnsembleRun, make_spec, parse_perturb

        spec = make_spec(ensemble or 0, parse_perturb(perturb or []), binding, seed=seed)
        members = EnsembleRun(scenarios, twin_name, binding, out, spec, seed=seed,
                              executor=executor.value,  # type: ignore[arg-type]
                              workers=workers)
        label, total, done = f"{twin_name}: {members.suite.suite_name}", len(members.suite.scenarios), [0, 0]
        with report_progress() as progress:
            def on_scenario(sid: str, status: str) -> None:
                done[0] += 1
                progress(ProgressEvent(label, done[0], total, f"{sid} {status}"))

            def on_member(member: int, count: int) -> None:
                done[1] += 1
                progress(ProgressEvent("ensemble members", done[1], count, f"member {member}"))

            manifest = members.run(resume=resume, on_scenario=on_scenario, on_member=on_member)
        if not json_out:
            console.print(f"ensemble: {spec.members} members per scenario, perturbed "
                          + ", ".join(f"{k} by ±{v:g}" for k, v in spec.perturb.items()))
    else:
        run = SuiteRun(scenarios, twin_name, binding, out, seed=seed)
        manifest = _run_with_progress(run, resume, f"{twin_name}: {run.suite.suite_name}")
    if json_out:
        emit_json({"out": str(out), "manifest": manifest})
        return
    print_table(console, [Column("scenario", False), Column("status", False)],
                [[record["id"], record["status"]] for record in manifest["scenarios"]])
    console.print(f"wrote {out}")


def _run_with_progress(run, resume: bool, label: str):  # type: ignore[no-untyped-def]
    total = len(run.suite.scenarios)
    done = [0]
    with report_progress() as progress:
        def on_scenario(sid: str, status: str) -> None:
            done[0] += 1
            progress(ProgressEvent(label, done[0], total, f"{sid} {status}"))

        return run.run(resume=resume, on_scenario=on_scenario)
