"""Worlds of several robots, each with its own Python controller written by the test (the composite multi-robot
tests, tests/webots/test_composite_multi_*.py): the project folder is written, the world run in one isolation
mode, and what the controllers printed is given back line by line."""

from __future__ import annotations

import contextlib
import io
import textwrap
from pathlib import Path

from dualtwin.webots.runner import run_world


def write_project(folder: Path, world: str, controllers: dict[str, str], protos: dict[str, str] | None = None) -> Path:
    """``folder/worlds/w.wbt`` (an R2023b header, then ``world``), ``folder/controllers/NAME/NAME.py`` for each
    controller and ``folder/protos/NAME.proto`` for each PROTO (the world declares it as
    ``EXTERNPROTO "../protos/NAME.proto"``); the world's path."""
    for name, source in (protos or {}).items():
        (folder / "protos").mkdir(parents=True, exist_ok=True)
        (folder / "protos" / f"{name}.proto").write_text(textwrap.dedent(source).lstrip(), encoding="utf-8")
    for name, source in controllers.items():
        (folder / "controllers" / name).mkdir(parents=True)
        (folder / "controllers" / name / f"{name}.py").write_text(textwrap.dedent(source), encoding="utf-8")
    (folder / "worlds").mkdir(parents=True)
    path = folder / "worlds" / "w.wbt"
    path.write_text("#VRML_SIM R2023b utf8\n" + textwrap.dedent(world), encoding="utf-8")
    return path


def run_multi(folder: Path, world: str, controllers: dict[str, str], isolation: str,
              duration_s: float | None = None, protos: dict[str, str] | None = None) -> list[str]:
    """Run the project written by :func:`write_project` (exit code 0 asserted); the lines the controllers printed,
    in the order they reached the output (one controller's lines keep their order)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert run_world(write_project(folder, world, controllers, protos), None, duration_s, isolation=isolation) == 0
    return out.getvalue().splitlines()


def lines_of(lines: list[str], prefix: str) -> list[str]:
    """The lines that start with ``prefix`` (one controller's, when each prints its robot's name first)."""
    return [line for line in lines if line.startswith(prefix)]
