"""Controllers × world lifecycle compositions: what a controller sees of nodes and of the other controllers as
robots are removed, imported, reset and run with and without synchronisation.

References: webots-python-api.md (Supervisor.getFromId "unique node id", Node.remove "delete"),
webots-on-ode.md §6 (simulationReset: added nodes removed) and §1.6 (a step waits for the synchronized
controllers), webots-devices.md §11.3-11.4.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from dualtwin.webots.controller import Robot, Supervisor
from dualtwin.webots.runner import run_world
from dualtwin.webots.runtime import Runtime
from tests.support.quiet_worlds import quiet_supervisor
from tests.support.webots_scene import write_controllers

TS = 8
NODES_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BOSS Robot {{ name "boss" supervisor TRUE }}
DEF BOT Robot {{ translation 1 0 0 name "bot" children [ DEF INNER Solid {{ name "inner" }} ] }}
DEF BOX Solid {{ translation 0 2 0 name "box" }}
"""


def _project(folder: Path, world_text: str, controllers: dict[str, str]) -> Path:
    """A Webots project in ``folder``: ``worlds/w.wbt`` holding ``world_text`` and the ``controllers`` (name ->
    script, :func:`write_controllers`); returns the world's path."""
    write_controllers(folder, controllers)
    (folder / "worlds").mkdir()
    world = folder / "worlds" / "w.wbt"
    world.write_text(world_text)
    return world


def test_get_from_id_no_longer_finds_a_removed_node_or_its_descendants() -> None:
    # Node.remove deletes the node: as getFromDef, getFromId then finds neither it nor what it held, while the
    # nodes left in the world are still found by their ids (ids are never given to another node)
    sup = quiet_supervisor(NODES_WORLD)
    bot, inner, box = (sup.getFromDef(name) for name in ("BOT", "INNER", "BOX"))
    ids = {name: node.getId() for name, node in (("BOT", bot), ("INNER", inner), ("BOX", box))}
    assert sup.getFromId(ids["BOT"]) == bot and sup.getFromId(ids["INNER"]) == inner
    bot.remove()
    assert sup.getFromDef("BOT") is None
    assert sup.getFromId(ids["BOT"]) is None and sup.getFromId(ids["INNER"]) is None
    sup.step(TS)
    assert sup.getFromId(ids["BOT"]) is None and sup.getFromId(ids["INNER"]) is None
    assert sup.getFromId(ids["BOX"]) == box and sup.getFromId(sup.getSelf().getId()) == sup.getSelf()


def test_get_from_id_no_longer_finds_a_node_the_reset_took_out() -> None:
    # simulationReset removes the nodes added since the load (webots-on-ode.md §6, webots-devices.md §11.3)
    sup = quiet_supervisor(NODES_WORLD)
    children = sup.getRoot().getField("children")
    children.importMFNodeFromString(-1, 'DEF ADDED Solid { translation 0 -2 0 name "added" }')
    added = sup.getFromDef("ADDED")
    assert added is not None and sup.getFromId(added.getId()) == added
    sup.step(TS)
    sup.simulationReset()
    sup.step(TS)  # the reset is applied at the end of this step
    assert sup.getFromDef("ADDED") is None and sup.getFromId(added.getId()) is None


