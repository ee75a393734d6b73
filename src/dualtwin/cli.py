"""The ``dualtwin`` command line. Thin: every command calls into a package and prints."""

from __future__ import annotations

import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from dualtwin.artifacts import check_output_dir
from dualtwin.errors import DualtwinError
from dualtwin.reporting import (
    Column,
    ProgressEvent,
    configure_console,
    emit_json,
    print_table,
)
from dualtwin.reporting import (
    report_progress as _report_progress,
)


@contextmanager
def report_progress() -> Iterator[Any]:
    """:func:`dualtwin.reporting.report_progress`, holding back each stage's opening (0-done) event until its
    first advance: a command refused while it validates its inputs prints only its one error line."""
    with _report_progress() as show:
        held: dict[str, Any] = {}

        def progress(event: Any) -> None:
            if event.done == 0 and event.stage not in held:
                held[event.stage] = event
                return
            opening = held.get(event.stage)
            if opening is not None:
                held[event.stage] = None
                show(opening)
            show(event)

        yield progress

# Loading a training run written before its statistics were JSON (or by another tool) means unpickling files
# from it, which can run code: only on the user's explicit word.
TrustPickles = Annotated[bool, typer.Option(
    "--trust-pickles", help="allow unpickling a run's legacy vecnormalize.pkl or foreign model entries "
    "(pickles can run code: only for files you trust)")]

app = typer.Typer(help="Dual digital twins (Webots on ODE + MuJoCo) for robotics RL.", no_args_is_help=True,
                  pretty_exceptions_enable=False, add_completion=False)
suite_app = typer.Typer(help="Scenario suites: validate and run.", no_args_is_help=True)
webots_app = typer.Typer(help="The headless Webots runtime.", no_args_is_help=True)
app.add_typer(suite_app, name="suite")
perception_app = typer.Typer(help="Learned perception: train and evaluate.", no_args_is_help=True)
app.add_typer(webots_app, name="webots")
app.add_typer(perception_app, name="perception")
console = configure_console(Console(stderr=False))
#: ``--json``: the results as one JSON document on stdout; progress and messages go to stderr.
JsonOutput = Annotated[bool, typer.Option("--json", help="print the results as JSON on stdout (progress and "
                                                          "messages go to stderr)")]


@app.callback()
def _global_options(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="print setup details (e.g. the OpenGL backend) "
                                                                   "on stderr")] = False,
) -> None:
    if verbose:
        from dualtwin import gl_backend

        print(gl_backend().describe(), file=sys.stderr)


@suite_app.command("validate")
def suite_validate(
    file: Annotated[Path, typer.Argument(help="suite JSON file, or a bundled robot's name for its suite")],
    robot: Annotated[str | None, typer.Option(help="also resolve robot-specific keys through this robot")] = None,
) -> None:
    """Check a suite file (and, with --robot, that the binding resolves every key)."""
    from dualtwin.suite.loader import load_suite, resolve_suite

    file = resolve_suite(file)
    suite = load_suite(file)
    if robot is not None:
        from dualtwin.robots.binding import resolve_robot
        from dualtwin.suite.runner import check_against_binding

        check_against_binding(suite, file, resolve_robot(robot))
    console.print(f"[green]ok[/green] {file}: suite {suite.suite_name!r}, {len(suite.scenarios)} scenarios, "
                  f"control period {suite.global_settings.TIME_STEP:g} ms")


