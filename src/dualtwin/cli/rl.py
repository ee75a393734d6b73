"""``dualtwin train``, ``transfer`` and ``export``: policies in the twins."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import (
    JsonOutput,
    OutOption,
    TrustPickles,
    Which,
    app,
    check_training_run,
    console,
    report_progress,
)
from dualtwin.errors import DualtwinError
from dualtwin.reporting import Column, ProgressEvent, emit_json, print_table


@app.command("train")
def train(
    env: Annotated[str, typer.Option(help="registered env id, e.g. dualtwin/CartPole-MuJoCo-Continuous-v0")],
    out: Annotated[Path, OutOption("run folder")],
    config: Annotated[Path | None, typer.Option(
        help="PPO config YAML, or a bundled config's name (ppo_cartpole, ppo_cartpole_text, ppo_cartpole_code, "
        "ppo_cartpole_continuous, ppo_pioneer, ppo_arm_reach; default ppo_cartpole)")] = None,
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
    out: Annotated[Path, OutOption("report folder")],
    policy_aligned: Annotated[Path | None, typer.Option(
        help="run folder of a policy trained in the aligned source twin (train --aligned knobs.json)")] = None,
    policy_dr: Annotated[Path | None, typer.Option(
        help="run folder of a policy trained with calibrated DR (train --dr dr_ranges.json)")] = None,
    policy_control: Annotated[Path | None, typer.Option(
        help="run folder of the control: the aligned policy's fine-tuning repeated in the nominal twin "
        "(train --init-from POLICY without --aligned)")] = None,
    episodes: Annotated[int, typer.Option(help="episodes per row")] = 10,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    which: Annotated[Which, typer.Option(help="which model of each run")] = Which.final,
    trust_pickles: TrustPickles = False,
    json_out: JsonOutput = False,
) -> None:
    """Evaluate policies in their source twin and in the target twin: before and after alignment, with DR (Table 1)."""
    from dualtwin.rl.transfer import transfer as run_transfer

    check_output_dir(out, "transfer")
    from dualtwin.rl import check_env_id

    check_env_id(target_env)
    for option, folder in (("--policy", policy), ("--policy-aligned", policy_aligned), ("--policy-dr", policy_dr),
                           ("--policy-control", policy_control)):
        check_training_run(folder, option)
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles), report_progress() as progress:
        progress(ProgressEvent("transfer", 0, None, f"{episodes} episodes per row, in the source and target twins"))
        report = run_transfer(policy, target_env, policy_aligned=policy_aligned, policy_dr=policy_dr,
                              policy_control=policy_control, episodes=episodes, seed=seed, out_dir=out,
                              which=which.value)
        progress(ProgressEvent("transfer", len(report.rows), len(report.rows), "rows evaluated"))
    if json_out:
        emit_json({"out": str(out), **report.to_dict()})
        return
    print_table(console, [Column("row", False), Column("result", False)],
                [[row.label, row.summary()] for row in report.rows])
    if report.source_converged is False:  # the report says so too; a reader of the terminal must not miss it
        console.print(unconverged_warning(report), markup=False)
    console.print(f"wrote {out}")


def unconverged_warning(report: Any) -> str:
    from dualtwin.rl.transfer import CONVERGED

    return (f"warning: the source is not converged ({report.rows[0].mean:.1f} < {CONVERGED:.0%} of the "
            f"{report.episode_cap}-step cap): ratios of rows trained for longer overstate what transfer, "
            "alignment or DR did")


@app.command("export")
def export(
    policy: Annotated[Path, typer.Option(help="training run folder")],
    out: Annotated[Path, OutOption("export folder (policy.onnx, policy_contract.json)")],
    which: Annotated[Which, typer.Option(help="which model of the run")] = Which.final,
    trust_pickles: TrustPickles = False,
    camera_only: Annotated[bool, typer.Option(
        help="write a camera-only contract: wheel odometry on board, the rest from --perception")] = False,
    perception: Annotated[Path | None, typer.Option(help="perception model folder, for --camera-only")] = None,
) -> None:
    """Export a policy to ONNX with observation normalisation and action scaling inside the graph."""
    from dualtwin.rl.export import export_policy

    if camera_only != (perception is not None):
        raise DualtwinError("--camera-only and --perception go together")
    if perception is not None:
        from dualtwin.perception.estimator import StateEstimator

        StateEstimator.load(perception)  # a bad model folder fails before anything is written
    check_output_dir(out, "export")
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles):
        path = export_policy(policy, out, which=which.value)  # type: ignore[arg-type]
    if perception is not None:
        from dualtwin.perception.camera_only import export_camera_only

        export_camera_only(out, perception, out)
    console.print(f"wrote {path}")
