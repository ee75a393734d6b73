"""What every command module shares: the typer app and its groups, the console, common options and the
input checks run before any work starts.

One CLI shape (issue 18), decided here so every command module follows it:

- every output folder or file is ``--out`` (short ``-o``): :func:`OutOption`;
- a suite is ``--scenarios FILE`` (a bundled robot's name means its suite);
- a twin pair is ``--reference TWIN`` (the ground truth) and ``--target TWIN`` (the twin that is explained,
  fitted or re-seated), a pair of runs ``--reference-run DIR`` and ``--target-run DIR``; a single twin is
  ``--twin``; twins are typed by :class:`Twin` so ``--help`` lists them;
- a list is a repeatable option with typed items (``--horizons 1 --horizons 5``); comma strings are not split
  (one way to write a list, and no item can be mistaken for two);
- a closed set of choices is a ``StrEnum`` here, or a ``Literal`` in a config model the options derive from
  (``--help`` lists it, a bad value is click's one-line usage error); commands pass ``.value`` on, so the
  libraries keep their plain-string APIs.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from dualtwin.errors import DualtwinError
from dualtwin.interrupts import ready
from dualtwin.reporting import configure_console
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
perception_app = typer.Typer(help="Learned perception: collect frames, train and evaluate.", no_args_is_help=True)
app.add_typer(webots_app, name="webots")
app.add_typer(perception_app, name="perception")
console = configure_console(Console(stderr=False))
#: ``--json``: the results as one JSON document on stdout; progress and messages go to stderr.
JsonOutput = Annotated[bool, typer.Option("--json", help="print the results as JSON on stdout (progress and "
                                                          "messages go to stderr)")]



def OutOption(help: str) -> Any:  # noqa: N802 -- used like typer.Option, inside Annotated[...]
    """The output option of every command: ``--out`` with ``-o`` as its short form."""
    return typer.Option("--out", "-o", help=help)


class Twin(StrEnum):
    """The twins (``dualtwin.twins.TWINS``; a test keeps the two in step)."""

    mujoco = "mujoco"
    webots = "webots"


class Executor(StrEnum):
    """Where independent simulations run (``dualtwin.parallel.EXECUTORS``)."""

    process = "process"
    serial = "serial"
    ray = "ray"


class Which(StrEnum):
    """Which checkpoint of a training run: the best evaluated or the final model."""

    best = "best"
    final = "final"


def _print_version(value: bool) -> None:
    if value:
        from dualtwin import __version__

        print(f"dualtwin {__version__}")
        raise typer.Exit(0)


@app.callback()
def _global_options(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="print setup details (e.g. the OpenGL backend) "
                                                                   "on stderr")] = False,
    version: Annotated[bool, typer.Option("--version", help="print the version and exit", is_eager=True,
                                          callback=_print_version)] = False,
) -> None:
    if verbose:
        from dualtwin import gl_backend

        print(gl_backend().describe(), file=sys.stderr)


# What an interrupted command leaves behind, for the one line Ctrl-C prints (set by commands that can resume).
_interrupt_notes: list[Any] = []


def resumable(command: Any) -> Any:
    """Mark a command that names what an interruption keeps (:func:`on_interrupt`, early in its code): a Ctrl-C
    that came while the command line loaded waits for that note (dualtwin.interrupts.command_starts)."""
    command.says_what_stopping_keeps = True
    return command


def on_interrupt(describe: Any) -> None:
    """Register ``describe() -> str`` ("3 scenarios kept, resume with --resume"), called if Ctrl-C stops the
    command; it must only read files (the command's own writes are atomic, so what it reads is whole)."""
    _interrupt_notes.append(describe)
    ready()  # a Ctrl-C held while the command line loaded stops the command now, with this note


def interrupted_note(reset: bool = False) -> str:
    """"; " and what the running command registered with :func:`on_interrupt` (empty if nothing)."""
    if reset:
        _interrupt_notes.clear()
        return ""
    notes = []
    for describe in _interrupt_notes:
        try:
            notes.append(str(describe()))
        except Exception:  # noqa: BLE001 -- a note must never turn Ctrl-C into a traceback
            continue
    return "".join(f"; {note}" for note in notes if note)


def resume_note(manifest: Path, key: str, what: str) -> str:
    """"N <what> kept, resume with --resume" from the list ``key`` of the run's manifest on disk."""
    import json

    try:
        kept = len(json.loads(manifest.read_text(encoding="utf-8")).get(key) or [])
    except (OSError, ValueError, AttributeError):
        kept = 0
    return f"{kept} {what} kept, resume with --resume"


def check_runs(*folders: Path) -> None:
    """Every folder must be a run whose logs verify, before any progress is shown or anything is written."""
    from dualtwin.divergence.runs import load_run

    for folder in folders:
        load_run(folder)


def check_training_run(folder: Path | None, option: str) -> None:
    """A training run folder (``run.json``) given to ``option``: checked before any work starts."""
    if folder is None:
        return
    from dualtwin.artifacts import read_json_object

    if not folder.is_dir() or not (folder / "run.json").exists():
        raise DualtwinError(f"{option} {folder}: not a training run folder (no run.json)")
    read_json_object(folder / "run.json", ("env_id",), what="training run record")


def int_list(text: str, option: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise DualtwinError(f"{option} must be comma-separated whole numbers, not {text!r}") from None
    if not values or min(values) < 1:
        raise DualtwinError(f"{option} must list positive whole numbers, not {text!r}")
    return values


def llm_proposer(label_a: str, label_b: str):  # type: ignore[no-untyped-def]
    """The LLM proposer for --llm (the provider is configured by DUALTWIN_LLM_* or DUALTWIN_LLM_CONFIG)."""
    from dualtwin.align.narrate import LLMProposer
    from dualtwin.genai.llm import make_llm

    return LLMProposer(make_llm(), label_a=label_a, label_b=label_b)
