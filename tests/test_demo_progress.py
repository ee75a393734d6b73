"""`dualtwin demo` never leaves a newcomer waiting without a line (issue 28, item 6): a long step repeats what it
last said, with the elapsed time, when nothing was printed for a while."""

from __future__ import annotations

import io
import time

import pytest
from rich.console import Console

from dualtwin import demo


def test_a_silent_step_says_it_is_still_working(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(demo, "HEARTBEAT_S", 0.3)  # the interval, not the mechanism
    out = io.StringIO()
    console = Console(file=out, width=200)
    with demo._heartbeat(console, "aligning") as beat:
        beat.say("  iteration 1: objective 0.5", status="iteration 1: objective 0.5")
        time.sleep(1.4)
    lines = out.getvalue().splitlines()
    assert lines[0] == "  iteration 1: objective 0.5"
    repeats = [line for line in lines[1:] if line.startswith("  ... aligning: iteration 1: objective 0.5 (")]
    assert 2 <= len(repeats) <= 5 and len(repeats) == len(lines) - 1


def test_a_step_that_keeps_talking_gets_no_extra_lines(monkeypatch: pytest.MonkeyPatch) -> None:
    """The control: lines closer together than the interval are all there is."""
    monkeypatch.setattr(demo, "HEARTBEAT_S", 0.5)
    out = io.StringIO()
    with demo._heartbeat(Console(file=out, width=200), "running") as beat:
        for i in range(6):
            beat.say(f"  scenario {i} completed")
            time.sleep(0.15)
    assert out.getvalue().splitlines() == [f"  scenario {i} completed" for i in range(6)]