SYNCED = """
import os
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
with open(os.path.join(ROOT, "synced.txt"), "w") as log:
    for _ in range(5):
        log.write(f"{robot.step(8)} {robot.getTime():.3f}\\n")
open(os.path.join(ROOT, "done"), "w").close()
"""
# waits, without stepping, until the synchronized controller has made all its steps (a bound of 30 s of real time
# only so that a run that holds the synchronized robot still ends, and the test then fails)
UNSYNCED = """
import os, time
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
since = time.monotonic()
while not os.path.exists(os.path.join(ROOT, "done")) and time.monotonic() - since < 30:
    time.sleep(0.01)
with open(os.path.join(ROOT, "unsynced.txt"), "w") as log:
    log.write(f"saw done {os.path.exists(os.path.join(ROOT, 'done'))}\\n")
    log.write(f"step {robot.step(8)}\\n")
"""
SYNC_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "synced" controller "synced" }
Robot { translation 1 0 0 name "unsynced" controller "unsynced" synchronization FALSE }
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_robot_without_synchronization_does_not_hold_the_synchronized_ones(tmp_path: Path,
                                                                              isolation: str) -> None:
    # webots-on-ode.md §1.6 step 1: each basic step waits until every *synchronized* controller has sent its
    # request; a robot whose synchronization is FALSE is not waited for (webots-devices.md §11.4: its step returns
    # without holding the others). The synchronized controller steps 8 ms five times: 8, 16, 24, 32, 40 ms, all
    # while the other one has not stepped yet; that one's own step, the only controller left, then returns 0.
    world = _project(tmp_path, SYNC_WORLD, {"synced": SYNCED, "unsynced": UNSYNCED})
    # no step timeout: what is tested is that nothing waits for the controller that does not step
    assert run_world(world, None, None, step_timeout_s=0, isolation=isolation) == 0
    assert (tmp_path / "synced.txt").read_text().splitlines() == [f"0 {t / 1000:.3f}" for t in range(8, 41, 8)]
    assert (tmp_path / "unsynced.txt").read_text().splitlines() == ["saw done True", "step 0"]


LOOPING = """
import os
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
steps = 0
# steps until the unsynchronized controller says it has been idle (a bound on the steps only so that a run in
# which it was stopped still ends)
while not os.path.exists(os.path.join(ROOT, "idled")) and steps < 1_000_000:
    assert robot.step(8) == 0
    steps += 1
open(os.path.join(ROOT, "done"), "w").close()
"""
IDLE = """
import os, time
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
time.sleep(1.5)  # three step timeouts without a step
open(os.path.join(ROOT, "idled"), "w").close()
while not os.path.exists(os.path.join(ROOT, "done")):
    time.sleep(0.01)
with open(os.path.join(ROOT, "idle.txt"), "w") as log:
    log.write(f"step {robot.step(8)}\\n")
"""


def test_the_step_timeout_does_not_stop_a_controller_nothing_waits_for(tmp_path: Path) -> None:
    # the step timeout is ours (Webots has none): it stops a controller the simulation waits for in vain. Nothing
    # waits for a robot whose synchronization is FALSE (webots-on-ode.md §1.6 step 1) while a synchronized
    # controller steps, so that one idling for three timeouts is not stopped and the run ends well (exit 0)
    world = _project(tmp_path, SYNC_WORLD, {"synced": LOOPING, "unsynced": IDLE})
    assert run_world(world, None, None, step_timeout_s=0.5) == 0
    assert (tmp_path / "idle.txt").read_text().splitlines() == ["step 0"]


def test_a_step_answered_before_its_robot_is_removed_keeps_its_answer_however_late_its_thread_wakes() -> None:
    # webots-on-ode.md §6: step(ms) returns with the values of its end; webots-devices.md §11.4: 0 for a
    # synchronized robot. BOT's controller steps 48 ms at once; the supervisor steps 8 ms six times, which answers
    # BOT's step at 48 ms, then removes BOT and steps on to the run's end (0.1 s) while BOT's thread has not woken
    # (the supervisor's thread keeps the runtime's lock, as a busy machine may schedule it). BOT's step still says
    # 0 and its getTime 0.048: what the simulation answered at 48 ms, not the end of the run it woke at.
    sim = quiet_supervisor(NODES_WORLD).simulation
    boss, bot = (rec.node for rec in sim.robots)
    runtime = Runtime(sim, 0.1)
    runtime.expect(2)
    seen: dict[str, float] = {}

    def bot_controller() -> None:
        runtime.bind_thread(bot)
        robot = Robot(robot_node=bot, runtime=runtime)
        seen["step"] = robot.step(48)
        seen["time"] = robot.getTime()
        runtime.thread_done()

    thread = threading.Thread(target=bot_controller, daemon=True)
    thread.start()
    runtime.bind_thread(boss)
    sup = Supervisor(robot_node=boss, runtime=runtime)
    assert sup.step(TS) == 0  # both controllers wait in their steps: BOT's asks for 48 ms
    with runtime._cond:  # BOT's thread cannot wake before the run is over
        for _ in range(5):
            assert sup.step(TS) == 0
        assert sup.getTime() == pytest.approx(0.048)
        sup.getFromDef("BOT").remove()
        while sup.step(TS) != -1:
            pass
    thread.join(timeout=10.0)
    assert not thread.is_alive()
    assert seen == {"step": 0, "time": pytest.approx(0.048)}
    runtime.thread_done()


