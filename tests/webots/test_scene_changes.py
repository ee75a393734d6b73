"""Nodes a supervisor imports or removes while the simulation runs take part in the physics, as in Webots: an
imported Solid with Physics falls, collides with the world and with other imported Solids, is seen by ray
sensors; a removed one stops colliding and stops being seen; a reset takes imported Solids out again. The SF
vector setters that place such nodes take a list only, as Webots' Python Field does.

Expectations follow from the geometry alone: a 0.2 m cube resting on the floor has its centre 0.1 m up (soft
contacts leave it a few millimetres lower), a distance sensor at the origin looking along +x reads the
distance to the first face it meets (lookup table = identity up to 2 m)."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Node, Supervisor
from dualtwin.webots.physics import Simulation

TS = 16
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF FLOOR Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF PEDESTAL Solid {{ translation -1 0 0.25 name "pedestal" boundingObject Box {{ size 0.5 0.5 0.5 }} }}
DEF SUP Robot {{ translation 0 0 0.1 supervisor TRUE children [
  DistanceSensor {{ name "ds" lookupTable [ 0 0 0, 2 2 0 ] }} ] }}
"""
CUBE = ('DEF CUBE Solid {{ translation {x} 0 {z} name "cube{x}" children [ Shape {{ geometry DEF B Box {{ size 0.2 0.2 0.2 }} }} ] '
        'boundingObject USE B {physics} }}')


def _supervisor() -> Supervisor:
    sim = Simulation(load_world_text(WORLD))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    sup.getDevice("ds").enable(TS)
    return sup


def _import(sup: Supervisor, text: str) -> None:
    sup.getRoot().getField("children").importMFNodeFromString(-1, text)


def _run(sup: Supervisor, seconds: float) -> None:
    for _ in range(round(seconds * 1000 / TS)):
        sup.step(TS)


def _cube(sup: Supervisor, x: float, z: float, physics: bool = True) -> Node:
    _import(sup, CUBE.format(x=x, z=z, physics="physics Physics { density 1000 }" if physics else ""))
    node = sup.getFromDef("CUBE")
    assert node is not None
    return node


def test_imported_solid_falls_onto_the_floor() -> None:
    sup = _supervisor()
    cube = _cube(sup, 1.0, 0.5)
    _run(sup, 1.0)
    assert cube.getPosition()[2] == pytest.approx(0.1, abs=0.005)  # resting on the floor
    assert cube.getVelocity()[2] == pytest.approx(0.0, abs=0.01)
    still = _supervisor()
    fixed = _cube(still, 1.0, 0.5, physics=False)  # control: without Physics it is a static obstacle
    _run(still, 1.0)
    assert fixed.getPosition()[2] == pytest.approx(0.5)


def test_imported_solid_collides_with_the_world_and_with_imported_solids() -> None:
    sup = _supervisor()
    first = _cube(sup, -1.0, 0.8)  # above the 0.5 m pedestal
    _run(sup, 1.0)
    assert first.getPosition()[2] == pytest.approx(0.6, abs=0.005)
    _import(sup, CUBE.format(x=-1.0, z=1.2, physics="physics Physics { density 1000 }").replace("DEF CUBE", "DEF TOP"))
    top = sup.getFromDef("TOP")
    _run(sup, 1.0)
    assert top.getPosition()[2] == pytest.approx(0.8, abs=0.01)  # stacked on the first imported cube


def test_ray_sensors_see_imported_solids_and_stop_seeing_removed_ones() -> None:
    sup = _supervisor()
    ds = sup.getDevice("ds")
    sup.step(TS)
    assert ds.getValue() == pytest.approx(2.0)  # control: nothing in front
    cube = _cube(sup, 1.0, 0.1, physics=False)
    sup.step(TS)
    assert ds.getValue() == pytest.approx(0.9, abs=1e-6)  # the cube's near face
    cube.remove()
    sup.step(TS)
    assert ds.getValue() == pytest.approx(2.0)


