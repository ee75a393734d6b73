"""``simulationReset()`` is done at the step of the supervisor that asked for it, as in Webots, where the request
travels with that supervisor's step message, and applied at the end of that step, once every controller has sent
its own: every controller's step then returns at t = 0, whichever stepped first. Another controller that reaches
its own ``step`` first must not carry it out (it used to: that step returned at t = 0 at once, and the
supervisor's step then ran on to 8 ms, or waited for ever for a controller that had already been answered), and
one that steps after the supervisor must not miss it. The order is forced here (one controller is inside its step
before the other steps), so the tests do not depend on which thread the machine runs first."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation
from dualtwin.webots.robot import Robot
from dualtwin.webots.runtime import Runtime
from dualtwin.webots.supervisor import Supervisor

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "boss" supervisor TRUE controller "<none>" }
Robot { translation 1 0 0 name "other" controller "<none>" }
"""


def _in_thread(call: Callable[[int], int], out: list[tuple[int, float]], sim: Simulation) -> threading.Thread:
    def run() -> None:
        out.append((call(8), sim.time))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def _reset_step(other_steps_first: bool) -> tuple[list[tuple[int, float]], list[tuple[int, float]]]:
    """(supervisor's answers, other's answers) of the step after a reset request, each (value, time)."""
    sim = Simulation(load_world_text(WORLD))
    try:
        runtime = Runtime(sim)
        sup = Supervisor(runtime=runtime, robot_node=sim.robots[0].node)
        other = Robot(runtime=runtime, robot_node=sim.robots[1].node)
        first: list[tuple[int, float]] = []
        thread = _in_thread(other.step, first, sim)
        sup.step(8)
        thread.join(5.0)
        assert first == [(0, 0.008)] and sim.time == 0.008  # both at 8 ms
        sup.simulationReset()
        sup_answers: list[tuple[int, float]] = []
        other_answers: list[tuple[int, float]] = []
        if other_steps_first:
            other_thread = _in_thread(other.step, other_answers, sim)
            time.sleep(0.3)  # it is inside its step now
            sup_thread = _in_thread(sup.step, sup_answers, sim)
        else:
            sup_thread = _in_thread(sup.step, sup_answers, sim)
            time.sleep(0.3)  # the supervisor is inside its step now
            other_thread = _in_thread(other.step, other_answers, sim)
        sup_thread.join(2.0)
        other_thread.join(2.0)
        runtime.finish()  # let whoever still waits go
        sup_thread.join(5.0)
        other_thread.join(5.0)
        return sup_answers, other_answers
    finally:
        sim.close()


def test_a_reset_is_done_at_the_requesting_supervisors_step_even_if_another_controller_steps_first() -> None:
    sup_answers, other_answers = _reset_step(other_steps_first=True)
    assert sup_answers[:1] == [(0, 0.0)]
    assert other_answers[:1] == [(0, 0.0)]  # the same step: every controller's answer comes after the reset


def test_a_reset_when_the_supervisor_steps_first() -> None:
    # the other order gives the same answers: the reset waits for every controller's step, as in Webots (it
    # used to be done at once, so a controller stepping after the supervisor went on to 8 ms)
    sup_answers, other_answers = _reset_step(other_steps_first=False)
    assert sup_answers[:1] == [(0, 0.0)]
    assert other_answers[:1] == [(0, 0.0)]
