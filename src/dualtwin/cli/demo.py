"""``dualtwin demo``: the bundled CartPole suite on both twins, compared."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dualtwin.cli.common import OutOption, app, console, on_interrupt, resumable


@app.command("demo")
@resumable
def demo(out: Annotated[Path, OutOption("demo output folder (new or empty)")] = Path("runs/demo"),
         resume: Annotated[bool, typer.Option(help="continue an earlier demo in OUT")] = False) -> None:
    """Run the bundled CartPole suite on both twins and write the comparison report."""
    from dualtwin.demo import run_demo

    on_interrupt(lambda: "resume with --resume" if (out / "manifest.json").is_file() else "")
    run_demo(out, console, resume=resume)
