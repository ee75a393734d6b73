"""A robot's ``customData`` seen from its own controller and from a supervisor's (webots-python-api.md Robot:
getCustomData/setCustomData read and write the Robot.customData field; webots-on-ode.md §6: a controller sees the
world through its steps, whose answer brings what changed).

Webots' libController keeps the robot's custom data as a string of its own: ``setCustomData`` replaces it at
once, and a supervisor's write of the field reaches the robot in the answer of the step the write was applied in
(Webots sends the new field value with that answer), so between two steps the robot reads what its last step
brought, whatever another controller does meanwhile.

The robot waits a real time before it reads, long enough for the supervisor's write to have been made (no timing
is asserted: the wait only orders the two controllers' calls)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF A Robot { name "a" controller "robot" customData "init" }
DEF S Robot { name "s" controller "writer" supervisor TRUE }
"""

ROBOT = """
import time
from controller import Robot
robot = Robot()
robot.step(8)
time.sleep(0.4)  # the supervisor writes the field meanwhile (its step 2 is not sent yet)
print("a between steps:", robot.getCustomData())
robot.step(8)
print("a after its next step:", robot.getCustomData())
robot.setCustomData("mine")
print("a after its own set:", robot.getCustomData())
robot.step(8)
"""

WRITER = """
from controller import Supervisor
supervisor = Supervisor()
field = supervisor.getFromDef("A").getField("customData")
supervisor.step(8)
field.setSFString("fromS")
supervisor.step(8)
supervisor.step(8)
print("s reads:", field.getSFString())
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_supervisors_write_of_customdata_reaches_the_robot_with_its_next_step(tmp_path: Path,
                                                                                isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"robot": ROBOT, "writer": WRITER}, isolation)
    # the write is made after step 1 (0 -> 8 ms) answered both: the robot's step-1 answer said "init"; step 2
    # (8 -> 16 ms) applies the write and its answer brings "fromS"
    assert lines_of(lines, "a ") == ["a between steps: init", "a after its next step: fromS",
                                     "a after its own set: mine"]
    # control: the robot's own write reaches the field, which the supervisor reads once both stepped again
    assert lines_of(lines, "s ") == ["s reads: mine"]
