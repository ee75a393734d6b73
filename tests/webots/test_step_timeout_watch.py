"""The threads runtime's step-timeout watch reads a controller's state without the runtime's lock, from its own thread,
every few hundredths of a second, and may look at any moment between two lines of the controller's thread. At no such
moment may it see a controller that has just made its Robot, or has just come back from a long step, with the time of
its start as its last sign of progress: it would stop a controller that is doing what it should.

The check runs here at every line the controller's thread executes in the runtime's ``register`` and ``advance``
(a trace function), so each moment is looked at, deterministically. The wall time these take is given by moving the
controller's last sign of progress back (no test waits): 30 s of imports, within the 60 s start-up grace but past the
5 s timeout, and a step that lasted 30 s.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any

import pytest

from dualtwin.webots import runtime as runtime_module
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text
from dualtwin.webots.robot import Robot
from dualtwin.webots.runner import _check_step_timeout, _ScriptResult
from dualtwin.webots.runtime import Runtime

TIMEOUT_S = 5.0  # the default --step-timeout
LONG_AGO_S = 30.0  # past the timeout, within the start-up grace (STARTUP_GRACE_S = 60 s)


@contextmanager
def _watched(runtime: Runtime, result: _ScriptResult, step_lasts: float = 0.0) -> Iterator[list[str]]:
    """Run the watch's check before every line (and at every return) of ``Runtime.register``/``advance`` in this
    thread; yields the list of the places where it stopped the controller. ``step_lasts``: the wall time each step
    is taken to have lasted (its start moved back when it returns)."""
    stopped: list[str] = []
    waited: dict[int, float] = {}
    controller = result.controller
    assert controller is not None

    def local(frame: FrameType, event: str, arg: Any) -> Any:
        if frame.f_code.co_name == "_advance":
            if event == "return" and step_lasts:
                controller.progress -= step_lasts
            return local
        if event in ("line", "return") and result.timed_out_at is None:
            _check_step_timeout(runtime, result, TIMEOUT_S, time.monotonic(), waited)
            if result.timed_out_at is not None:
                stopped.append(f"{frame.f_code.co_name}:{frame.f_lineno}")
        return local

    def calls(frame: FrameType, event: str, arg: Any) -> Any:
        code = frame.f_code
        if code.co_filename == runtime_module.__file__ and code.co_name in ("register", "advance", "_advance"):
            return local
        return None

    previous = sys.gettrace()  # (a coverage tracer's, given back after)
    sys.settrace(calls)
    try:
        yield stopped
    finally:
        sys.settrace(previous)


@pytest.fixture
def sim() -> Iterator[Simulation]:
    world = load_world_text('#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\nRobot { name "r" }\n')
    simulation = Simulation(world)
    yield simulation
    simulation.close()


def _controller(sim: Simulation) -> tuple[Runtime, _ScriptResult]:
    runtime = Runtime(sim)
    result = _ScriptResult(Path("probe.py"))
    result.controller = runtime.bind_thread(sim.robots[0].node)
    result.running = True  # (result.thread stays None: the check never stops this test's own thread)
    return runtime, result


def test_a_controller_that_makes_its_robot_after_long_imports_is_not_stopped(sim: Simulation) -> None:
    runtime, result = _controller(sim)
    assert result.controller is not None
    result.controller.progress -= LONG_AGO_S  # its imports took 30 s
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with _watched(runtime, result) as stopped:
            robot = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    try:
        # (it stopped it between 'arrived = True' and the new progress time on the previous code)
        assert stopped == []
    finally:
        robot.cleanup()


def test_a_controller_back_from_a_step_longer_than_the_timeout_is_not_stopped(sim: Simulation) -> None:
    runtime, result = _controller(sim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    try:
        with _watched(runtime, result, step_lasts=LONG_AGO_S) as stopped:
            assert robot.step(8) == 0
        # (it stopped it between 'in_step = False' and the new progress time on the previous code)
        assert stopped == []
    finally:
        robot.cleanup()
