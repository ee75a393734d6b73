"""Supervisor edits of bounding geometry reach ODE at the next step (issue 23 item 2, issue 26 item 4).

Each obstacle's centre is 1 m ahead of a one-ray generic distance sensor whose table maps distance to itself,
so the reading is ``1 − (the obstacle's half extent along the ray)``, before and after the edit. The edit is
made on the visual Shape's DEF node while the boundingObject is a USE of it (or the reverse), as worlds do.
Controls: before this change the field read back the new value but the geom (hence rays and contacts) kept
the old size, and a sleeping body never noticed its support shrink. The last tests move a whole static support
(a Box or a Plane, by its Solid's translation or a Pose above it) from under, or onto, a sleeping body.
"""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

SENSORS = "".join(
    f'DistanceSensor {{ name "{n}" translation 0 {y} 0 lookupTable [ 0 0 0, 2 2 0 ] }} '
    for n, y in (("box", 0), ("sphere", 2), ("cylinder", 4), ("capsule", 6))
)
OBSTACLES = """
Solid { translation 1 0 0 children [ Shape { geometry DEF BOX Box { size 0.2 0.2 0.2 } } ] boundingObject USE BOX }
Solid { translation 1 2 0 boundingObject DEF BALL Sphere { radius 0.1 } children [ Shape { geometry USE BALL } ] }
Solid { translation 1 4 0 children [ Shape { geometry DEF CYL Cylinder { radius 0.1 height 0.5 } } ]
        boundingObject USE CYL }
Solid { translation 1 6 0 rotation 0 1 0 1.5707963267948966
        children [ Shape { geometry DEF CAP Capsule { radius 0.1 height 0.2 } } ] boundingObject USE CAP }
"""


def _supervisor(text: str) -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text("#VRML_SIM R2023b utf8\n" + text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def test_resized_primitives_are_seen_by_rays_at_the_next_step() -> None:
    sup = _supervisor(f"WorldInfo {{ basicTimeStep 8 }}\nRobot {{ supervisor TRUE children [ {SENSORS} ] }}\n{OBSTACLES}")
    names = ("box", "sphere", "cylinder", "capsule")
    sensors = [sup.getDevice(n) for n in names]
    for s in sensors:
        s.enable(8)
    sup.step(8)
    assert [s.getValue() for s in sensors] == pytest.approx([0.9, 0.9, 0.9, 0.8])
    sup.getFromDef("BOX").getField("size").setSFVec3f([0.6, 0.2, 0.2])
    sup.getFromDef("BALL").getField("radius").setSFFloat(0.3)
    sup.getFromDef("CYL").getField("radius").setSFFloat(0.25)
    sup.getFromDef("CAP").getField("height").setSFFloat(0.6)
    sup.step(8)
    assert [s.getValue() for s in sensors] == pytest.approx([0.7, 0.7, 0.75, 0.6])
    assert sup.getFromDef("BOX").getField("size").getSFVec3f() == [0.6, 0.2, 0.2]


def test_a_sleeping_body_wakes_and_falls_when_its_support_shrinks() -> None:
    sup = _supervisor(
        "WorldInfo { basicTimeStep 8 physicsDisableTime 0.2 }\nRobot { supervisor TRUE }\n"
        "Solid { translation 0 0 0.05 children [ Shape { geometry DEF STAND Box { size 1 1 0.1 } } ] "
        "boundingObject USE STAND }\n"
        "DEF CUBE Solid { translation 0 0 0.15 boundingObject Box { size 0.1 0.1 0.1 } "
        "physics Physics { density -1 mass 1 } }"
    )
    sim = sup.simulation
    cube = sup.getFromDef("CUBE")
    for _ in range(125):  # 1 s: the cube settles and ODE disables it after 0.2 s of rest
        sup.step(8)
    body = sim.solid_for(cube.scene_node).body
    assert not sim._lib.dBodyIsEnabled(body.ptr)  # asleep before the edit
    z_rest = cube.getPosition()[2]
    assert z_rest == pytest.approx(0.15, abs=2e-3)
    sup.getFromDef("STAND").getField("size").setSFVec3f([1.0, 1.0, 0.02])  # top face now at z = 0.06
    for _ in range(63):
        sup.step(8)
    assert cube.getPosition()[2] == pytest.approx(0.11, abs=2e-3)  # fell onto the thinner stand


# A ball (radius 0.1 m) asleep on a static support, which a supervisor then moves. Nothing awake touches the
# ball, so only the edit can wake it (a body asleep takes no contact from a static shape, webots-on-ode.md §2.3
# rule 9); as when the support is moved by a Pose among its Solid's children (test_children_pose_edits.py), the
# bodies near where a static shape was and where it lands are woken. A ball that fell 1 m rests on the lowered
# floor with its centre at -1 + 0.1 = -0.9 m (within 1 cm: soft contact), 0.5·g·t² = 1 m taking 0.45 s.
FLOORS = {
    "a Box Solid moved by its translation": (
        'DEF FLOOR Solid { translation 0 0 -0.5 boundingObject Box { size 2 2 1 } }', "FLOOR", [0, 0, -1.5]),
    "a Plane Solid moved by its translation": ('DEF FLOOR Solid { boundingObject Plane { size 2 2 } }', "FLOOR",
                                               [0, 0, -1]),
    "a Plane Solid below a moved Pose": (
        'Solid { children [ DEF LIFT Pose { children [ Solid { boundingObject Plane { size 2 2 } } ] } ] }', "LIFT",
        [0, 0, -1]),
}


def _asleep_ball(floor: str) -> tuple[Supervisor, object]:
    sup = _supervisor(
        "WorldInfo { basicTimeStep 8 physicsDisableTime 0.2 }\nRobot { supervisor TRUE }\n" + floor + "\n"
        "DEF BALL Solid { translation 0 0 0.1 boundingObject Sphere { radius 0.1 } physics Physics { } }"
    )
    for _ in range(125):  # 1 s: settled, and asleep after 0.2 s at rest
        sup.step(8)
    ball = sup.getFromDef("BALL")
    assert not sup.simulation._lib.dBodyIsEnabled(sup.simulation.solid_for(ball.scene_node).body.ptr)
    return sup, ball


@pytest.mark.parametrize("floor", list(FLOORS), ids=list(FLOORS))
def test_a_body_asleep_on_a_static_support_a_supervisor_moves_away_wakes_and_falls(floor: str) -> None:
    text, name, translation = FLOORS[floor]
    sup, ball = _asleep_ball(text)
    assert ball.getPosition()[2] == pytest.approx(0.1, abs=2e-3)
    sup.getFromDef(name).getField("translation").setSFVec3f(translation)
    for _ in range(125):  # 1 s
        sup.step(8)
    assert ball.getPosition()[2] == pytest.approx(-0.9, abs=0.01)


def test_a_body_asleep_where_a_supervisor_moves_a_static_solid_wakes_and_is_pushed_out() -> None:
    # a 0.2 m box Solid (no Physics) teleported to x = 0.18 overlaps the ball (x ∈ [-0.1, 0.1]) by 2 cm: the
    # contact pushes the ball towards -x; asleep and unwoken, it would stay at x = 0 in the box
    sup, ball = _asleep_ball('Solid { boundingObject Plane { } }\n'
                             'DEF WALL Solid { translation 3 0 0.1 boundingObject Box { size 0.2 0.2 0.2 } }')
    sup.getFromDef("WALL").getField("translation").setSFVec3f([0.18, 0, 0.1])
    for _ in range(25):  # 0.2 s
        sup.step(8)
    assert ball.getPosition()[0] < -0.01