@suite_app.command("run")
def suite_run(
    twin: Annotated[str, typer.Option(help="twin to run on: mujoco or webots")],
    robot: Annotated[str, typer.Option(help="bundled robot name (cartpole) or path to a binding file")],
    scenarios: Annotated[Path, typer.Option(help="suite JSON file")],
    out: Annotated[Path, typer.Option(help="run directory to write")],
    resume: Annotated[bool, typer.Option(help="continue an interrupted run in OUT")] = False,
    seed: Annotated[int, typer.Option(help="seed for scenarios that give none")] = 0,
    ensemble: Annotated[int, typer.Option(help="run each scenario N times (N >= 2, the unperturbed member "
                                               "included) with initial conditions moved by --perturb")] = 0,
    perturb: Annotated[list[str] | None, typer.Option(help="KEY=EPS: move initial condition KEY by up to "
                                                           "±EPS in the ensemble members (repeatable)")] = None,
    executor: Annotated[str, typer.Option(help="where ensemble members run: process, serial or ray")] = "process",
    workers: Annotated[int, typer.Option(help="process-pool size for ensemble members")] = 2,
    json_out: JsonOutput = False,
) -> None:
    """Run a suite on one twin, writing on-board and ground-truth logs per scenario (and ensemble members)."""
    from dualtwin.parallel import check_executor
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.suite.runner import SuiteRun

    try:  # even without --ensemble, so a typo never passes silently
        check_executor(executor)
    except DualtwinError as exc:
        raise DualtwinError(f"--executor: {exc}") from None
    binding = resolve_robot(robot)
    if ensemble or perturb:
        from dualtwin.suite.ensemble import EnsembleRun, make_spec, parse_perturb

        spec = make_spec(ensemble, parse_perturb(perturb or []), binding, seed=seed)
        members = EnsembleRun(scenarios, twin, binding, out, spec, seed=seed, executor=executor,  # type: ignore[arg-type]
                              workers=workers)
        label, total, done = f"{twin}: {members.suite.suite_name}", len(members.suite.scenarios), [0, 0]
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
        run = SuiteRun(scenarios, twin, binding, out, seed=seed)
        manifest = _run_with_progress(run, resume, f"{twin}: {run.suite.suite_name}")
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
    _runs(run_a, run_b)
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
    _runs(run_a, run_b)
    if robot is not None:
        from dualtwin.robots.binding import resolve_robot

        resolve_robot(robot)
    proposer = _llm_proposer(run_a.name, run_b.name) if llm else None
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
    horizon_list = _int_list(horizons, "--horizons")  # checked even when unused, so a typo never passes
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
        extra["propose_fn"] = _llm_proposer(str(ref), target)
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


def _llm_proposer(label_a: str, label_b: str):  # type: ignore[no-untyped-def]
    """The LLM proposer for --llm (the provider is configured by DUALTWIN_LLM_* or DUALTWIN_LLM_CONFIG)."""
    from dualtwin.align.narrate import LLMProposer
    from dualtwin.genai.llm import make_llm

    return LLMProposer(make_llm(), label_a=label_a, label_b=label_b)


@app.command("train")
def train(
    env: Annotated[str, typer.Option(help="registered env id, e.g. dualtwin/CartPole-MuJoCo-Continuous-v0")],
    out: Annotated[Path, typer.Option(help="run folder")],
    config: Annotated[Path | None, typer.Option(
        help="PPO config YAML, or a bundled config's name (ppo_cartpole, ppo_cartpole_text, ppo_cartpole_code, "
        "ppo_cartpole_continuous; default ppo_cartpole)")] = None,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    steps: Annotated[int | None, typer.Option(help="total timesteps (overrides the config)")] = None,
    resume: Annotated[bool, typer.Option(help="continue an interrupted run from its last checkpoint")] = False,
    dr: Annotated[Path | None, typer.Option(help="domain-randomisation ranges (dr_ranges.json from align)")] = None,
    shadow_fraction: Annotated[float, typer.Option(help="share of episodes shadowed in the Webots twin")] = 0.0,
    aligned: Annotated[Path | None, typer.Option(
        help="train in the aligned twin: knobs.json from align --target <this env's twin>")] = None,
    init_from: Annotated[Path | None, typer.Option(
        help="fine-tune: start from this run's best policy and normalisation (same env id)")] = None,
    trust_pickles: TrustPickles = False,
) -> None:
    """Train PPO (Stable-Baselines3) on a twin env; VecNormalize stats are saved with the model."""
    from dualtwin.rl.train import train as run_train

    check_output_dir(out, "train", resume=resume, resumable=True)
    run = run_train(env, config, out, seed=seed, total_timesteps=steps, resume=resume, dr_ranges=dr,
                    shadow_fraction=shadow_fraction, aligned=aligned, init_from=init_from,
                    trust_pickles=trust_pickles, report=lambda line: typer.echo(line, err=True))
    console.print(f"wrote {run}")


