"""The rest of the controller API users reach for (issue 16.3), with controllers in Webots' Python style.

Numeric arguments as users pass them, Keyboard (headless and scripted), simulation modes, getSelf/getFromId,
contact points and static balance, --duration across simulationReset, and the end of a controller after -1.
"""

from __future__ import annotations

import math
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF FLOOR Solid { name "floor" boundingObject Plane { size 20 20 } }
DEF BOX Solid {
  translation 0 0 0.05 name "box"
  boundingObject Box { size 0.2 0.1 0.1 } physics Physics { density -1 mass 1 }
}
DEF TIPPY Solid {
  translation 2 0 0.05 name "tippy"
  boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1 centerOfMass [ 0.3 0 0 ] }
}
DEF PARENT Solid {
  translation -2 0 0.05 name "parent"
  children [ DEF CHILD Solid {
    translation 0.5 0 0 name "child" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1 }
  } ]
  boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1 }
}
DEF ARM Robot {
  translation 0 2 1
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 }
      device [ RotationalMotor { name "m" maxTorque 50 maxVelocity 10 } PositionSensor { name "s" } ]
      endPoint Solid {
        translation 0.3 0 0
        boundingObject Sphere { radius 0.05 }
        physics Physics { density -1 mass 1 }
      }
    }
  ]
  controller "ctl"
  supervisor TRUE
}
"""


def _project(tmp_path: Path, script: str) -> Path:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "controllers" / "ctl").mkdir(parents=True)
    (tmp_path / "worlds" / "w.wbt").write_text(WORLD)
    (tmp_path / "controllers" / "ctl" / "ctl.py").write_text(textwrap.dedent(script))
    return tmp_path / "worlds" / "w.wbt"


def _supervisor() -> tuple[Simulation, Supervisor]:
    sim = Simulation(load_world_text(WORLD))
    return sim, Supervisor(simulation=sim, robot_node=sim.robots[0].node)


# ------------------------------------------------------------------ numeric arguments


def test_numpy_and_one_element_arrays_drive_the_motor(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, """
        import numpy as np
        from controller import Robot
        robot = Robot()
        motor = robot.getDevice("m")
        sensor = robot.getDevice("s")
        sensor.enable(np.int64(8))
        motor.setPosition(float("inf"))
        action = np.array([2.0], dtype=np.float32)  # what model.predict() returns
        motor.setVelocity(action)
        while robot.step(8.0) != -1:
            pass
        print(f"pos={sensor.getValue():.3f}")
    """)
    assert run_world(world, None, 0.5) == 0
    out = capsys.readouterr().out
    assert "pos=" in out
    assert float(out.split("pos=")[1]) == pytest.approx(1.0, abs=0.02)  # 2 rad/s for 0.5 s


@pytest.mark.parametrize(
    ("call", "method"),
    [
        ("motor.setVelocity(np.array([1.0, 2.0]))", "Motor.setVelocity"),
        ("motor.setPosition('1.0')", "Motor.setPosition"),
        ("motor.setForce([3.0])", "Motor.setForce"),
        ("motor.setAvailableTorque(None)", "Motor.setAvailableForce"),
        ("motor.setControlPID(1, np.array([[0.5, 1]]), 0)", "Motor.setControlPID"),
        ("sensor.enable(8.5)", "PositionSensor.enable"),
        ("robot.step('8')", "Robot.step"),
    ],
)
def test_bad_numbers_fail_at_the_call_naming_the_method(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], call: str, method: str
) -> None:
    world = _project(tmp_path, f"""
        import numpy as np
        from controller import Robot
        robot = Robot()
        motor = robot.getDevice("m")
        sensor = robot.getDevice("s")
        robot.step(8)
        {call}
        print("not reached")
    """)
    assert run_world(world, None, 0.1) == 1
    captured = capsys.readouterr()
    assert "not reached" not in captured.out
    assert f"TypeError: {method}()" in captured.err and "ctl.py\", line 8" in captured.err


def test_scalar_kinds_are_accepted_everywhere() -> None:
    sim, sup = _supervisor()
    motor = sup.getDevice("m")
    for value in (1, 1.5, True, np.float32(1.5), np.float64(1.5), np.int32(1), np.array(1.5), np.array([[1.5]])):
        motor.setVelocity(value)
        assert isinstance(motor.getVelocity(), float)
    motor.setControlPID(np.float64(10), 0, np.array([0.0]))
    box = sup.getFromDef("BOX")
    box.getField("translation").setSFVec3f([np.float64(0.0), 0, np.float32(0.5)])  # a list of any real scalars
    box.setVelocity(np.zeros(6))
    assert sup.step(np.int64(8)) == 0
    assert box.getPosition()[2] == pytest.approx(0.5, abs=1e-3)
    sim.close()


# ------------------------------------------------------------------ keyboard


KEYS_CONTROLLER = """
    from controller import Robot, Keyboard
    robot = Robot()
    kb = robot.getKeyboard()
    print("disabled", kb.getKey())
    kb.enable(16)
    assert Keyboard.UP == 315 and Keyboard.SHIFT == 0x10000
    while robot.step(8) != -1:
        keys = []
        k = kb.getKey()
        while k != -1:
            keys.append(k)
            k = kb.getKey()
        if keys:
            print(f"{robot.getTime():.3f} {keys}")