def test_removed_solid_no_longer_holds_anything_up() -> None:
    sup = _supervisor()
    base = _cube(sup, 1.0, 0.1, physics=False)
    _import(sup, CUBE.format(x=1.0, z=0.35, physics="physics Physics { density 1000 }").replace("DEF CUBE", "DEF TOP"))
    top = sup.getFromDef("TOP")
    _run(sup, 0.5)
    assert top.getPosition()[2] == pytest.approx(0.3, abs=0.005)  # resting on the static imported cube
    base.remove()
    _run(sup, 1.0)
    assert top.getPosition()[2] == pytest.approx(0.1, abs=0.005)  # fell to the floor through where it was


def test_removing_a_world_solid_frees_what_it_held() -> None:
    sup = _supervisor()
    cube = _cube(sup, -1.0, 0.8)
    _run(sup, 1.0)
    assert cube.getPosition()[2] == pytest.approx(0.6, abs=0.005)
    sup.getFromDef("PEDESTAL").remove()
    _run(sup, 1.0)
    assert cube.getPosition()[2] == pytest.approx(0.1, abs=0.005)


def test_reset_takes_imported_solids_out_of_the_physics() -> None:
    sup = _supervisor()
    ds = sup.getDevice("ds")
    _cube(sup, 1.0, 0.1, physics=False)
    sup.step(TS)
    assert ds.getValue() == pytest.approx(0.9, abs=1e-6)
    sup.simulationReset()
    sup.step(TS)
    sup.step(TS)
    assert sup.getFromDef("CUBE") is None
    assert ds.getValue() == pytest.approx(2.0)  # the imported cube left the physics with the tree
    assert not math.isnan(ds.getValue())


def test_imported_robot_is_a_body_and_says_its_controller_does_not_start(capsys: pytest.CaptureFixture[str]) -> None:
    # a Supervisor driven directly has no process runner to start controllers (tests/webots/test_imported_robots.py
    # runs one that does)
    sup = _supervisor()
    _import(sup, 'DEF R2 Robot { translation 1 0 0.5 name "r2" controller "walker" '
                 'boundingObject DEF S Sphere { radius 0.1 } physics Physics { } }')
    _run(sup, 1.0)  # (the import's start is carried out at the supervisor's next step, as Webots does)
    assert "the controller of robot 'r2' is not started: only a runner" in capsys.readouterr().err
    assert sup.getFromDef("R2").getPosition()[2] == pytest.approx(0.1, abs=0.005)


@pytest.mark.parametrize("method, good", [("setSFVec3f", [0.5, 0.0, 0.2]), ("setSFRotation", [0.0, 0.0, 1.0, 0.3])])
def test_sf_vector_setters_take_a_list_only(method: str, good: list[float], capsys: pytest.CaptureFixture[str]) -> None:
    # Webots' Field.setSFVec2f/Vec3f/Rotation/Color check isinstance(value, list): a tuple or an array prints
    # Webots' error line and leaves the field as it was
    import numpy as np

    sup = _supervisor()
    field = sup.getFromDef("PEDESTAL").getField("translation" if method == "setSFVec3f" else "rotation")
    before = field.getSFVec3f() if method == "setSFVec3f" else field.getSFRotation()
    for refused in (tuple(good), np.array(good)):
        capsys.readouterr()
        getattr(field, method)(refused)
        assert capsys.readouterr().err == "Error: new field value has wrong type or length.\n"
        field.value = refused
        assert "wrong type or length" in capsys.readouterr().err
        sup.step(TS)
        assert (field.getSFVec3f() if method == "setSFVec3f" else field.getSFRotation()) == before
    getattr(field, method)(good)  # control: the same numbers as a list are applied at the next step
    sup.step(TS)
    assert (field.getSFVec3f() if method == "setSFVec3f" else field.getSFRotation()) == pytest.approx(good)