RESETTER = """
import os
from controller import Supervisor
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
sup = Supervisor()
with open(os.path.join(ROOT, "sup.txt"), "w") as log:
    for i in range(3):
        log.write(f"{sup.step(16)} {sup.getTime():.3f}\\n")
        if i == 0:
            sup.simulationReset()
"""
STEPPER = """
import os
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
with open(os.path.join(ROOT, "bot.txt"), "w") as log:
    for _ in range(6):
        log.write(f"{robot.step(8)} {robot.getTime():.3f}\\n")
"""
RESET_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "boss" controller "resetter" supervisor TRUE }
Robot { translation 1 0 0 name "bot" controller "stepper" }
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_reset_waits_for_the_end_of_the_longer_step_that_carries_it(tmp_path: Path, isolation: str) -> None:
    # webots-devices.md §11.3 / webots-on-ode.md §6: simulationReset is applied at the end of the step that carries
    # the request (time passes in that step). The supervisor steps 16 ms and asks at 16 ms; its step to 32 ms
    # carries the request while the robot steps 8 ms twice (24, 32 ms); at 32 ms the world is reset and both steps
    # return at t = 0. Then the supervisor steps to 16 ms while the robot steps to 8 and 16 ms.
    world = _project(tmp_path, RESET_WORLD, {"resetter": RESETTER, "stepper": STEPPER})
    assert run_world(world, None, None, isolation=isolation) == 0
    assert (tmp_path / "sup.txt").read_text().splitlines() == ["0 0.016", "0 0.000", "0 0.016"]
    assert (tmp_path / "bot.txt").read_text().splitlines() == [
        "0 0.008", "0 0.016", "0 0.024", "0 0.000", "0 0.008", "0 0.016"]


TWO_SUPERVISORS = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ name "a" supervisor TRUE }}
Robot {{ translation 0 2 0 name "b" supervisor TRUE }}
"""


def test_simulation_get_mode_reads_the_mode_of_the_last_step_answer() -> None:
    # webots-devices.md §11.2: simulationGetMode() returns the value cached at the last step. Both supervisors'
    # steps are answered at 8 ms in FAST mode; then A pauses the simulation before B's thread has woken (A keeps the
    # runtime's lock). B still reads FAST (2): the pause reaches it with its next step, not in between.
    sim = quiet_supervisor(TWO_SUPERVISORS).simulation
    a, b = (rec.node for rec in sim.robots)
    runtime = Runtime(sim)
    runtime.expect(2)
    seen: dict[str, int] = {}

    def b_controller() -> None:
        runtime.bind_thread(b)
        sup_b = Supervisor(robot_node=b, runtime=runtime)
        seen["step"] = sup_b.step(TS)
        seen["mode"] = sup_b.simulationGetMode()
        runtime.thread_done()

    thread = threading.Thread(target=b_controller, daemon=True)
    runtime.bind_thread(a)
    sup_a = Supervisor(robot_node=a, runtime=runtime)
    thread.start()
    # until B waits inside its step: A's step is then the one that runs the simulation (a fixed sleep let a slow
    # machine start A's step first, B's step then ran the simulation and read the mode before A paused it)
    while thread.is_alive() and not any(c.waiting for c in list(runtime._clients)):
        time.sleep(0.001)
    with runtime._cond:  # B's thread cannot wake before A has paused
        assert sup_a.step(TS) == 0
        sup_a.simulationSetMode(Supervisor.SIMULATION_MODE_PAUSE)
    thread.join(timeout=10.0)
    assert not thread.is_alive()
    assert seen == {"step": 0, "mode": Supervisor.SIMULATION_MODE_FAST}
    runtime.thread_done()


QUITTER = """
import os, time
from controller import Supervisor
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
sup = Supervisor()
for _ in range(3):
    sup.step(8)
