"""The robots a conversion does not convert are part of its world: their bodies, joints and motors are converted
(before, they were skipped, collision geometry included, and the converted model lacked obstacles the Webots twin
has). The Webots twin drives the chosen robot only, so the others' motors keep Webots' initial state, a position
servo on the initial position (on-ODE §5.1), and the converted actuators run the same Webots motor law; the parts of
one robot never touch each other without ``selfCollision`` (on-ODE §2.3 rule 4); the binding exposes only the chosen
robot's devices.

Hand computations (ARM_WORLD): OTHER is a robot without Physics (static base) at z = 0.5 whose 0.6 m arm (a 1 kg
0.6 x 0.2 x 0.05 m box, centre 0.3 m from the hinge) turns about +y. R, a 1 kg 0.2 m cube, is dropped from z = 1 at
x = 0.4, above the arm:
* held by its motor (maxTorque 100 N*m against at most 1 * 9.81 * 0.4 + 1 * 9.81 * 0.3 = 6.9 N*m), the arm stays
  level and R comes to rest on it: centre at 0.5 + 0.025 + 0.1 = 0.625 m (on the floor, without the arm: 0.1 m);
* without a motor the arm is a pendulum released level (rod pivoted at its end: equivalent length 2/3 * 0.6 = 0.4 m,
  quarter period of a 90 deg swing 1.18 * pi/2 * sqrt(0.4 / 9.81) = 0.37 s): at 0.4 s it is past the vertical
  (> pi/2: a turn about +y takes +x toward -z), through the floor, which a body jointed to the static environment
  never touches (on-ODE §2.3 rule 6).
The twins' states hold the converted robot's joints only (the Webots twin's state is its robot's joints and the
world's top-level DEF bodies).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.convert.world_robots import OTHER_ROBOT_BITS, OtherRobot
from dualtwin.errors import DualtwinError
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node
from tests.support.converted_twins import converted_twins, world_text

FLOOR = "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }\n"
ARM = ("DEF OTHER Robot {{ translation 0 0 0.5 children [ DEF H HingeJoint {{\n"
       "  jointParameters HingeJointParameters {{ axis 0 1 0 }} device [ {devices} ]\n"
       "  endPoint DEF ARM Solid {{ translation 0.3 0 0 boundingObject Box {{ size 0.6 0.2 0.05 }}\n"
       "    physics Physics {{ density -1 mass 1 }} }} }} ]\n"
       "  boundingObject Box {{ size 0.1 0.1 0.1 }} }}\n")
HELD = 'RotationalMotor { name "m" maxTorque 100 } PositionSensor { name "s" }'
CUBE = ('DEF R Robot { translation 0.4 0 1 controller "<extern>" children [ GPS { name "gps" } ] '
        "boundingObject Box { size 0.2 0.2 0.2 } physics Physics { density -1 mass 1 } }")


def _arm_world(devices: str) -> str:
    return world_text(FLOOR + ARM.format(devices=devices) + CUBE, "basicTimeStep 4")


def test_the_other_robot_is_converted_outside_the_binding() -> None:
    conv = convert_world_text(_arm_world(HELD), "arm.wbt", robot="R")
    model = conv.compile()
    assert model.body("ARM").jntnum == 1 and model.joint("H").type == 3  # mjJNT_HINGE: the joint, as a joint
    assert model.body("OTHER").weldid == 0  # no Physics: its base is static, as in Webots
    assert model.actuator("OTHER/m").trnid[0] == model.joint("H").id
    assert [m.name for m in conv.motors] == [] and [j.name for j in conv.joints] == []
    assert conv.sensors == {"gps": "GPS"}
    assert "s" not in {model.sensor(i).name for i in range(model.nsensor)}  # no controller reads OTHER's sensor
    binding = conv.binding
    assert binding["twins"]["webots"]["robot"] == "R"
    assert not binding["actions"] and set(binding["onboard"]) == {"gps_x_m"}
    assert any("robot 'OTHER' is not the converted robot" in w for w in conv.warnings)


def test_an_other_robot_with_physics_is_free_and_its_parts_keep_apart() -> None:
    # Two other robots (one with selfCollision) and the converted one: collision bits 1 (environment), 2 (R), 4 and
    # 8. An other robot's conaffinity is every bit but its own (1 + 2 + 8 = 11, 1 + 2 + 4 = 7), its own too with
    # selfCollision (15); MuJoCo lets two geoms touch when (contype1 & conaffinity2) | (contype2 & conaffinity1).
    text = world_text(FLOOR + "DEF A Robot { translation 2 0 0.1 boundingObject Box { size 0.1 0.1 0.1 } "
                      "physics Physics { } }\nDEF B Robot { translation -2 0 0.1 selfCollision TRUE "
                      "boundingObject Box { size 0.1 0.1 0.1 } }\n" + CUBE)
    model = convert_world_text(text, "robots.wbt", robot="R").compile()
    joint = model.body("A").jntadr[0]
    assert model.jnt_type[joint] == 0  # mjJNT_FREE
    bits = {name: (int(model.geom(name).contype[0]), int(model.geom(name).conaffinity[0]))
            for name in ("FLOOR", "R", "A", "B")}
    assert bits == {"FLOOR": (1, 3), "R": (2, 1), "A": (4, 11), "B": (8, 15)}


def test_past_mujocos_collision_bits_the_last_robots_share_one_and_touch_themselves() -> None:
    # contype is a 32-bit int: bits 0 (environment) and 1 (the converted robot), then one for each other robot up to
    # bit 30 (29 robots). With 31 other robots, the 28th (index 27) still has bit 29 to itself, the 29th to 31st share
    # bit 30; every other robot then accepts bits 0..30, 2^31 - 1, its own left out only while it is alone on it.
    robot = Node("Robot", schema.default_fields("Robot"))
    every = 2**31 - 1
    alone = OtherRobot.place(robot, np.eye(4), 1.0, 27, 31)
    assert (alone.contype, alone.conaffinity, alone.group) == (2**29, every - 2**29, "robot")
    shared = OtherRobot.place(robot, np.eye(4), 1.0, 30, 31)
    assert (shared.contype, shared.conaffinity, shared.group) == (2**30, every, "")
    assert OTHER_ROBOT_BITS == 29
    last = OtherRobot.place(robot, np.eye(4), 1.0, 28, 29)  # 29 other robots: the last has bit 30 to itself
    assert (last.contype, last.conaffinity) == (2**30, every - 2**30)


def test_an_other_robot_the_converter_cannot_map_is_skipped_with_a_warning() -> None:
    # the user's robot converts; the tracked robot beside it is left out, with one line saying so
    text = world_text(FLOOR + 'DEF TANK Robot { translation 2 0 0 children [ Track { } ] }\n' + CUBE)
    conv = convert_world_text(text, "tank.wbt", robot="R")
    model = conv.compile()
    assert "TANK" not in {model.body(i).name for i in range(model.nbody)}
    assert any("robot 'TANK' is not the converted robot and holds a Track (tank.wbt:" in w for w in conv.warnings)


def test_no_contact_pair_brings_two_parts_of_one_robot_together() -> None:
    # OTHER's two arms (materials a and b, whose ContactProperties differ from MuJoCo's mixing of their geoms)
    # never touch in Webots (no selfCollision): no explicit <pair> may join them (MuJoCo's mixing gives them the
    # larger friction, 1.3, for 0.2). ARM0 meets the floor (default) by one (MuJoCo's mixing: 1, the floor's, for
    # 0.7); OTHER has Physics, so its arms are not jointed to the static environment, which they would never touch.
    arms = "".join(f"HingeJoint {{ endPoint DEF ARM{i} Solid {{ translation {x} 0 0 contactMaterial \"{m}\" "
                   "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } } "
                   for i, (x, m) in enumerate(((0.2, "a"), (-0.2, "b"))))
    other = f"DEF OTHER Robot {{ translation 0 0 1 children [ {arms} ] physics Physics {{ density -1 mass 1 }} }}\n"
    text = world_text(FLOOR + other + CUBE,
                      "contactProperties [ ContactProperties { material1 \"a\" material2 \"b\" coulombFriction 0.2 }"
                      " ContactProperties { material1 \"default\" material2 \"a\" coulombFriction 0.7 }"
                      " ContactProperties { material1 \"default\" material2 \"b\" coulombFriction 1.3 } ]")
    model = convert_world_text(text, "arms.wbt", robot="R").compile()
    pairs = {frozenset((model.geom(int(model.pair_geom1[i])).name, model.geom(int(model.pair_geom2[i])).name))
             for i in range(model.npair)}
    assert frozenset(("ARM0", "ARM1")) not in pairs
    assert frozenset(("FLOOR", "ARM0")) in pairs


def test_the_conversion_of_two_robots_is_the_same_twice() -> None:
    assert convert_world_text(_arm_world(HELD), "arm.wbt", robot="R").xml == convert_world_text(
        _arm_world(HELD), "arm.wbt", robot="R").xml


def test_both_twins_rest_the_dropped_robot_on_the_other_robots_held_arm(tmp_path: Path) -> None:
    with converted_twins(_arm_world(HELD), tmp_path, 0.02, robot="R") as (_, webots, mujoco_twin):
        for _ in range(50):  # 1 s: the 0.375 m drop takes 0.28 s
            webots.step()
            mujoco_twin.step()
        for twin in (webots, mujoco_twin):
            assert twin.body_position("R")[2] == pytest.approx(0.625, abs=3e-3), twin.name
            assert twin.joint_position("H") == pytest.approx(0.0, abs=2e-3), twin.name  # the motor holds it


@pytest.mark.parametrize("physics", ["", "physics Physics { density -1 mass 1 }"])
def test_both_twins_state_holds_the_converted_robots_joints_only(tmp_path: Path, physics: str) -> None:
    # The Webots twin's state is its robot's joints and the world's top-level DEF bodies (OTHER with Physics): the
    # MuJoCo twin's leaves OTHER's joint H and its motor's hold out too, so a state passes between the twins.
    text = _arm_world(HELD).replace("size 0.1 0.1 0.1 } }", f"size 0.1 0.1 0.1 }} {physics} }}")
    with converted_twins(text, tmp_path, 0.02, robot="R") as (_, webots, mujoco_twin):
        states = webots.get_state(), mujoco_twin.get_state()
        bodies = {"R", "OTHER"} if physics else {"R"}
        for state in states:
            assert set(state.bodies) == bodies and not state.joint_positions and not state.holds
        webots.set_state(states[1])
        mujoco_twin.set_state(states[0])


def test_both_twins_swing_the_other_robots_arm_without_a_motor(tmp_path: Path) -> None:
    # control: the same arm without a motor is a pendulum in both twins (R falls past it, onto the floor, later)
    with converted_twins(_arm_world('PositionSensor { name "s" }'), tmp_path, 0.02, robot="R") as (
            _, webots, mujoco_twin):
        for _ in range(20):  # 0.4 s
            webots.step()
            mujoco_twin.step()
        assert webots.joint_position("H") > math.pi / 2
        assert mujoco_twin.joint_position("H") == pytest.approx(webots.joint_position("H"), abs=0.05)


def test_the_mujoco_twin_offers_no_knob_for_the_other_robots_motors(tmp_path: Path) -> None:
    # OTHER's motor is no device of R in either twin (the binding exposes R's devices only), so no knob tunes it: a
    # glob such as 'motor.*.gain' reaches the converted robot's motors only. Control: the same world with the motor on
    # R's side (R a robot with a hinge and a motor of its own) has that motor's knobs
    (tmp_path / "other").mkdir()
    with converted_twins(_arm_world(HELD), tmp_path / "other", 0.02, robot="R") as (_, _, mujoco_twin):
        assert not [name for name in mujoco_twin.knobs() if name.startswith("motor.")]
    (tmp_path / "own").mkdir()
    own = _arm_world(HELD).replace("DEF OTHER Robot {", 'DEF OTHER Robot { controller "<extern>"')
    with converted_twins(own, tmp_path / "own", 0.02, robot="OTHER") as (_, _, mujoco_twin):
        assert "motor.m.max_torque" in mujoco_twin.knobs()


@pytest.mark.parametrize("name", ["OTHER/m", "m"])
def test_neither_twin_takes_a_command_for_the_other_robots_motor(tmp_path: Path, name: str) -> None:
    # the Webots twin drives R's devices only; the MuJoCo twin took a command for OTHER's actuator by its name and
    # moved a motor the Webots twin cannot reach
    with converted_twins(_arm_world(HELD), tmp_path, 0.02, robot="R") as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            with pytest.raises(DualtwinError, match="no motor named"):
                twin.command(name, "velocity", 1.0)
