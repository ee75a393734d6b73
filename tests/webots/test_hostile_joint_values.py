"""Hostile values in joint parameters, written in the world or by a supervisor at run time: the simulation goes on
(Webots' field checks reset the value, with a warning), no exception comes out of a step, no ODE assertion ends
the process (those cases run in a child process).

S = /work/shared/reference/webots-on-ode.md. S §4.5: the spring and damper rows take CFM = 1/(h·K + B) and
ERP = h·K/(h·K + B), and staticFriction is ≥ 0; Webots resets a negative springConstant, dampingConstant,
staticFriction or suspension constant to 0 with a warning (its joint parameters' field checks), which also keeps
h·K + B from being 0 (it was: a ZeroDivisionError out of the load or of the step after the edit)."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from dualtwin.webots.runner import run_world
from tests.support.hinge_arm import BOB, TS, G, load_arm
from tests.support.world_runs import run_world_cli

HEAVY = "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 100 }"
# h·K + B = 0.004·(−250) + 1 = 0 at a 4 ms step (hand computation)
K_ZERO_SUM = -250.0

JOINTS = {
    "hinge": "HingeJoint {{ jointParameters DEF P HingeJointParameters {{ axis 0 1 0 {p} }} endPoint {end} }}",
    "slider": "SliderJoint {{ jointParameters DEF P JointParameters {{ axis 1 0 0 {p} }} endPoint {end} }}",
    "hinge2": "Hinge2Joint {{ jointParameters DEF P HingeJointParameters {{ axis 0 1 0 {p} }} endPoint {end} }}",
    "ball": "BallJoint {{ jointParameters DEF P BallJointParameters {{ {p} }} endPoint {end} }}",
}


def _sup(kind: str, params: str) -> tuple[Supervisor, list[str]]:
    """The arm with a ``kind`` joint whose parameters node (DEF P) holds ``params``, and the load's warnings."""
    sim, sup = load_arm(JOINTS[kind].format(p=params, end=BOB.format(t="0.5 0 0.1")), gravity=G)
    return sup, sim.build_warnings


def _edit(sup: Supervisor, name: str, value: float) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sup.getFromDef("P").getField(name).setSFFloat(value)
        for _ in range(10):
            assert sup.step(TS) != -1
    return [str(w.message) for w in caught]


CASES = [("hinge", "springConstant", "dampingConstant 1"), ("hinge", "dampingConstant", "springConstant 250"),
         ("slider", "springConstant", "dampingConstant 1"), ("hinge2", "springConstant", "dampingConstant 1"),
         ("ball", "springConstant", "dampingConstant 1"),
         ("hinge2", "suspensionSpringConstant", "suspensionDampingConstant 1")]


@pytest.mark.parametrize(("kind", "name", "other"), CASES)
def test_a_negative_constant_edited_at_run_time_is_reset_to_zero(kind: str, name: str, other: str) -> None:
    sup, _ = _sup(kind, other)
    assert sup.step(TS) != -1
    value = K_ZERO_SUM if "Spring" in name or name == "springConstant" else -1.0
    messages = _edit(sup, name, value)
    assert sup.getFromDef("P").getField(name).getSFFloat() == 0.0
    assert any(f"{name} {value:g} is negative; reset to 0" in m for m in messages), messages


@pytest.mark.parametrize(("kind", "name", "other"), CASES)
def test_a_negative_constant_in_the_world_is_reset_to_zero(kind: str, name: str, other: str) -> None:
    value = K_ZERO_SUM if "Spring" in name or name == "springConstant" else -1.0
    sup, messages = _sup(kind, f"{other} {name} {value:g}")
    assert any(f"{name} {value:g} is negative; reset to 0" in m for m in messages), messages
    assert sup.getFromDef("P").getField(name).getSFFloat() == 0.0
    for _ in range(10):
        assert sup.step(TS) != -1


def test_a_negative_static_friction_is_reset_to_zero() -> None:
    # S §4.5: staticFriction ≥ 0 (a negative one was passed to ODE as the motor row's force limit)
    sup, messages = _sup("hinge", "staticFriction -3")
    assert any("staticFriction -3 is negative; reset to 0" in m for m in messages), messages
    assert any("staticFriction -2 is negative" in m for m in _edit(sup, "staticFriction", -2.0))
    assert sup.getFromDef("P").getField("staticFriction").getSFFloat() == 0.0


def test_imported_parameters_with_a_negative_constant_are_reset_to_zero() -> None:
    # a parameters node imported into an empty field is checked as at load
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, sup = load_arm("HingeJoint { endPoint " + BOB.format(t="0.5 0 0") + " }", gravity=G)
    joint: Any = sup.getSelf().getField("children").getMFNode(0)
    assert sup.step(TS) != -1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        joint.getField("jointParameters").importSFNodeFromString(
            "HingeJointParameters { axis 0 1 0 springConstant -250 dampingConstant 1 }")
        for _ in range(10):
            assert sup.step(TS) != -1
    assert any("springConstant -250 is negative" in str(w.message) for w in caught)


