"""A supervisor restarts a robot's controller, as Webots R2023b does: ``Node.restartController()``, or a new value
of the Robot's ``controller`` field. The request acts at the supervisor's next step: the running controller's
step returns -1 (it then ends as after any -1) and the controller the field names now starts in its place and
steps in lock-step with the others from that step; the clock goes on, and the new controller finds none of the
robot's devices enabled. ``<extern>``/``<none>`` start nothing; the same value again changes nothing; on a node
that is not a Robot, one error line and nothing else. Both runtimes (processes and threads) do the same.

Expectations by hand (basicTimeStep 8 ms, every controller steps 8 ms, run 0.1 s): each controller instance
logs into ``<script>_<start ms>.txt`` at the project's root. The supervisor restarts BOT after its 3rd step
(t = 24 ms): ``child_0`` steps to 8, 16, 24, then its step to 32 says -1; ``child_24`` starts at 24 ms, its GPS
disabled, and steps to 32, 40, 48. After the 6th step (48 ms) the field becomes "other": ``child_24`` gets -1
and ``other_48`` steps to 56, 64, 72; setting "other" again at 64 ms changes nothing; "<extern>" at 72 ms ends
it (-1) and starts nothing. The supervisor steps on to 96 ms.

Also: a ``--controller`` override is what a restart runs again while the field is unchanged; a supervisor may
restart itself (its next step says -1, a fresh one starts at that time); a robot imported and restarted twice
in one step runs one controller.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

SUPERVISOR = """
    import os
    from controller import Supervisor
    ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    sup = Supervisor()
    bot = sup.getFromDef("BOT")
    with open(os.path.join(ROOT, "sup.txt"), "w") as log:
        for i in range(12):
            if sup.step(8) == -1:
                break
            log.write(f"sup {sup.getTime():.3f}\\n")
            if "{plan}" == "restart":
                if i == 2:
                    bot.restartController()
                    sup.getFromDef("BOX").restartController()  # not a Robot: an error line, nothing else
                if i == 5:
                    bot.getField("controller").setSFString("other")
                if i == 7:
                    bot.getField("controller").setSFString("other")  # the same value: no restart
                if i == 8:
                    bot.getField("controller").setSFString("<extern>")
"""
CHILD = """
    import os
    from controller import Robot
    NAME = os.path.splitext(os.path.basename(__file__))[0]
    ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    robot = Robot()
    gps = robot.getDevice("gps")
    start = robot.getTime()
    # "x": a second controller of the same robot started at the same time would fail here (exit code 1)
    with open(os.path.join(ROOT, f"{NAME}_{round(start * 1000)}.txt"), "x") as log:
        log.write(f"start {start:.3f} gps period {gps.getSamplingPeriod()}\\n")
        gps.enable(8)
        ms = round(start * 1000)
        while True:
            if robot.step(8) == -1:
                log.write("-1\\n")
                break
            # the step's own time, counted here (getTime reads the same: the time of the step's answer, even once
            # the simulation no longer waits for this controller)
            ms += 8
            log.write(f"{ms / 1000:.3f} {gps.getValues()[0]:.1f}\\n")
"""
WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "boss" controller "sup" supervisor TRUE }
DEF BOT Robot { translation 1 0 0 name "bot" controller "child" children [ GPS { } ] }
DEF BOX Solid { translation 0 2 0 }
"""


def _project(tmp_path: Path, plan: str) -> Path:
    scripts = {"sup": SUPERVISOR.replace("{plan}", plan), "child": CHILD, "other": CHILD}
    for name, script in scripts.items():
        folder = tmp_path / "controllers" / name
        folder.mkdir(parents=True)
        (folder / f"{name}.py").write_text(textwrap.dedent(script))
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(WORLD)
    return world


def _logs(tmp_path: Path) -> dict[str, list[str]]:
    return {p.stem: p.read_text().splitlines() for p in sorted(tmp_path.glob("*.txt"))}


