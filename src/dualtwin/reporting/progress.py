"""Progress for work longer than a few seconds: library code reports events, the CLI chooses how to show them.

Library functions take an optional ``progress: ProgressCallback`` and call it (directly or through
`Progress`) as stages advance; they never print. The CLI renders events with `report_progress`: rich
progress bars when stderr is a terminal, otherwise one plain line per event. Both go to stderr, so a command's
``--json`` stdout stays clean.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TextIO

from rich.console import Console


@dataclass(frozen=True)
class ProgressEvent:
    """``done`` of ``total`` units (None: unknown) of a named stage, with an optional status message."""

    stage: str
    done: int
    total: int | None = None
    message: str = ""

    def line(self) -> str:
        if self.total is None and self.done == 0 and self.message:
            return f"{self.stage}: {self.message}"  # a stage starting with no count yet: "0" would read as data
        count = f"{self.done}/{self.total}" if self.total is not None else str(self.done)
        return f"{self.stage}: {count}" + (f" {self.message}" if self.message else "")


ProgressCallback = Callable[[ProgressEvent], None]


class Progress:
    """A counter for one stage that reports to an optional callback (library side)."""

    def __init__(self, callback: ProgressCallback | None, stage: str, total: int | None = None) -> None:
        self.callback, self.stage, self.total, self.done = callback, stage, total, 0

    def start(self, message: str = "") -> None:
        if self.callback is not None:
            self.callback(ProgressEvent(self.stage, self.done, self.total, message))

    def advance(self, n: int = 1, message: str = "") -> None:
        self.done += n
        if self.callback is not None:
            self.callback(ProgressEvent(self.stage, self.done, self.total, message))


@contextmanager
def report_progress(stream: TextIO | None = None, *, force_plain: bool = False) -> Iterator[ProgressCallback]:
    """A callback that shows progress events on ``stream`` (default stderr) while the block runs."""
    target = stream if stream is not None else sys.stderr
    console = Console(file=target, stderr=stream is None)
    if force_plain or not console.is_terminal:
        def plain(event: ProgressEvent) -> None:
            target.write(event.line() + "\n")
            target.flush()

        yield plain
        return
    from rich.progress import BarColumn, MofNCompleteColumn, TaskID, TextColumn, TimeElapsedColumn
    from rich.progress import Progress as RichProgress

    tasks: dict[str, TaskID] = {}
    # markup=False: stage names and messages (scenario ids, knob names) are shown as they are.
    with RichProgress(TextColumn("{task.description}", markup=False), BarColumn(bar_width=24), MofNCompleteColumn(),
                      TimeElapsedColumn(), TextColumn("{task.fields[message]}", markup=False), console=console,
                      transient=False) as bars:
        def rich_event(event: ProgressEvent) -> None:
            task = tasks.get(event.stage)
            if task is None:
                task = tasks[event.stage] = bars.add_task(event.stage, total=event.total, message="")
            bars.update(task, completed=event.done, total=event.total, message=event.message)

        yield rich_event
