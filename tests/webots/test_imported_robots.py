"""A Robot a supervisor imports while the run goes on gets its controller, as in Webots: the script named by its
``controller`` field starts in its own process and steps in lock-step with the others from the next step;
``<none>`` and ``<extern>`` start nothing. Removing the robot ends its controller: its step returns -1 (then
the process exits) while the others run on, and nobody hangs.

Expectations by hand: the supervisor imports the robot after its 3rd step of 8 ms (t = 24 ms); the new
controller's first step returns at t = 32 ms, the supervisor's next step's end. The supervisor removes it after
its 6th step (t = 48 ms): the child's step that was waiting returns -1 at once (its log says so while the run goes on), and the
supervisor's steps go on to the end of the 0.1 s run. The threads runtime does the same."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

SUPERVISOR = """
    import os, time
    from controller import Supervisor
    HERE = os.path.dirname(os.path.abspath(__file__))  # (threads share one working folder)
    CHILD_LOG = os.path.join(HERE, "..", "child", "times.txt")
    sup = Supervisor()
    children = sup.getRoot().getField("children")
    log = open(os.path.join(HERE, "times.txt"), "w")
    for i in range(12):
        if sup.step(8) == -1:
            break
        log.write(f"sup {sup.getTime():.3f}\\n")
        if i == 2:
            children.importMFNodeFromString(-1, 'DEF NEW Robot { translation 1 0 0.5 name "new" '
                                                 'controller "{child}" }')
        if i == 2 and "{remove}" == "at once":
            sup.getFromDef("NEW").remove()  # before its controller could start
        if i == 5 and "{remove}" == "remove":
            sup.getFromDef("NEW").remove()
        if i == 5 and "{remove}" == "reset":
            sup.simulationReset()  # done at the next step: the reset takes imported nodes out
        if i == 8 and "{remove}" in ("remove", "reset"):  # the child's log says -1 within 3 s of real time, while this run still goes on
            deadline = time.monotonic() + 3.0
            ended = False
            while not ended and time.monotonic() < deadline:
                ended = os.path.isfile(CHILD_LOG) and "-1" in open(CHILD_LOG).read()
                time.sleep(0.01)
            log.write(f"child ended by {sup.getTime():.3f}: {ended}\\n")
    log.close()
"""
CHILD = """
    import os
    from controller import Robot
    robot = Robot()
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "times.txt"), "w") as log:
        ms = round(robot.getTime() * 1000)
        log.write(f"start {ms / 1000:.3f} {robot.getName()}\\n")
        while True:
            result = robot.step(8)
            if result == -1:  # (its robot may be gone: the time is not read then)
                log.write("child -1\\n")
                break
            # the step's time counted here: a thread reading the clock just after its robot's removal could see
            # time its step never reached (the simulation no longer waits for it)
            ms += 8
            log.write(f"child {ms / 1000:.3f} {result}\\n")
            log.flush()
"""


#: controller processes (as Webots), and the threads runtime the tests compare them with: both start them alike
BOTH_RUNTIMES = pytest.mark.parametrize("isolation", ["process", "threads"])


def _project(tmp_path: Path, child: str, remove: str = "no") -> Path:
    for name, script in (("sup", SUPERVISOR.replace("{child}", child).replace("{remove}", remove)),
                         ("child", CHILD)):
        folder = tmp_path / "controllers" / name
        folder.mkdir(parents=True)
        (folder / f"{name}.py").write_text(textwrap.dedent(script))
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text('#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n'
                     'Robot { name "boss" controller "sup" supervisor TRUE }\n')
    return world


def _log(tmp_path: Path, name: str) -> list[str]:
    path = tmp_path / "controllers" / name / "times.txt"
    return path.read_text().splitlines() if path.is_file() else []


@BOTH_RUNTIMES
def test_imported_robot_controller_starts_and_steps_in_lock_step(tmp_path: Path, isolation: str) -> None:
    world = _project(tmp_path, "child")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    sup = _log(tmp_path, "sup")
    assert sup[:3] == ["sup 0.008", "sup 0.016", "sup 0.024"]
    child = _log(tmp_path, "child")
    assert child[0] == "start 0.024 new"  # made at the import's time
    # lock-step from the next step: 32, 40, ... 96 ms, then the run's end (0.1 s reached inside the step to 104)
    assert child[1:] == [f"child {t / 1000:.3f} 0" for t in range(32, 97, 8)] + ["child -1"]
    # (control for the removal test below: without a removal, no -1 before the run's end)


@BOTH_RUNTIMES
@pytest.mark.parametrize("field", ["<none>", "<extern>"])
def test_imported_robot_without_a_controller_starts_nothing(tmp_path: Path, field: str, isolation: str) -> None:
    world = _project(tmp_path, field)
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    assert _log(tmp_path, "child") == []  # control for the test above: the script exists but is not named
    assert len(_log(tmp_path, "sup")) == 12


@BOTH_RUNTIMES
def test_removing_an_imported_robot_ends_its_controller_and_the_run_goes_on(tmp_path: Path, isolation: str) -> None:
    world = _project(tmp_path, "child", "remove")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    child = _log(tmp_path, "child")
    # steps to 32, 40, 48 ms; the supervisor removes the robot at 48 ms: the step the child waits in says -1
    assert child == ["start 0.024 new", "child 0.032 0", "child 0.040 0", "child 0.048 0", "child -1"]
    sup = _log(tmp_path, "sup")
    assert "child ended by 0.072: True" in sup  # the -1 came at once, not at the run's end
    assert sup[-1] == "sup 0.096" and len(sup) == 13  # the supervisor ran on to the end, unhindered


@BOTH_RUNTIMES
def test_a_reset_that_takes_an_imported_robot_out_ends_its_controller(tmp_path: Path, isolation: str) -> None:
    # simulationReset removes what a supervisor imported; it is done at the supervisor's step after the request
    # (its 7th, from 48 ms), while the child waits in its step to 56 ms: that step says -1
    world = _project(tmp_path, "child", "reset")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    assert _log(tmp_path, "child") == ["start 0.024 new", "child 0.032 0", "child 0.040 0", "child 0.048 0",
                                       "child -1"]
    sup = _log(tmp_path, "sup")
    assert sup[6] == "sup 0.000"  # the reset
    assert "child ended by 0.016: True" in sup


@BOTH_RUNTIMES
def test_a_robot_removed_in_the_step_it_was_imported_never_runs_and_nobody_waits_for_it(
    tmp_path: Path, isolation: str
) -> None:
    world = _project(tmp_path, "child", "at once")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    assert _log(tmp_path, "child") == []
    assert len(_log(tmp_path, "sup")) == 12


@BOTH_RUNTIMES
def test_a_world_given_by_a_relative_path_finds_the_imported_robots_controller(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, isolation: str
) -> None:
    # the threads runtime moves the working folder to the first controller's: the project is found all the same
    world = _project(tmp_path, "child")
    monkeypatch.chdir(tmp_path)
    assert run_world(world.relative_to(tmp_path), None, 0.1, isolation=isolation) == 0
    assert _log(tmp_path, "child")[:2] == ["start 0.024 new", "child 0.032 0"]