@app.command("transfer")
def transfer(
    policy: Annotated[Path, typer.Option(help="run folder of the policy trained in the nominal source twin")],
    target_env: Annotated[str, typer.Option(help="env id of the other twin")],
    out: Annotated[Path, typer.Option(help="report folder")],
    policy_aligned: Annotated[Path | None, typer.Option(
        help="run folder of a policy trained in the aligned source twin (train --aligned knobs.json)")] = None,
    policy_dr: Annotated[Path | None, typer.Option(
        help="run folder of a policy trained with calibrated DR (train --dr dr_ranges.json)")] = None,
    policy_control: Annotated[Path | None, typer.Option(
        help="run folder of the control: the aligned policy's fine-tuning repeated in the nominal twin "
        "(train --init-from POLICY without --aligned)")] = None,
    episodes: Annotated[int, typer.Option(help="episodes per row")] = 10,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    which: Annotated[str, typer.Option(help="best or final model")] = "final",
    trust_pickles: TrustPickles = False,
    json_out: JsonOutput = False,
) -> None:
    """Evaluate policies in their source twin and in the target twin: before and after alignment, with DR (Table 1)."""
    from dualtwin.rl.transfer import transfer as run_transfer

    if which not in ("best", "final"):
        raise DualtwinError(f"--which must be best or final, not {which!r}")
    check_output_dir(out, "transfer")
    from dualtwin.rl import check_env_id

    check_env_id(target_env)
    for option, folder in (("--policy", policy), ("--policy-aligned", policy_aligned), ("--policy-dr", policy_dr),
                           ("--policy-control", policy_control)):
        _training_run(folder, option)
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles), report_progress() as progress:
        progress(ProgressEvent("transfer", 0, None, f"{episodes} episodes per row, in the source and target twins"))
        report = run_transfer(policy, target_env, policy_aligned=policy_aligned, policy_dr=policy_dr,
                              policy_control=policy_control, episodes=episodes, seed=seed, out_dir=out, which=which)
        progress(ProgressEvent("transfer", len(report.rows), len(report.rows), "rows evaluated"))
    if json_out:
        emit_json({"out": str(out), **report.to_dict()})
        return
    print_table(console, [Column("row", False), Column("result", False)],
                [[row.label, row.summary()] for row in report.rows])
    console.print(f"wrote {out}")


@app.command("export")
def export(
    policy: Annotated[Path, typer.Option(help="training run folder")],
    out: Annotated[Path, typer.Option(help="export folder (policy.onnx, policy_contract.json)")],
    which: Annotated[str, typer.Option(help="best or final model")] = "final",
    trust_pickles: TrustPickles = False,
    camera_only: Annotated[bool, typer.Option(
        help="write a camera-only contract: wheel odometry on board, the rest from --perception")] = False,
    perception: Annotated[Path | None, typer.Option(help="perception model folder, for --camera-only")] = None,
) -> None:
    """Export a policy to ONNX with observation normalisation and action scaling inside the graph."""
    from dualtwin.rl.export import export_policy

    if which not in ("best", "final"):
        raise DualtwinError(f"--which must be best or final, not {which!r}")
    if camera_only != (perception is not None):
        raise DualtwinError("--camera-only and --perception go together")
    if perception is not None:
        from dualtwin.perception.estimator import StateEstimator

        StateEstimator.load(perception)  # a bad model folder fails before anything is written
    check_output_dir(out, "export")
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles):
        path = export_policy(policy, out, which=which)  # type: ignore[arg-type]
    if perception is not None:
        from dualtwin.perception.camera_only import export_camera_only

        export_camera_only(out, perception, out)
    console.print(f"wrote {path}")


