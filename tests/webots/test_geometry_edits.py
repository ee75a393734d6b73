"""Supervisor edits of bounding geometry reach ODE at the next step (issue 23 item 2, issue 26 item 4).

Each obstacle's centre is 1 m ahead of a one-ray generic distance sensor whose table maps distance to itself,
so the reading is ``1 − (the obstacle's half extent along the ray)``, before and after the edit. The edit is
made on the visual Shape's DEF node while the boundingObject is a USE of it (or the reverse), as worlds do.
Controls: before this change the field read back the new value but the geom (hence rays and contacts) kept
the old size, and a sleeping body never noticed its support shrink.
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
