"""A Solid a supervisor imports inside an existing Solid joins the physics by the load's rules (Webots §3.3):
with Physics under a Solid that has a body it is merged into that body (one body, masses summed, the centre
of mass moves), under a Solid without Physics it gets its own body fixed to the world (static basis); its
removal takes its mass out again.

Expectations by hand. BASE is a 0.2 m cube of density 1000 (8 kg) resting on the floor, its support
half-width 0.1 m. A 0.1 m cube merged into it 0.5 m out along +x (and 0.2 m up, clear of the floor) moves the
body's centre of mass to x = 0.5·m/(8 + m): beyond the support (the body tips over, toward +x) when m > 2 kg,
within it when m < 2 kg; tipped, it rests on the weight's outer bottom edge. Density 8000 gives 8 kg (x = 0.25 m: tips), density 1000 gives 1 kg (x = 0.056 m:
stands). A 0.5 m box imported with Physics into the static SHELF stays fixed where it is put, so the ball
dropped on it rests with its centre 0.1 m above the box's top."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 8
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF BASE Solid {{ translation 0 0 0.1 name "base" boundingObject Box {{ size 0.2 0.2 0.2 }} physics Physics {{ }} }}
DEF SHELF Solid {{ translation 2 0 0 name "shelf" }}
DEF BALL Solid {{ translation 2 0 1.2 name "ball" boundingObject Sphere {{ radius 0.1 }} physics Physics {{ }} }}
Robot {{ translation -3 0 0 supervisor TRUE }}
"""
WEIGHT = ('DEF W Solid {{ translation 0.5 0 0.2 name "weight" boundingObject Box {{ size 0.1 0.1 0.1 }} '
          'physics Physics {{ density {density} }} }}')


def _supervisor() -> Supervisor:
    sim = Simulation(load_world_text(WORLD))
    return Supervisor(simulation=sim)


def _run(sup: Supervisor, seconds: float) -> None:
    for _ in range(round(seconds * 1000 / TS)):
        sup.step(TS)


def _tilt(sup: Supervisor) -> float:
    """Angle in degrees between BASE's z axis and the world's."""
    return math.degrees(math.acos(max(-1.0, min(1.0, sup.getFromDef("BASE").getOrientation()[8]))))


def _add_weight(sup: Supervisor, density: float) -> None:
    sup.getFromDef("BASE").getField("children").importMFNodeFromString(-1, WEIGHT.format(density=density))


def test_solid_merged_into_a_body_moves_its_centre_of_mass_and_tips_it() -> None:
    sup = _supervisor()
    _run(sup, 0.2)  # settled
    before = sup.getFromDef("BASE").getPosition()
    _add_weight(sup, 8000)
    com = sup.getFromDef("BASE").getCenterOfMass()
    assert com[0] == pytest.approx(before[0] + 0.25, abs=1e-3)  # x = 0.5 * 8 / 16
    assert com[2] == pytest.approx(before[2] + 0.1, abs=1e-3)  # z = 0.2 * 8 / 16
    sup.step(TS)
    assert sup.getFromDef("BASE").getPosition() == pytest.approx(before, abs=1e-3)  # the root did not jump
    assert sup.getFromDef("W").getPosition()[0] == pytest.approx(before[0] + 0.5, abs=1e-3)
    _run(sup, 1.5)
    # it tipped over its +x bottom edge until the weight's outer bottom edge (0.45 m out, 0.25 m up from
    # that edge) touched the floor: atan(0.25 / 0.45) = 29.05 degrees
    assert _tilt(sup) == pytest.approx(math.degrees(math.atan2(0.25, 0.45)), abs=1.0)
    assert sup.getFromDef("BASE").getPosition()[0] > before[0]  # toward the weight


def test_a_light_merged_solid_leaves_it_standing() -> None:
    # control: the same import, 1 kg, keeps the centre of mass over the support
    sup = _supervisor()
    _run(sup, 0.2)
    _add_weight(sup, 1000)
    _run(sup, 1.5)
    assert _tilt(sup) < 1.0
    assert sup.getFromDef("W").getPosition()[2] == pytest.approx(0.3, abs=0.01)  # carried by the body


def test_removing_a_merged_solid_takes_its_mass_out() -> None:
    sup = _supervisor()
    _run(sup, 0.2)
    before = sup.getFromDef("BASE").getPosition()
    _add_weight(sup, 8000)
    sup.step(TS)
    sup.getFromDef("W").remove()
    assert sup.getFromDef("BASE").getCenterOfMass() == pytest.approx(before, abs=2e-3)
    _run(sup, 1.5)
    assert _tilt(sup) < 1.0  # 8 kg at x = 0.25 m left in the body would tip it


def test_solid_with_physics_under_a_static_solid_is_fixed_to_the_world() -> None:
    sup = _supervisor()
    sup.getFromDef("SHELF").getField("children").importMFNodeFromString(
        -1, 'DEF STAND Solid { translation 0 0 0.25 name "stand" boundingObject Box { size 0.5 0.5 0.5 } '
            'physics Physics { } }')
    _run(sup, 1.5)
    assert sup.getFromDef("STAND").getPosition()[2] == pytest.approx(0.25, abs=2e-3)  # it does not fall (the
    # fixed joint gives a fraction of a millimetre under the ball)
    assert sup.getFromDef("BALL").getPosition()[2] == pytest.approx(0.6, abs=0.005)  # the ball rests on it
    control = _supervisor()
    _run(control, 1.5)
    assert control.getFromDef("BALL").getPosition()[2] == pytest.approx(0.1, abs=0.005)


def test_importing_at_the_start_is_loading_it() -> None:
    # the merge at run time is the load's merge: the weight imported before the first step, or written in the
    # world, gives the same motion (same body, mass, centre of mass and inertia; only the order of the calls
    # that build it differs)
    sup = _supervisor()
    _add_weight(sup, 8000)
    written = WORLD.replace("physics Physics { } }\nDEF SHELF",
                            "physics Physics { } children [ " + WEIGHT.format(density=8000) + " ] }\nDEF SHELF")
    assert written != WORLD
    loaded = Supervisor(simulation=Simulation(load_world_text(written)))
    for s in (sup, loaded):
        _run(s, 0.6)
    for name in ("BASE", "W"):
        assert sup.getFromDef(name).getPosition() == pytest.approx(loaded.getFromDef(name).getPosition(), abs=1e-4)
    assert sup.getFromDef("BASE").getOrientation() == pytest.approx(loaded.getFromDef("BASE").getOrientation(),
                                                                    abs=1e-4)
    assert _tilt(sup) > 5.0  # it is tipping by then