@app.command("collect")
def collect(
    env: Annotated[str, typer.Option(help="registered env id whose twin renders the frames")],
    episodes: Annotated[int, typer.Option(help="episodes in the finished dataset")],
    out: Annotated[Path, typer.Option(help="dataset folder (shards + manifest.json)")],
    controller: Annotated[str, typer.Option(help="scripted, random or noisy-policy")] = "scripted",
    policy: Annotated[Path | None, typer.Option(help="training run, for --controller noisy-policy")] = None,
    resume: Annotated[bool, typer.Option(help="continue an interrupted collection")] = False,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    width: Annotated[int, typer.Option(help="frame width")] = 64,
    height: Annotated[int, typer.Option(help="frame height")] = 64,
    randomize: Annotated[bool, typer.Option(help="visual randomisation (lights, colours, camera jitter)")] = True,
    trust_pickles: TrustPickles = False,
) -> None:
    """Record camera frames paired with the supervisor's ground truth (Pattern 2)."""
    from dualtwin.perception.dataset import collect as run_collect

    check_output_dir(out, "collect", resume=resume, resumable=True)
    if policy is not None and controller != "noisy-policy":
        raise DualtwinError("--policy is used only with --controller noisy-policy")
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles), report_progress() as progress:
        path = run_collect(env, episodes, out, controller=controller, policy_run=policy, resume=resume, seed=seed,
                           width=width, height=height, randomize=randomize, progress=progress)
    console.print(f"wrote {path}")


@perception_app.command("train")
def perception_train(
    data: Annotated[Path, typer.Option(help="dataset folder from dualtwin collect")],
    out: Annotated[Path, typer.Option(help="model folder (perception.onnx + contract)")],
    epochs: Annotated[int, typer.Option(help="training epochs")] = 15,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    init_from: Annotated[Path | None, typer.Option(help="model folder to continue training from")] = None,
    colour_jitter: Annotated[float, typer.Option(help="per-channel colour gain augmentation exp(U(-c, c))")] = 0.0,
) -> None:
    """Train the small CNN that recovers pole angle and cart position from stacked frames."""
    from dualtwin.perception.model import train_perception

    if not 0.0 <= colour_jitter <= 2.0:
        raise DualtwinError(f"--colour-jitter must be in [0, 2], not {colour_jitter}")
    check_output_dir(out, "perception-train")
    with report_progress() as progress:
        path = train_perception(data, out, epochs=epochs, seed=seed, progress=progress, init_from=init_from,
                                colour_jitter=colour_jitter)
    console.print(f"wrote {path}")


@perception_app.command("eval")
def perception_eval(
    model: Annotated[Path, typer.Option(help="model folder")],
    data: Annotated[Path, typer.Option(help="dataset folder")],
    json_out: JsonOutput = False,
) -> None:
    """MAE per quantity of the exported model on the episodes it did not train on (by episode identity)."""
    from dualtwin.perception.model import evaluate_perception

    result = evaluate_perception(model, data)
    if json_out:
        emit_json(result)
        return
    console.print(f"{len(result['heldout_episodes'])} held-out episode(s), {result['frames']} frames; "
                  f"{result['excluded_training_episodes']} training episode(s) of this dataset left out")
    units = result.get("units", {})
    print_table(console, [Column("quantity", False), Column("MAE"), Column("constant predictor"),
                          Column("unit", False)],
                [[name, f"{value:.5g}", f"{result['mae_constant'][name]:.5g}", units.get(name, "")]
                 for name, value in result.get("mae", {}).items()])