sup.{end}
# waits without stepping for the other controller to end (a bound of 10 s of real time only so that a run in which
# it never ends still does, and the test then fails)
since = time.monotonic()
while not os.path.exists(os.path.join(ROOT, "bot.txt")) and time.monotonic() - since < 10:
    time.sleep(0.01)
with open(os.path.join(ROOT, "sup.txt"), "w") as log:
    log.write(f"saw the robot end {os.path.exists(os.path.join(ROOT, 'bot.txt'))}\\n")
    log.write(f"step {sup.step(8)}\\n")
"""
QUIT_STEPPER = """
import os
from controller import Robot
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
robot = Robot()
while (value := robot.step(8)) != -1:
    pass
with open(os.path.join(ROOT, "bot.txt.part"), "w") as log:
    log.write(f"{value} {robot.getTime():.3f}\\n")
os.replace(os.path.join(ROOT, "bot.txt.part"), os.path.join(ROOT, "bot.txt"))
"""
EMPTY_WORLD = "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n"
QUIT_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "boss" controller "quitter" supervisor TRUE }
Robot { translation 1 0 0 name "bot" controller "stepper" }
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
@pytest.mark.parametrize(("end", "status"), [("simulationQuit(3)", 3), ("worldLoad(os.path.join(ROOT, 'worlds', "
                                                                         "'empty.wbt'))", 0)])
def test_quit_and_world_load_end_the_other_controllers_at_once(tmp_path: Path, isolation: str, end: str,
                                                               status: int) -> None:
    # webots-devices.md §11.4: step returns -1 when Webots is about to terminate the controller (quit, world
    # load); simulationQuit(status) quits with that exit status (webots-python-api.md). The supervisor quits (or
    # loads a world without controllers) at 24 ms and does not step again until the robot's controller has ended:
    # the robot's step waiting at 24 ms says -1 then (not once the supervisor steps); the exit status is 3 (0).
    world = _project(tmp_path, QUIT_WORLD, {"quitter": QUITTER.replace("{end}", end), "stepper": QUIT_STEPPER})
    (tmp_path / "worlds" / "empty.wbt").write_text(EMPTY_WORLD)
    assert run_world(world, None, 1.0, step_timeout_s=30, isolation=isolation) == status
    assert (tmp_path / "bot.txt").read_text().splitlines() == ["-1 0.024"]
    assert (tmp_path / "sup.txt").read_text().splitlines() == ["saw the robot end True", "step -1"]


FLAGS_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BOSS Robot {{ name "boss" supervisor TRUE }}
DEF SYNCED Robot {{ translation 1 0 0 name "synced" }}
DEF UNSYNCED Robot {{ translation 2 0 0 name "unsynced" synchronization FALSE }}
"""


def test_the_step_timeout_asks_what_the_synchronisation_goes_by_after_a_supervisor_writes_the_field() -> None:
    # webots-on-ode.md §1.6 step 1: a step waits for the synchronized controllers. The runtime takes a robot's
    # synchronization when its controller makes its Robot, and waits accordingly; the step timeout (ours) asks
    # Runtime.waits_for whether the simulation waits for a controller. A supervisor then writes both fields the
    # other way: SYNCED's controller is still waited for (the boss's step blocks until SYNCED steps), so the
    # timeout must still watch it; UNSYNCED's is still not waited for while SYNCED drives the simulation, so its
    # idling must not be stopped. (The reference is silent on a write at run time; the two must agree.)
    sup = quiet_supervisor(FLAGS_WORLD)
    runtime = Runtime(sup.simulation)
    nodes = [rec.node for rec in sup.simulation.robots]  # BOSS, SYNCED, UNSYNCED
    robots = [Robot(robot_node=node, runtime=runtime) for node in nodes]
    assert runtime.waits_for(nodes[1]) and not runtime.waits_for(nodes[2])
    sup.getFromDef("SYNCED").getField("synchronization").setSFBool(False)
    sup.getFromDef("UNSYNCED").getField("synchronization").setSFBool(True)
    assert runtime.waits_for(nodes[1]) and not runtime.waits_for(nodes[2])
    del robots  # (held until here: a Robot dropped before leaves the synchronisation)