def test_cli_runs_a_world_with_a_negative_spring(tmp_path: Path) -> None:
    world = ("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 }\n"
             'Robot { controller "<extern>" children [ HingeJoint { jointParameters HingeJointParameters { '
             "axis 0 1 0 springConstant -250 dampingConstant 1 } endPoint " + BOB.format(t="0.5 0 0") + " } ] }\n")
    controller = "from controller import Robot\nr = Robot()\nfor _ in range(20):\n    r.step(4)\nprint('DONE')\n"
    run = run_world_cli(tmp_path, "spring", world, controller)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    assert "DONE" in run.stdout and "springConstant -250 is negative; reset to 0" in run.stderr


@pytest.mark.parametrize("joint", [
    "HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 position 1e308 } device [ RotationalMotor { } ]",
    "Hinge2Joint { jointParameters2 JointParameters { position -1e308 } device2 [ RotationalMotor { } ]",  # (2 bodies)
    "BallJoint { jointParameters BallJointParameters { position 1e308 }",
])
def test_a_joint_loaded_at_a_huge_position_runs(tmp_path: Path, joint: str) -> None:
    # Unwrapping the read angle about the last position (§4.2) looped for ever: about 1e308, center ± π is the
    # centre itself. Whole turns cannot be counted at such a position: the angle is read as it is. (A child
    # process: the old code hung; its timeout is only a hang guard.)
    world = ("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 }\n"
             f'Robot {{ controller "<extern>" {HEAVY} children [ {joint} endPoint ' + BOB.format(t="0.5 0 0")
             + " } ] }\n")
    controller = "from controller import Robot\nr = Robot()\nfor _ in range(20):\n    r.step(4)\nprint('DONE')\n"
    run = run_world_cli(tmp_path, "huge", world, controller)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    assert "DONE" in run.stdout


SLIDER_IMPORT = """from controller import Supervisor
s = Supervisor()
s.step(4)
s.getFromDef("J").getField("jointParameters").importSFNodeFromString("JointParameters { axis 1e308 1e308 -1e308 }")
for _ in range(20):
    s.step(4)
print("DONE", " ".join(repr(v) for v in s.getFromDef("END").getPosition()))
"""


@pytest.mark.parametrize("params", ["jointParameters JointParameters { axis 1e308 1e308 0 }", ""])
def test_a_slider_axis_of_huge_components_keeps_its_direction(tmp_path: Path, params: str) -> None:
    # S §4.3: Webots normalises the slider axis; the length of (1e308, 1e308, 0) overflows, and the axis came out
    # zero, on which ODE aborted the whole process (the world is run in a child process). The direction is kept:
    # in zero gravity nothing moves the endPoint, loaded (1st case) or with the parameters imported (2nd).
    world = ("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 gravity 0 }\n"
             f'Robot {{ controller "<extern>" supervisor TRUE {HEAVY} children [ DEF J SliderJoint {{ {params} '
             "endPoint DEF END " + BOB.format(t="0.5 0 0") + " } ] }\n")
    run = run_world_cli(tmp_path, "slider", world, SLIDER_IMPORT if not params else SLIDER_IMPORT.replace(
        's.getFromDef("J").getField("jointParameters").importSFNodeFromString', "print"))
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    done = next(line for line in run.stdout.splitlines() if line.startswith("DONE"))
    assert [float(v) for v in done.split()[1:]] == pytest.approx([0.5, 0.0, 0.0], abs=1e-9)


BLOW_WORLD = ("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 }\n"
              'Robot { controller "<extern>" supervisor TRUE children [ SliderJoint { jointParameters DEF P '
              "JointParameters { axis 1 0 0 } endPoint " + BOB.format(t="0 0 0") + " } ] }\n")
BLOW_CONTROLLER = ("from controller import Supervisor\ns = Supervisor()\ns.step(4)\n"
                   's.getFromDef("P").getField("position").setSFFloat(1e308)\nwhile s.step(4) != -1:\n    pass\n')
BLOW_LINE = "Error: non-finite or diverging body state at t=0.008s; reset() to recover"


def test_a_run_whose_physics_blows_up_ends_on_one_line(tmp_path: Path) -> None:
    # S §4.1: a slider's position edited to 1e308 teleports its endPoint 1e308 m away, and the next step reports
    # the state diverged: step() raises SimulationUnstable in the controller, which can catch it (see
    # test_controller_processes.py); let through, the run ends with its message on one line, not a traceback
    run = run_world_cli(tmp_path, "blow", BLOW_WORLD, BLOW_CONTROLLER)
    assert run.returncode == 1
    assert run.stderr.strip().splitlines() == [BLOW_LINE], run.stderr


def test_a_run_whose_physics_blows_up_ends_on_one_line_in_threads(tmp_path: Path,
                                                                 capfd: pytest.CaptureFixture[str]) -> None:
    # the same in the threads isolation (no ODE abort here: the divergence is found after the step)
    (tmp_path / "blow.wbt").write_text(BLOW_WORLD)
    (tmp_path / "blow.py").write_text(BLOW_CONTROLLER)
    assert run_world(tmp_path / "blow.wbt", tmp_path / "blow.py", isolation="threads") == 1
    assert capfd.readouterr().err.strip().splitlines() == [BLOW_LINE]
