"""``dualtwin perception``: collect frames, train and evaluate the state estimator."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from dualtwin.artifacts import check_output_dir
from dualtwin.cli.common import JsonOutput, OutOption, TrustPickles, console, perception_app, report_progress
from dualtwin.errors import DualtwinError
from dualtwin.reporting import Column, emit_json, print_table


class Controller(StrEnum):
    """What drives the robot while frames are recorded."""

    scripted = "scripted"
    random = "random"
    noisy_policy = "noisy-policy"


@perception_app.command("collect")
def collect(
    env: Annotated[str, typer.Option(help="registered env id whose twin renders the frames")],
    episodes: Annotated[int, typer.Option(help="episodes in the finished dataset")],
    out: Annotated[Path, OutOption("dataset folder (shards + manifest.json)")],
    controller: Annotated[Controller, typer.Option(help="what drives the robot")] = Controller.scripted,
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
    if policy is not None and controller != Controller.noisy_policy:
        raise DualtwinError("--policy is used only with --controller noisy-policy")
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(trust_pickles), report_progress() as progress:
        path = run_collect(env, episodes, out, controller=controller.value, policy_run=policy, resume=resume, seed=seed,
                           width=width, height=height, randomize=randomize, progress=progress)
    console.print(f"wrote {path}")


@perception_app.command("train")
def perception_train(
    data: Annotated[Path, typer.Option(help="dataset folder from dualtwin perception collect")],
    out: Annotated[Path, OutOption("model folder (perception.onnx + contract)")],
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