"""


def test_keyboard_headless_reads_no_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, KEYS_CONTROLLER)
    assert run_world(world, None, 0.3) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == "disabled -1" and "disabled keyboard" in captured.err


def test_keyboard_replays_a_key_script(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, KEYS_CONTROLLER)
    keys = tmp_path / "keys.txt"
    keys.write_text("# time key [hold]\n0.05 UP\n0.1  SHIFT+a 0.05   # held\n\n0.2 65\n")
    assert run_world(world, None, 0.3, keys=keys) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    # sampled every 16 ms: a press is read at the first sample at or after its time, a hold at each sample
    assert lines == [
        "disabled -1", "0.064 [315]", "0.112 [65601]", "0.128 [65601]", "0.144 [65601]", "0.208 [65]",
    ]


@pytest.mark.parametrize(
    ("text", "message"),
    [("0.1 NOPE\n", ":1: unknown key 'NOPE'"), ("0.1\n", ":1: expected 'TIME KEY [HOLD]'"),
     ("# c\nnan UP\n", ":2: time must be finite"), ("0.1 UP -1\n", ":1: hold must be finite and > 0"),
     ("0.1 HYPER+UP\n", ":1: unknown modifier")],
)
def test_bad_key_script_is_refused_before_running(tmp_path: Path, text: str, message: str) -> None:
    world = _project(tmp_path, "raise SystemExit('must not run')\n")
    keys = tmp_path / "keys.txt"
    keys.write_text(text)
    with pytest.raises(DualtwinError) as info:
        run_world(world, None, 0.1, keys=keys)
    assert str(info.value).startswith(f"--keys {keys}") and message in str(info.value)


# ------------------------------------------------------------------ modes, ids, self


def test_simulation_modes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, """
        from controller import Supervisor
        sup = Supervisor()
        assert (Supervisor.SIMULATION_MODE_PAUSE, Supervisor.SIMULATION_MODE_REAL_TIME,
                Supervisor.SIMULATION_MODE_FAST) == (0, 1, 2)
        print("start", sup.simulationGetMode())
        sup.simulationSetMode(Supervisor.SIMULATION_MODE_REAL_TIME)
        print("cached", sup.simulationGetMode())
        sup.step(8)
        print("after step", sup.simulationGetMode())
        sup.simulationSetMode(sup.SIMULATION_MODE_PAUSE)
        print("step(0)", sup.step(0), sup.getTime())
        print("paused step", sup.step(8), sup.getTime())
    """)
    assert run_world(world, None, 10.0) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [
        "start 2", "cached 2", "after step 1", "step(0) 0 0.008", "paused step -1 0.008",
    ]
    assert "paused the simulation" in captured.err


def test_get_self_and_get_from_id() -> None:
    sim, sup = _supervisor()
    me = sup.getSelf()
    assert me.getDef() == "ARM" and sup.getFromId(me.getId()) == me
    box = sup.getFromDef("BOX")
    assert box is not None and box.getId() > 0 and sup.getFromId(box.getId()) == box
    root = sup.getRoot()
    assert root.getId() == 0 and sup.getFromId(0) is not None and sup.getFromId(0).getId() == 0
    ids = [sup.getFromDef(d).getId() for d in ("FLOOR", "BOX", "TIPPY", "PARENT", "ARM")]
    assert len(set(ids)) == 5 and ids == sorted(ids)  # pre-order of the scene tree
    assert sup.getFromId(10_000) is None
    sim.close()


# ------------------------------------------------------------------ contacts


def test_contact_points_and_static_balance() -> None:
    sim, sup = _supervisor()
    box, tippy = sup.getFromDef("BOX"), sup.getFromDef("TIPPY")
    parent, arm = sup.getFromDef("PARENT"), sup.getSelf()
    for _ in range(10):
        sup.step(8)
    points = box.getContactPoints()
    assert box.getNumberOfContactPoints() == len(points) == 4  # a box resting on a plane: its 4 corners
    corners = sorted((round(p.point[0], 3), round(p.point[1], 3)) for p in points)
    assert corners == [(-0.1, -0.05), (-0.1, 0.05), (0.1, -0.05), (0.1, 0.05)]
    assert all(abs(p.getPoint()[2]) < 1e-3 and p.getNodeId() == box.getId() for p in points)
    assert box.getStaticBalance()
    # centre of mass 0.3 m beyond a 0.1 m base: outside the support polygon
    assert tippy.getNumberOfContactPoints() > 0 and not tippy.getStaticBalance()
    # a child Solid's own geoms count only with includeDescendants
    assert parent.getNumberOfContactPoints() == 4 and parent.getNumberOfContactPoints(True) == 8
    assert {p.node_id for p in parent.getContactPoints(True)} == {
        parent.getId(), sup.getFromDef("CHILD").getId()
    }
    assert arm.getNumberOfContactPoints(True) == 0 and not arm.getStaticBalance()  # in the air
    assert box.getContactPointNode(0) == box and math.isnan(box.getContactPoint(99)[0])
    sim.close()


# ------------------------------------------------------------------ duration and termination


def test_duration_bounds_total_time_across_resets(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, """
        from controller import Supervisor
        sup = Supervisor()
        calls = resets = 0
        latest = 0.0
        while sup.step(8) != -1:
            calls += 1
            latest = max(latest, sup.getTime())
            if sup.getTime() >= 0.5 - 1e-9:
                sup.simulationReset()
                resets += 1
        print(f"calls={calls} resets={resets} latest={latest:.3f}")
    """)
    assert run_world(world, None, 2.0) == 0
    # every step call counts 8 ms of the run (the step carrying a reset too): 250 calls reach 2 s
    assert "calls=249 resets=3 latest=0.504" in capsys.readouterr().out


def test_reset_loop_without_time_still_ends(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, """
        from controller import Supervisor
        sup = Supervisor()
        while True:
            sup.simulationReset()
            sup.step(8)
    """)
    assert run_world(world, None, 0.5) == 0


def test_controller_ignoring_minus_one_is_stopped_at_its_next_step(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    world = _project(tmp_path, """
        from controller import Robot
        robot = Robot()
        results = []
        try:
            while True:
                results.append(robot.step(8))
        finally:
            print("minus ones:", results.count(-1), "zeros:", results.count(0))
        print("not reached")
    """)
    assert run_world(world, None, 0.08) == 0
    out = capsys.readouterr().out
    assert "minus ones: 1 zeros: 9" in out and "not reached" not in out


def test_controller_still_busy_after_minus_one_is_terminated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    world = _project(tmp_path, """
        from controller import Robot
        robot = Robot()
        while robot.step(8) != -1:
            pass
        print("cleanup")
        while True:
            pass
    """)
    start = time.monotonic()
    assert run_world(world, None, 0.08) == 0
    elapsed = time.monotonic() - start
    captured = capsys.readouterr()
    assert "cleanup" in captured.out and "forced termination" in captured.err
    assert 0.9 < elapsed < 10.0


def test_add_force_and_torque_act_for_one_basic_step() -> None:
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 gravity 0 }
DEF FREE Solid {
  rotation 0 0 1 1.5707963267948966
  boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 2 }
}
DEF ME Robot { supervisor TRUE }
"""
    sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    free = sup.getFromDef("FREE")
    free.addForce(np.array([10.0, 0.0, 0.0]), False)
    sup.step(32)  # four basic steps: the force acts during the first only
    assert free.getVelocity()[:3] == pytest.approx([10 / 2 * 0.008, 0.0, 0.0], abs=1e-12)
    free.setVelocity([0.0] * 6)
    sup.step(8)
    free.addForce([1.0, 0.0, 0.0], True)  # the Solid's x axis is the world's y axis
    sup.step(8)
    assert free.getVelocity()[:3] == pytest.approx([0.0, 1 / 2 * 0.008, 0.0], abs=1e-12)
    free.setVelocity([0.0] * 6)
    sup.step(8)
    free.addTorque([0.0, 0.0, 0.01], False)
    sup.step(8)
    inertia = 2 * (0.1**2 + 0.1**2) / 12
    assert free.getVelocity()[3:] == pytest.approx([0.0, 0.0, 0.01 / inertia * 0.008], abs=1e-12)
    with pytest.raises(TypeError, match=r"Node\.addForce\(\)"):
        free.addForce(["1", 0, 0], False)
    sim.close()


@pytest.mark.parametrize("kind", ["missing", "directory", "pipe", "binary"])
def test_unreadable_key_script_is_one_error(tmp_path: Path, kind: str) -> None:
    import os

    world = _project(tmp_path, "raise SystemExit('must not run')\n")
    keys = tmp_path / "keys"
    if kind == "directory":
        keys.mkdir()
    elif kind == "pipe":
        os.mkfifo(keys)
    elif kind == "binary":
        keys.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(DualtwinError, match=r"^--keys .*keys"):
        run_world(world, None, 0.1, keys=keys)