@app.command("serve")
def serve(
    policy: Annotated[Path, typer.Option(help="exported policy folder (policy.onnx + policy_contract.json)")],
    perception: Annotated[Path, typer.Option(help="perception model folder")],
    host: Annotated[str, typer.Option(help="address to listen on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="port")] = 8000,
    api_key_env: Annotated[str | None, typer.Option(help="environment variable holding the API key")] = None,
    camera_only: Annotated[bool, typer.Option(
        help="camera-only: requests carry wheel odometry only; pole angle and rate come from the camera")] = False,
) -> None:
    """Serve the policy plus perception over HTTP (Pattern 3): POST /v1/act, GET /v1/info, GET /healthz."""
    import os

    from dualtwin.server.app import serve as run_serve

    api_key = None
    if api_key_env is not None:
        api_key = os.environ.get(api_key_env)
        if not api_key:
            raise DualtwinError(f"--api-key-env: environment variable {api_key_env} is not set")
    run_serve(policy, perception, host=host, port=port, api_key=api_key, camera_only=camera_only)


@app.command("deploy")
def deploy(
    server: Annotated[str, typer.Option(help="RobotServer URL, e.g. http://127.0.0.1:8000")],
    env: Annotated[str, typer.Option(help="registered env id to run closed-loop")],
    episodes: Annotated[int, typer.Option(help="episodes")] = 5,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    api_key_env: Annotated[str | None, typer.Option(help="environment variable holding the API key")] = None,
) -> None:
    """Run a twin through the server with on-board sensors and camera only; compare with privileged state."""
    import json
    import os

    from dualtwin.server.client import deploy as run_deploy

    with report_progress() as progress:
        result = run_deploy(server, env, episodes, seed=seed,
                            api_key=os.environ.get(api_key_env) if api_key_env else None, progress=progress)
    console.print_json(json.dumps(result, default=str))


def _runs(*folders: Path) -> None:
    """Every folder must be a run whose logs verify, before any progress is shown or anything is written."""
    from dualtwin.divergence.runs import load_run

    for folder in folders:
        load_run(folder)


def _training_run(folder: Path | None, option: str) -> None:
    """A training run folder (``run.json``) given to ``option``: checked before any work starts."""
    if folder is None:
        return
    from dualtwin.artifacts import read_json_object

    if not folder.is_dir() or not (folder / "run.json").exists():
        raise DualtwinError(f"{option} {folder}: not a training run folder (no run.json)")
    read_json_object(folder / "run.json", ("env_id",), what="training run record")


def _int_list(text: str, option: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise DualtwinError(f"{option} must be comma-separated whole numbers, not {text!r}") from None
    if not values or min(values) < 1:
        raise DualtwinError(f"{option} must list positive whole numbers, not {text!r}")
    return values


@app.command("lockstep")
def lockstep(
    robot: Annotated[str, typer.Option(help="bundled robot name or binding file")],
    out: Annotated[Path, typer.Option(help="output directory")],
    primary: Annotated[str, typer.Option(help="twin whose state is the reference")] = "webots",
    secondary: Annotated[str, typer.Option(help="twin re-seated in the primary's state")] = "mujoco",
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
        result = run_lockstep(primary, secondary, robot, out_dir=out, suite=scenarios, policy=policy, resync=resync,
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
    out: Annotated[Path, typer.Option(help="output directory")],
    primary: Annotated[str, typer.Option(help="reference twin")] = "webots",
    secondary: Annotated[str, typer.Option(help="predicting twin")] = "mujoco",
    horizons: Annotated[str, typer.Option(help="horizons in control periods")] = "1,5,25",
    stride: Annotated[int, typer.Option(help="periods between synchronised start states")] = 5,
    json_out: JsonOutput = False,
) -> None:
    """Short-horizon prediction error from synchronised states: the chaos-insensitive model mismatch."""
    from dualtwin.sync import prediction_error, write_sync_report

    horizon_list = _int_list(horizons, "--horizons")
    check_output_dir(out, "predict-error")
    result = prediction_error(primary, secondary, robot, suite=scenarios, out_dir=out,
                              horizons=horizon_list, stride=stride)
    report = write_sync_report(out / "report", prediction=result)
    if json_out:
        emit_json({"report": str(report), "prediction": result.table})
        return
    by_h = result.table.get("by_horizon", {})
    print_table(console, [Column("horizon [periods]"), Column("normalised RMS error")],
                [[str(h), f"{row.get('normalized_rms', float('nan')):.4g}"] for h, row in by_h.items()])
    console.print(f"report: {report}")


@app.command("demo")
def demo(out: Annotated[Path, typer.Option(help="demo output folder (new or empty)")] = Path("runs/demo"),
         resume: Annotated[bool, typer.Option(help="continue an earlier demo in OUT")] = False) -> None:
    """Run the bundled CartPole suite on both twins and write the comparison report."""
    from dualtwin.demo import run_demo

    run_demo(out, console, resume=resume)


@webots_app.command("run")
def webots_run(
    world: Annotated[Path, typer.Argument(help=".wbt world file")],
    controller: Annotated[Path | None, typer.Option(help="controller script (default: the one the world names)")] = None,
    duration: Annotated[float | None, typer.Option(help="simulated seconds before step() returns -1")] = None,
    keys: Annotated[Path | None, typer.Option(help="key script replayed by Keyboard: lines 'TIME KEY [HOLD]'")] = None,
) -> None:
    """Run a Webots world headless with its (unchanged) Python controller."""
    from dualtwin.webots.runner import run_world

    if controller is not None:
        from dualtwin.artifacts import read_text_file

        read_text_file(controller, "controller script")  # missing, a folder, a pipe or binary: one line
    code = run_world(world, controller, duration, keys=keys)
    raise typer.Exit(code)


@webots_app.command("fetch")
def webots_fetch(
    worlds: Annotated[list[Path], typer.Argument(help=".wbt world files")],
    out: Annotated[Path | None, typer.Option(help="fill this folder (for DUALTWIN_PROTO_MIRROR on an offline "
                                                  "machine) instead of your PROTO cache")] = None,
) -> None:
    """Download every PROTO (and bounding-object mesh) the worlds need, verified, for offline runs."""
    from dualtwin.webots.fetch import fetch_command

    report, root = fetch_command(worlds, out, say=lambda line: print(line, file=sys.stderr))
    for warning in report.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"{len(report.protos)} PROTO files and {len(report.assets)} meshes ready in {root}")


@app.command("convert")
def convert(
    world: Annotated[Path, typer.Argument(help=".wbt world to convert")],
    output: Annotated[Path, typer.Option("-o", "--output", help="MJCF file to write")],
    robot: Annotated[str | None, typer.Option(help="DEF or name of the robot (default: the only one)")] = None,
    binding: Annotated[Path | None, typer.Option(help="also write a binding for both twins")] = None,
) -> None:
    """Convert a Webots robot to MJCF (deterministic), with Webots' mass, joint and motor semantics."""
    from dualtwin.artifacts import check_output_file
    from dualtwin.convert import ConversionError, convert_world

    # An existing model file is never replaced (nothing marks it as ours); a binding this command wrote is.
    check_output_file(output, "--output")
    if binding is not None:
        check_output_file(binding, "--binding", marker="# Generated by dualtwin convert")
    conversion = convert_world(world, robot=robot)
    for warning in conversion.warnings:
        console.print(f"[yellow]warning[/yellow] {warning}")
    for finding in conversion.lint:
        console.print(f"lint {finding}")
    errors = [f for f in conversion.lint if f.level == "error"]
    if errors:
        raise ConversionError(f"{world}: the converted model fails {len(errors)} lint check(s): {errors[0]}")
    smoke = conversion.smoke()
    if not smoke.ok:
        raise ConversionError(f"{world}: the converted model fails the physics smoke test: {smoke.message}")
    conversion.write(output, binding)
    console.print(f"wrote {output}" + (f" and {binding}" if binding else ""))


class JsonDialect(StrEnum):
    """Schemas a primitive robot description may be written in."""

    auto = "auto"
    dualtwin = "dualtwin"
    paper = "paper"


@app.command("generate")
def generate(
    output: Annotated[Path, typer.Option("-o", "--output", help="output folder for both twins")],
    from_text: Annotated[Path | None, typer.Option(help="robot described in text (needs an LLM)")] = None,
    from_json: Annotated[Path | None, typer.Option(help="primitive robot description (JSON)")] = None,
    from_wbt: Annotated[Path | None, typer.Option(help="Webots world to convert")] = None,
    max_iterations: Annotated[int, typer.Option(help="LLM generate-compile-repair rounds")] = 5,
    json_dialect: Annotated[JsonDialect, typer.Option(
        help="schema of the description (--from-json and LLM replies): ours, the paper's, or auto-detected")]
    = JsonDialect.auto,
) -> None:
    """Make both twins (MJCF + .wbt + binding) from text, a primitive JSON or a Webots world."""
    from dualtwin.genai.generate import Source
    from dualtwin.genai.generate import generate as run_generate

    given = [(p, f) for p, f in ((from_text, Source.from_text), (from_json, Source.from_json),
                                  (from_wbt, Source.from_wbt)) if p is not None]
    if len(given) != 1:
        raise DualtwinError("give exactly one of --from-text, --from-json or --from-wbt")
    path, make = given[0]
    from dualtwin.artifacts import read_text_file

    read_text_file(path, "robot description")  # before the output folder is made
    if from_json is not None:
        from dualtwin.artifacts import read_json

        read_json(from_json, "robot description")
    check_output_dir(output, "generate", option="--output")
    result = run_generate(make(path), output, max_iterations=max_iterations, dialect=json_dialect.value)
    console.print(f"converged after {result.iterations} LLM iteration(s)" if result.iterations
                  else "built deterministically")
    if result.assumptions:
        console.print(f"read in the {result.dialect} schema with {len(result.assumptions)} assumption(s) "
                      "(listed in generation.json and transcript.json)")
    for name, file in result.files.items():
        console.print(f"  {name:<10} {file}")


# ------------------------------------------------------------------ the CLI's promise
# Ranges for numeric options, by option name, the same in every command (a new command's --seed is checked like
# every other). (low, high): None means unbounded; high may be a float for float options. Numeric options not
# named here must be >= 0. Every float option must be finite. Violations are usage errors naming the option.
MAX_SEED = 2**32 - 1
OPTION_RANGES: dict[str, tuple[float | None, float | None]] = {
    "seed": (0, MAX_SEED), "port": (1, 65535), "episodes": (1, 1_000_000), "budget": (1, 10_000_000),
    "epochs": (1, 100_000), "steps": (1, 10**10), "stride": (1, 1_000_000), "width": (8, 4096),
    "height": (8, 4096), "max_iterations": (1, 100), "workers": (1, 1024), "shadow_fraction": (0, 1),
    "duration": (0, 86_400), "ensemble": (0, 10_000),
}


def _check_number(name: str, value: float) -> str | None:
    """Why ``value`` is not acceptable for the option ``name`` (see OPTION_RANGES), or None."""
    import math

    low, high = OPTION_RANGES.get(name, (0, None))
    if isinstance(value, float) and not math.isfinite(value):
        return f"{value!r} is not a finite number"
    if (low is not None and value < low) or (high is not None and value > high):
        def text(bound: float) -> str:
            return str(int(bound)) if float(bound).is_integer() else f"{bound:g}"

        return f"{value!r} is out of range (must be " + (
            f"from {text(low or 0)} to {text(high)})" if high is not None else f">= {text(low or 0)})")
    return None


def _policy_callback(original: Any) -> Any:
    """A parameter callback applying the option policies to the converted value, then ``original``'s."""

    def callback(ctx: Any, param: Any, value: Any) -> Any:
        option = (param.opts or [param.name or "?"])[0]
        values = value if isinstance(value, list | tuple) else [value]
        for item in values:
            if isinstance(item, int | float) and not isinstance(item, bool):
                problem = _check_number(param.name or "", item)
                if problem:
                    raise DualtwinError(f"{option}: {problem}")
        if param.name == "scenarios" and isinstance(value, Path):
            # A bundled robot's name means its bundled suite, from any folder (suite.loader.resolve_suite).
            from dualtwin.suite.loader import resolve_suite

            try:
                value = resolve_suite(value)
            except DualtwinError as exc:
                raise DualtwinError(f"{option}: {exc}") from None
        return original(ctx, param, value) if original is not None else value

    return callback


def _harden(command: Any) -> Any:
    """Apply the option policies above to every parameter of every command, recursively (new commands too)."""
    for param in command.params:
        if not getattr(param, "_dualtwin_policy", False):
            param.callback = _policy_callback(param.callback)
            param._dualtwin_policy = True
    for sub in getattr(command, "commands", {}).values():
        _harden(sub)
    return command


# ------------------------------------------------------------------ import (recorded runs)
import_app = typer.Typer(help="Import recordings (the paper's logs, CSV/TSV, ROS 2 bags) as run folders.",
                         no_args_is_help=True)
app.add_typer(import_app, name="import")
ImportSuite = Annotated[Path, typer.Option("--suite", help="the suite the recording was made from (JSON)")]
ImportRobot = Annotated[str, typer.Option(help="bundled robot name or path to a binding file")]
ImportOut = Annotated[Path, typer.Option(help="run folder to write (empty, new, or an earlier import)")]
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
    console.print(f"wrote {out}")


@import_app.command("paper")
def import_paper_cmd(
    log_dir: Annotated[Path, typer.Argument(help="folder of simulation_log_SUP_<i>.tsv files")],
    suite: ImportSuite, robot: ImportRobot, out: ImportOut, json_out: JsonOutput = False,
) -> None:
    """The paper's TestOrchestrator logs (one TSV per scenario, paired with the suite by index)."""
    from dualtwin.recorded import import_paper

    _import_with_progress(lambda p: import_paper(log_dir, suite, robot, out, progress=p), json_out)


@import_app.command("table")
def import_table_cmd(
    mapping: Annotated[Path, typer.Argument(help="YAML mapping: files, time column, channels")],
    suite: ImportSuite, robot: ImportRobot, out: ImportOut, data_dir: ImportDataDir = None,
    json_out: JsonOutput = False,
) -> None:
    """CSV/TSV logs, one file per scenario, described by a YAML mapping."""
    from dualtwin.recorded import import_table

    _import_with_progress(lambda p: import_table(mapping, suite, robot, out, data_dir=data_dir, progress=p),
                          json_out)


@import_app.command("mcap")
def import_mcap_cmd(
    mapping: Annotated[Path, typer.Argument(help="YAML mapping: bags, topics and fields, scenario ranges")],
    suite: ImportSuite, robot: ImportRobot, out: ImportOut, data_dir: ImportDataDir = None,
    json_out: JsonOutput = False,
) -> None:
    """ROS 2 bags in MCAP, described by a YAML mapping."""
    from dualtwin.recorded import import_mcap

    _import_with_progress(lambda p: import_mcap(mapping, suite, robot, out, data_dir=data_dir, progress=p),
                          json_out)


def one_line(message: str) -> str:
    """The error promise: one line, whatever the message's own line breaks."""
    return "; ".join(part.strip() for part in str(message).splitlines() if part.strip())


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: user errors become one line on stderr and exit code 2, never a traceback.

    Usage errors (unknown option, bad number, missing option) are printed by us, not by click/typer's boxes, so
    they keep the same one-line form; ``argv`` (default ``sys.argv[1:]``) lets tests call this in-process.
    """
    from typer.exceptions import Abort, TyperException

    code = 0
    try:
        command = _harden(typer.main.get_command(app))
        result = command.main(args=list(sys.argv[1:] if argv is None else argv), prog_name="dualtwin",
                              standalone_mode=False)
        code = result if isinstance(result, int) else 0
    except Abort:
        print("error: interrupted", file=sys.stderr)
        code = 130
    except TyperException as exc:  # click's usage errors, as vendored by typer: bad value, missing option...
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            print(ctx.get_help())  # a group without a subcommand: its help, as before
        else:
            where = f"{ctx.command_path}: " if ctx is not None else ""
            print(f"error: {where}{one_line(exc.format_message())}", file=sys.stderr)
        code = getattr(exc, "exit_code", 2) or 2
    except DualtwinError as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        code = 2
    except OSError as exc:
        # A file the user named cannot be read or written (permissions, a folder where a file belongs, a full
        # disk): their input, not our bug. Errors without a file name are bugs and keep their traceback.
        if exc.filename is None:
            raise
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        code = 2
    sys.stdout.flush()
    if argv is None:
        sys.exit(code)
    return code


if __name__ == "__main__":
    main()
