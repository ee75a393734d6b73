"""``dualtwin webots``: the headless Webots runtime."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from dualtwin.cli.common import OutOption, webots_app


@webots_app.command("run")
def webots_run(
    world: Annotated[Path, typer.Argument(help=".wbt world file")],
    controller: Annotated[Path | None, typer.Option(help="controller script (default: the one the world names)")] = None,
    duration: Annotated[float | None, typer.Option(help="simulated seconds before step() returns -1")] = None,
    keys: Annotated[Path | None, typer.Option(help="key script replayed by Keyboard: lines 'TIME KEY [HOLD]'")] = None,
    step_timeout: Annotated[float, typer.Option(
        help="real seconds a controller may run without calling step() before the run is stopped (exit 2); "
             "0 waits forever, like Webots")] = 5.0,
) -> None:
    """Run a Webots world headless, each (unchanged) Python controller in its own process."""
    try:
        from dualtwin.webots.runner import run_world

        if controller is not None:
            from dualtwin.artifacts import read_text_file

            read_text_file(controller, "controller script")  # missing, a folder, a pipe or binary: one line
        code = run_world(world, controller, duration, keys=keys, step_timeout_s=step_timeout)
    except KeyboardInterrupt:  # Ctrl-C while loading: the run itself answers it (children stopped, 130)
        print("error: interrupted", file=sys.stderr)
        code = 130
    raise typer.Exit(code)


@webots_app.command("fetch")
def webots_fetch(
    worlds: Annotated[list[Path], typer.Argument(help=".wbt world files")],
    out: Annotated[Path | None, OutOption("fill this folder (for DUALTWIN_PROTO_MIRROR on an offline "
                                                  "machine) instead of your PROTO cache")] = None,
) -> None:
    """Download every PROTO and mesh file (Mesh, CadShape; not textures or sounds) the worlds need, verified."""
    from dualtwin.webots.fetch import fetch_command

    report, root = fetch_command(worlds, out, say=lambda line: print(line, file=sys.stderr))
    for warning in report.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"{len(report.protos)} PROTO files and {len(report.assets)} meshes ready in {root}")
