"""The threads runtime's step-timeout watch reads a controller's state (``arrived``, ``in_step``, ``progress``) without
the runtime's lock, from its own thread, every few hundredths of a second, and may look at any moment between two
lines of the controller's thread. It stops a controller that has arrived (made its Robot), is not in a step, and whose
last sign of progress is older than the timeout. So at no moment may a controller that has just made its Robot, or has
just come back from a step, count as arrived or out of its step with a sign of progress older than that moment: after
imports or a step longer than the timeout (both normal), the watch would stop a controller doing what it should.

The state is read here at every line the controller's thread executes in the runtime's ``register`` and ``advance``
(a trace function), so each moment is looked at, deterministically, without waiting.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

import pytest

from dualtwin.webots import runtime as runtime_module
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text
from dualtwin.webots.robot import Robot
from dualtwin.webots.runtime import Controller, Runtime


@contextmanager
def _watched(controller: Controller, since: list[float]) -> Iterator[list[str]]:
    """Look at ``controller`` before every line (and at every return) of ``Runtime.register``/``advance`` in this
    thread; yields the places where it counted as arrived and out of a step with a sign of progress older than
    ``since[0]`` (a step's end moves ``since[0]`` to the time it returned)."""
    stale: list[str] = []

    def local(frame: FrameType, event: str, arg: Any) -> Any:
        if frame.f_code.co_name == "_advance":
            if event == "return":
                since[0] = time.monotonic()  # the step is over: its own start is no sign of progress any more
            return local
        if event in ("line", "return") and controller.arrived and not controller.in_step \
                and controller.progress < since[0]:
            stale.append(f"{frame.f_code.co_name}:{frame.f_lineno}")
        return local

    def calls(frame: FrameType, event: str, arg: Any) -> Any:
        code = frame.f_code
        if code.co_filename == runtime_module.__file__ and code.co_name in ("register", "advance", "_advance"):
            return local
        return None

    previous = sys.gettrace()  # (a coverage tracer's, given back after)
    sys.settrace(calls)
    try:
        yield stale
    finally:
        sys.settrace(previous)


@pytest.fixture
def sim() -> Iterator[Simulation]:
    world = load_world_text('#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\nRobot { name "r" }\n')
    simulation = Simulation(world)
    yield simulation
    simulation.close()


def _robot(sim: Simulation, runtime: Runtime) -> Robot:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Robot(runtime=runtime, robot_node=sim.robots[0].node)


def test_a_controller_counts_as_arrived_only_with_the_time_it_arrived(sim: Simulation) -> None:
    runtime = Runtime(sim)
    controller = runtime.bind_thread(sim.robots[0].node)  # its sign of progress: now, before its imports
    since = [time.monotonic()]  # its imports are over: what came before is no sign of progress
    with _watched(controller, since) as stale:
        robot = _robot(sim, runtime)
    try:
        # (it arrived with the time of its start on the previous code: 'arrived = True' came before the new time)
        assert stale == []
        assert controller.arrived
    finally:
        robot.cleanup()


def test_a_controller_leaves_a_step_only_with_the_time_it_returned(sim: Simulation) -> None:
    runtime = Runtime(sim)
    controller = runtime.bind_thread(sim.robots[0].node)
    robot = _robot(sim, runtime)
    try:
        since = [0.0]
        with _watched(controller, since) as stale:
            assert robot.step(8) == 0
        # (it left the step with the time of the step's start on the previous code: 'in_step = False' came first)
        assert stale == []
        assert not controller.in_step and controller.progress >= since[0] > 0.0
    finally:
        robot.cleanup()
