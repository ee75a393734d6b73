"""A boundingObject a supervisor imports (into a Solid's empty ``boundingObject`` field, or into a Group inside
one) becomes ODE geoms at once, as in Webots: contacts and ray sensors see it from the next step on, on the
Solid's body where the Solid is now if it has one. Removing it takes the geoms out: what rested on it falls.

Expectations from the geometry: a 0.5 m box centred 0.25 m up at x = 1 has its top at 0.5 m, so a 0.1 m ball
dropped on it rests with its centre at 0.6 m (0.1 m on the floor); a distance sensor at the origin, 0.25 m up,
looking along +x meets the box's near face at 0.75 m (lookup table = identity up to 2 m, 2 m = nothing)."""

from __future__ import annotations

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 8
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF SHELF Solid {{ translation 1 0 0.25 name "shelf" {{shelf}} }}
DEF BALL Solid {{ translation 1 0 1 name "ball" boundingObject Sphere {{ radius 0.1 }} physics Physics {{ }} }}
DEF DROP Solid {{ translation 3 0 0.5 name "drop" physics Physics {{ mass 1 }} }}
Robot {{ translation 0 0 0.25 supervisor TRUE children [ DistanceSensor {{ name "ds" lookupTable [ 0 0 0, 2 2 0 ] }} ] }}
"""
BOX = "Box { size 0.5 0.5 0.5 }"


def _supervisor(shelf: str = "") -> Supervisor:
    sim = Simulation(load_world_text(WORLD.replace("{shelf}", shelf)))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    sup.getDevice("ds").enable(TS)
    return sup


def _run(sup: Supervisor, seconds: float) -> None:
    for _ in range(round(seconds * 1000 / TS)):
        sup.step(TS)


def _z(sup: Supervisor, name: str) -> float:
    return float(sup.getFromDef(name).getPosition()[2])


@pytest.mark.parametrize("where", ["field", "group"])
def test_imported_bounding_object_collides_and_is_seen_then_removed_it_is_gone(where: str) -> None:
    sup = _supervisor("" if where == "field" else "boundingObject Group { }")
    shelf = sup.getFromDef("SHELF")
    if where == "field":
        shelf.getField("boundingObject").importSFNodeFromString(BOX)
    else:
        shelf.getField("boundingObject").getSFNode().getField("children").importMFNodeFromString(-1, BOX)
    sup.step(TS)
    assert sup.getDevice("ds").getValue() == pytest.approx(0.75, abs=1e-6)
    _run(sup, 1.5)  # the ball falls 0.4 m onto the box and sleeps there
    assert _z(sup, "BALL") == pytest.approx(0.6, abs=0.005)
    if where == "field":
        shelf.getField("boundingObject").removeSF()
    else:
        shelf.getField("boundingObject").getSFNode().getField("children").removeMF(0)
    sup.step(TS)
    assert sup.getDevice("ds").getValue() == pytest.approx(2.0)
    _run(sup, 1.0)
    assert _z(sup, "BALL") == pytest.approx(0.1, abs=0.005)  # woken, it fell to the floor


def test_without_a_bounding_object_nothing_is_there() -> None:
    # control for the test above: the shelf without a boundingObject stops neither the ray nor the ball
    sup = _supervisor()
    _run(sup, 1.5)
    assert sup.getDevice("ds").getValue() == pytest.approx(2.0)
    assert _z(sup, "BALL") == pytest.approx(0.1, abs=0.005)


def test_bounding_object_imported_on_a_falling_body_sits_where_the_body_is() -> None:
    # a body with mass but no boundingObject falls through the floor; given a 0.1 m sphere after 0.1 s (about
    # 5 cm down) it lands on the floor with its centre 0.1 m up. Placed at the load pose instead, the sphere
    # would sit 5 cm above the body and it would rest at 0.05 m.
    sup = _supervisor()
    _run(sup, 0.1)
    drop = sup.getFromDef("DROP")
    assert 0.4 < _z(sup, "DROP") < 0.47
    drop.getField("boundingObject").importSFNodeFromString("Sphere { radius 0.1 }")
    _run(sup, 1.5)
    assert _z(sup, "DROP") == pytest.approx(0.1, abs=0.005)
    control = _supervisor()
    _run(control, 1.0)
    assert _z(control, "DROP") < -1.0  # without it, it falls through the floor
