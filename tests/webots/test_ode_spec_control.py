"""Sections 6 (controller/supervisor semantics), 7.1 (PROTO) and 8 (.wbt grammar) of the Webots-on-ODE
specification, one fact per test.

S = /work/shared/reference/webots-on-ode.md (line numbers as of this writing); the project's restatement is
docs/reference/webots-on-ode.md. Expected values come from the specification or from hand computation (each test
says which). Facts pinned elsewhere (step returning −1, dotted and PROTO-internal getFromDef, teleport keeping
velocities, resetPhysics, reset restoring the load state, getUrdf, IS/defaults/DEF scopes, hidden PROTO fields,
EXTERNPROTO lists, USE of Solids/joints refused, tokenizer comments/commas/escapes) are not repeated.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 8  # ms
DT = TS / 1000.0
HEADER = "#VRML_SIM R2023b utf8\n"


def _load(nodes: str, gravity: float = 0.0, robot: str = "") -> tuple[Simulation, Supervisor]:
    text = (
        HEADER
        + f"WorldInfo {{ basicTimeStep {TS} gravity {gravity} physicsDisableTime 0 }}\n"
        + f'DEF SUP Robot {{ name "sup" supervisor TRUE children [ {robot} ] }}\n'
        + nodes
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return sim, Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


# ------------------------------------------------------------------------------------------ §6 controller API


def test_basic_time_step_is_the_world_info_value_in_ms() -> None:
    # S l.481: Robot.getBasicTimeStep() → WorldInfo.basicTimeStep (ms, float)
    _, sup = _load("")
    value = sup.getBasicTimeStep()
    assert value == 8.0 and isinstance(value, float)


def test_get_self_is_the_supervisors_robot_node() -> None:
    # S l.489-490: getSelf() is the supervisor's own Robot node
    _, sup = _load("")
    me = sup.getSelf()
    assert me.getTypeName() == "Robot" and me.getDef() == "SUP"
    assert me.getField("name").getSFString() == "sup"


def test_get_position_is_the_frame_origin_not_the_centre_of_mass() -> None:
    # S l.491: getPosition() is the node's frame origin, not its CoM (here 0.3 m away along x)
    _, sup = _load(
        "DEF BOX Solid { translation 1 2 3 boundingObject Sphere { radius 0.1 } "
        "physics Physics { density -1 mass 1 centerOfMass [ 0.3 0 0 ] } }"
    )
    _steps(sup, 1)
    assert sup.getFromDef("BOX").getPosition() == pytest.approx([1.0, 2.0, 3.0], abs=1e-12)


def test_get_orientation_is_row_major_with_node_axes_as_columns() -> None:
    # S l.492: 3×3 world rotation, row-major; columns are the node's axes in the world: a quarter turn about z
    # sends the node x axis to world y and its y axis to world −x
    _, sup = _load("DEF T Pose { rotation 0 0 1 1.5707963267948966 }")
    r = sup.getFromDef("T").getOrientation()
    assert r == pytest.approx([0, -1, 0, 1, 0, 0, 0, 0, 1], abs=1e-12)


def test_get_velocity_is_the_body_com_velocity_in_the_world() -> None:
    # S l.493-495: getVelocity() = [v w] of the ODE body, v being its CoM velocity: a body spinning at 2 rad/s
    # about z and drifting at 1 m/s keeps v = (1, 0, 0) (gravity 0), while its frame origin, 0.3 m from the CoM,
    # circles about it: origin = CoM − Rz(2t)·(0.3, 0, 0) (hand computation)
    _, sup = _load(
        "DEF BALL Solid { boundingObject Sphere { radius 0.1 } "
        "physics Physics { density -1 mass 1 centerOfMass [ 0.3 0 0 ] } }"
    )
    ball = sup.getFromDef("BALL")
    ball.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 2.0])
    _steps(sup, 25)
    t = 25 * DT
    assert ball.getVelocity() == pytest.approx([1.0, 0.0, 0.0, 0.0, 0.0, 2.0], abs=1e-9)
    com = (0.3 + t, 0.0)
    origin = (com[0] - 0.3 * math.cos(2 * t), com[1] - 0.3 * math.sin(2 * t))
    assert ball.getPosition()[:2] == pytest.approx(origin, abs=1e-4)  # ODE integrates the rotation to O(h²)


def test_merged_solid_reports_its_parent_body_velocity() -> None:
    # S l.494-495: a Solid merged into a parent reports the parent body's values
    _, sup = _load(
        "DEF BASE Solid { boundingObject Box { size 0.2 0.2 0.2 } physics Physics { density -1 mass 1 } "
        "children [ DEF PART Solid { translation 0.5 0 0 boundingObject Sphere { radius 0.05 } "
        'name "part" physics Physics { density -1 mass 1 } } ] }'
    )
    base = sup.getFromDef("BASE")
    base.setVelocity([0.5, 0.0, 0.0, 0.0, 0.0, 1.0])
    _steps(sup, 3)
    assert sup.getFromDef("PART").getVelocity() == pytest.approx(base.getVelocity(), abs=1e-12)


def test_translation_edit_is_applied_at_the_next_step() -> None:
    # S l.497-499: setSFVec3f on translation is queued and run at the beginning of the next step; getPosition
    # right after still returns the old pose
    _, sup = _load("DEF BOX Solid { translation 0 0 1 boundingObject Sphere { radius 0.1 } "
                   "physics Physics { density -1 mass 1 } }")
    box = sup.getFromDef("BOX")
    _steps(sup, 1)
    box.getField("translation").setSFVec3f([2.0, 0.0, 1.0])
    assert box.getPosition() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    _steps(sup, 1)
    assert box.getPosition() == pytest.approx([2.0, 0.0, 1.0], abs=1e-12)


def test_simulation_reset_restores_motor_targets_and_keeps_the_controller() -> None:
    # S l.505-508: simulationReset restores the load state, motors get their §5.1 initial state (target =
    # initial position, target velocity = maxVelocity), time → 0, and the controller is not restarted
    arm = (
        "HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 } "
        'device [ RotationalMotor { name "m" maxVelocity 4 maxTorque 100 } PositionSensor { name "s" } ] '
        'endPoint Solid { translation 0.5 0 0 name "bob" boundingObject Sphere { radius 0.05 } '
        "physics Physics { density -1 mass 1 } } }"
    )
    _, sup = _load("", robot=arm)
    m = sup.getDevice("m")
    s = sup.getDevice("s")
    s.enable(TS)
    m.setPosition(0.5)
    m.setVelocity(2.0)
    _steps(sup, 100)
    assert s.getValue() == pytest.approx(0.5, abs=1e-3)
    sup.simulationReset()
    _steps(sup, 1)
    assert sup.getTime() == pytest.approx(0.0, abs=DT)
    assert m.getTargetPosition() == 0.0 and m.getVelocity() == 4.0
    _steps(sup, 50)
    assert s.getValue() == pytest.approx(0.0, abs=1e-3)  # held at the initial position by the same controller
    assert sup.getDevice("m") is m


# ------------------------------------------------------------------------------------------ §7.1 PROTO


def test_use_inside_bounding_objects_makes_separate_geoms() -> None:
    # S l.536-537: USE of a geometry is fine; a USE inside a boundingObject creates a separate ODE geom
    sim, _ = _load(
        'DEF A Solid { name "a" boundingObject DEF BALL Sphere { radius 0.1 } physics Physics { } } '
        'Solid { name "b" translation 1 0 0 boundingObject USE BALL physics Physics { } }'
    )
    assert len(sim.bodies) == 2
    geoms = [g for g in sim.geoms.values() if g.body is not None]
    assert len(geoms) == 2 and geoms[0].body is not geoms[1].body


# ------------------------------------------------------------------------------------------ §8 .wbt grammar


def test_use_refers_to_the_closest_preceding_def() -> None:
    # S l.610-611: USE name refers to the closest preceding DEF in the same file
    w = load_world_text(
        HEADER + "WorldInfo { }\n"
        "DEF G Shape { geometry DEF B Box { size 1 1 1 } }\n"
        "Shape { geometry DEF B Box { size 2 2 2 } }\n"
        "Shape { geometry USE B }\n"
    )
    assert w.nodes[-1]["geometry"]["size"] == (2.0, 2.0, 2.0)


def test_mf_field_takes_a_single_value_without_brackets() -> None:
    # S l.617-618: an MF value is `[ v1 v2 ... ]` or a single value without brackets
    w = load_world_text(
        HEADER + 'WorldInfo { contactProperties ContactProperties { coulombFriction 0.3 } }\n'
        'Robot { controllerArgs "one" children Pose { } }\n'
    )
    info, robot = w.nodes
    assert info["contactProperties"][0]["coulombFriction"] == [0.3]
    assert robot["controllerArgs"] == ["one"]
    assert [c.type_name for c in robot["children"]] == ["Pose"]


def test_commas_separate_values_like_whitespace() -> None:
    # S l.608: whitespace and commas are separators (VRML97)
    w = load_world_text(HEADER + "WorldInfo { gravity 3 }\nSolid { translation 1, 2, 3 rotation 0,0,1,0.5 }\n")
    solid = w.nodes[1]
    assert solid["translation"] == (1.0, 2.0, 3.0) and solid["rotation"] == (0.0, 0.0, 1.0, 0.5)


def test_bool_and_null_keywords() -> None:
    # S l.615-616: SFBool TRUE|FALSE; SFNode = node | USE n | NULL
    w = load_world_text(HEADER + "WorldInfo { }\nRobot { supervisor TRUE synchronization FALSE physics NULL }\n")
    robot = w.nodes[1]
    assert robot["supervisor"] is True and robot["synchronization"] is False and robot["physics"] is None


def test_world_without_the_vrml_sim_header_is_refused() -> None:
    # S l.604: the first line is exactly `#VRML_SIM R2023b utf8`
    with pytest.raises(Exception, match="(?i)header"):
        load_world_text("WorldInfo { }\n")
