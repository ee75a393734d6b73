"""Two supervisors restart the same robot's controller (webots-python-api.md Node.restartController; a robot runs one
controller at a time: restarting ends the running one, its step returns -1 (webots-devices.md §11.4), and starts
the one its controller field names).

Both supervisors ask in the same step: the robot then has one new controller, which runs from that step. Two
controllers of one robot ran side by side in a controller-process run (the second request came while the first
new controller was still starting in its process, and ending it missed it). Control: a request in a later step
restarts the controller again."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from dualtwin.webots.controller import Robot, Supervisor
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.runtime import Runtime
from tests.support.multi_worlds import lines_of, run_multi
from tests.support.quiet_worlds import quiet_supervisor

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


BOSSES_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF S1 Robot { name "s1" supervisor TRUE }
DEF S2 Robot { name "s2" supervisor TRUE }
DEF BOT Robot { name "bot" controller "a" }
"""


def test_a_restart_ends_the_controller_an_earlier_restart_is_still_starting() -> None:
    # The race of a controller-process run made certain: the runner's controller starter is replaced by one whose
    # controllers take part (bind to the run, as a new process's serving thread does) only when the test lets them.
    # s1 restarts BOT's controller; while that one is still starting, s2 names another controller in BOT's
    # controller field in the same step. BOT must end up with one controller, the one the field names now ("b"):
    # the one still starting is ended (its first step returns -1, webots-devices.md §11.4).
    sim = quiet_supervisor(BOSSES_WORLD).simulation
    s1_node, s2_node, bot = (rec.node for rec in sim.robots)
    runtime = Runtime(sim)
    runtime.expect(2)
    may_start = threading.Event()
    first_steps: dict[str, int] = {}
    threads: list[threading.Thread] = []

    def controller(name: str, node: SceneNode) -> None:
        may_start.wait(10.0)
        runtime.bind_thread(node)
        first_steps[name] = Robot(robot_node=node, runtime=runtime).step(8)
        runtime.thread_done()

    def starter(node: SceneNode) -> None:  # what the runner's starters do, with a start that takes its time
        runtime.expect_another(node)
        thread = threading.Thread(target=controller, args=(str(node.fields["controller"]), node), daemon=True)
        threads.append(thread)
        thread.start()

    runtime.controller_starter = starter

    def s2_controller() -> None:
        runtime.bind_thread(s2_node)
        s2 = Supervisor(robot_node=s2_node, runtime=runtime)
        s2.step(8)
        time.sleep(0.3)  # s1 has asked for its restart and stepped: the "a" controller is starting
        s2.getFromDef("BOT").getField("controller").setSFString("b")
        s2.step(8)
        s2.step(8)
        runtime.thread_done()

    s2_thread = threading.Thread(target=s2_controller, daemon=True)
    s2_thread.start()
    runtime.bind_thread(s1_node)
    s1 = Supervisor(robot_node=s1_node, runtime=runtime)
    s1.step(8)
    s1.getFromDef("BOT").restartController()
    threading.Timer(0.6, may_start.set).start()  # once s2's request is in
    s1.step(8)
    s1.step(8)
    runtime.thread_done()
    for thread in [s2_thread, *threads]:
        thread.join(10.0)
    assert first_steps == {"a": -1, "b": 0}