def _steps(start_ms: int, end_ms: int) -> list[str]:
    return [f"{t / 1000:.3f} 1.0" for t in range(start_ms, end_ms + 1, 8)]


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_restart_and_controller_field_changes_restart_the_controller_in_lock_step(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], isolation: str
) -> None:
    world = _project(tmp_path, "restart")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    err = capsys.readouterr().err
    logs = _logs(tmp_path)
    assert logs["sup"] == [f"sup {t / 1000:.3f}" for t in range(8, 97, 8)]  # the supervisor was never held up
    assert logs["child_0"] == ["start 0.000 gps period 0", *_steps(8, 24), "-1"]
    # restarted at 24 ms: time goes on, the GPS the former controller enabled is disabled for the new one
    assert logs["child_24"] == ["start 0.024 gps period 0", *_steps(32, 48), "-1"]
    assert logs["other_48"] == ["start 0.048 gps period 0", *_steps(56, 72), "-1"]
    assert set(logs) == {"sup", "child_0", "child_24", "other_48"}  # "<extern>" and the same value start nothing
    assert err.count("Error: wb_supervisor_node_restart_controller() can only be called on a Robot node.") == 1
    # no forced termination, no "not started" (the threads runtime's one warning: its shared working folder)
    assert [line for line in err.splitlines() if "Warning" in line and "different folders" not in line] == []


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_without_a_restart_the_controller_runs_to_the_end(tmp_path: Path, isolation: str) -> None:
    # the control for the test above: the same world and scripts, no request
    world = _project(tmp_path, "none")
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    logs = _logs(tmp_path)
    assert logs["child_0"] == ["start 0.000 gps period 0", *_steps(8, 96), "-1"]
    assert set(logs) == {"sup", "child_0"}


def test_a_restart_keeps_the_controller_override_while_the_field_names_the_same_controller(tmp_path: Path) -> None:
    # `--controller` replaced BOT's "child": restartController() runs the replacement again; a new field value
    # ("other") is looked up in the project as at load
    world = _project(tmp_path, "restart")
    override = tmp_path / "elsewhere" / "scripts" / "child.py"  # the same name as BOT's field, outside the project
    override.parent.mkdir(parents=True)
    override.write_text(textwrap.dedent(CHILD).replace("NAME = os.path.splitext(os.path.basename(__file__))[0]",
                                                       'NAME = "override"'))
    assert run_world(world, override, 0.1) == 0
    logs = _logs(tmp_path)
    assert logs["override_0"] == ["start 0.000 gps period 0", *_steps(8, 24), "-1"]
    assert logs["override_24"] == ["start 0.024 gps period 0", *_steps(32, 48), "-1"]
    assert logs["other_48"] == ["start 0.048 gps period 0", *_steps(56, 72), "-1"]
    assert set(logs) == {"sup", "override_0", "override_24", "other_48"}


SELF_RESTARTING = """
    import os
    from controller import Supervisor
    ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    sup = Supervisor()
    start = round(sup.getTime() * 1000)
    with open(os.path.join(ROOT, f"sup_{start}.txt"), "w") as log:
        for i in range(6):
            if sup.step(8) == -1:
                log.write(f"-1 at step {i + 1}\\n")
                break
            if i == 2:
                sup.getSelf().restartController()  # its own: this step says -1, a fresh one starts
            if i == 1 and start == 0:  # imported and restarted twice in one step: one controller starts
                sup.getRoot().getField("children").importMFNodeFromString(
                    -1, 'DEF NEW Robot { translation 1 0 0 name "new" controller "child" children [ GPS { } ] }')
                sup.getFromDef("NEW").restartController()
                sup.getFromDef("NEW").restartController()
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_supervisor_restarting_itself_and_a_robot_asked_for_twice_in_one_step(
    tmp_path: Path, isolation: str
) -> None:
    world = _project(tmp_path, "none")
    (tmp_path / "controllers" / "sup" / "sup.py").write_text(textwrap.dedent(SELF_RESTARTING))
    (tmp_path / "worlds" / "w.wbt").write_text(WORLD.replace('controller "child"', 'controller "<none>"'))
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    logs = _logs(tmp_path)
    # each supervisor restarts itself after its 3rd step: its 4th says -1 and the next starts 24 ms later
    assert {name: logs[name] for name in logs if name.startswith("sup")} == {
        "sup_0": ["-1 at step 4"], "sup_24": ["-1 at step 4"], "sup_48": ["-1 at step 4"],
        "sup_72": ["-1 at step 4"], "sup_96": ["-1 at step 1"]}
    # the robot imported at 16 ms runs one controller, from then to the end of the run
    assert logs["child_16"] == ["start 0.016 gps period 0", *_steps(24, 96), "-1"]
    assert set(logs) == {"sup_0", "sup_24", "sup_48", "sup_72", "sup_96", "child_16"}
