"""Two supervisors restart the same robot's controller (webots-python-api.md Node.restartController; a robot runs one
controller at a time: restarting ends the running one, its step returns -1 (webots-devices.md §11.4), and starts
the one its controller field names).

Both supervisors ask in the same step: the robot then has one new controller, which runs from that step. Two
controllers of one robot ran side by side in a controller-process run (the second request came while the first
new controller was still starting in its process, and ending it missed it). Control: a request in a later step
restarts the controller again."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF A Robot { name "a" controller "counter" }
DEF S1 Robot { name "s1" controller "restarter" supervisor TRUE customData "2" }
DEF S2 Robot { name "s2" controller "restarter" supervisor TRUE customData "2 4" }
"""

COUNTER = """
from controller import Robot
robot = Robot()
started = robot.getTime()
steps = 0
while robot.step(8) != -1:
    steps += 1
print(f"a started at {started * 1000:.0f} ms ran {steps} steps")
"""

RESTARTER = """
from controller import Supervisor
supervisor = Supervisor()
restarts = [int(n) for n in supervisor.getCustomData().split()]
steps = 0
while supervisor.step(8) != -1:
    steps += 1
    if steps in restarts:
        supervisor.getFromDef("A").restartController()
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_two_restarts_of_one_robot_in_one_step_start_one_controller(tmp_path: Path, isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"counter": COUNTER, "restarter": RESTARTER}, isolation, duration_s=0.08)
    # a run of 80 ms in steps of 8 ms: restarts asked after step 2 (16 ms, by both) and step 4 (32 ms, by s2). The
    # first controller's third step returns -1 (2 steps counted), the one started at 16 ms counts 2 (16 -> 32 ms),
    # the one started at 32 ms counts 5 (32 -> 72 ms): its sixth step reaches 80 ms, the run's end, and says -1
    assert sorted(lines_of(lines, "a ")) == ["a started at 0 ms ran 2 steps", "a started at 16 ms ran 2 steps",
                                             "a started at 32 ms ran 5 steps"]
