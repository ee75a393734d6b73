"""Buoyancy follows a supervisor's run-time edits of what makes a Solid immersed: ImmersionProperties imported into
or removed from a Solid's ``immersionProperties``, and Physics given to a Solid that has them, act from the next
step, as every field write reaches the physics at the next step in Webots. Before, the immersed Solids were those
of the load (a world with no immersed Solid at load had no buoyancy at all).

Expected values by hand (webots-devices Fluid: Archimedes, ρ·V·g): a box of density 500 wholly under water (a
Fluid's default density 1000) is pushed up by 1000·V·g against a weight of 500·V·g, so it rises at g and gains
g·h per step (ODE: v ← v + h·F/m); without buoyancy it loses g·h per step.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.kicks import supervisor_in

TS = 8
H = TS / 1000
G = 9.81
POOL = 'Fluid { translation 0 0 0.5 boundingObject Box { size 4 4 1 } }'
IMMERSION = 'ImmersionProperties { fluidName "fluid" }'


def _box(physics: str = "physics Physics { density 500 }", immersion: str = "") -> str:
    return (f"DEF BOX Solid {{ translation 0 0 0.5 boundingObject Box {{ size 0.1 0.1 0.1 }} {physics} "
            f"immersionProperties [ {immersion} ] }}")


def _supervisor(scene: str) -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return supervisor_in(POOL + " " + scene, TS, gravity=G)


def _gain(sup: Supervisor) -> float:
    """The vertical speed the box gains over one step."""
    box = sup.getFromDef("BOX")
    before = box.getVelocity()[2]
    assert sup.step(TS) == 0
    return box.getVelocity()[2] - before


def test_immersion_properties_imported_at_run_time_make_the_box_float() -> None:
    sup = _supervisor(_box())
    assert _gain(sup) == pytest.approx(-G * H, rel=1e-9)  # the control: no immersionProperties, it sinks
    sup.getFromDef("BOX").getField("immersionProperties").importMFNodeFromString(-1, IMMERSION)
    assert _gain(sup) == pytest.approx(G * H, rel=1e-9)  # (before: -g·h, not immersed)


def test_immersion_properties_removed_at_run_time_let_the_box_sink() -> None:
    sup = _supervisor(_box(immersion=IMMERSION))
    assert _gain(sup) == pytest.approx(G * H, rel=1e-9)  # it floats up (this removal already acted before)
    sup.getFromDef("BOX").getField("immersionProperties").removeMF(0)
    assert _gain(sup) == pytest.approx(-G * H, rel=1e-9)


def test_a_solid_given_physics_at_run_time_is_pushed_by_the_fluid() -> None:
    sup = _supervisor(_box(physics="", immersion=IMMERSION))
    assert _gain(sup) == 0.0  # the control: static, no body
    sup.getFromDef("BOX").getField("physics").importSFNodeFromString("Physics { density 500 }")
    sup.step(TS)  # its first step from rest, buoyancy included
    assert _gain(sup) == pytest.approx(G * H, rel=1e-9)  # (before: -g·h, the load had no immersed body)


def test_a_gravity_edit_turns_the_fluid_surface_with_it() -> None:
    # The surface of a Fluid box is its face the most against the gravity: with the gravity written upward (-9.81:
    # S §1.1, along the down axis) it is the pool's bottom face z = 0. A 0.1 m ball centred on that face is half
    # immersed: V = (2/3)·π·0.1³ = 2.0944e-3 m³, pushed by -ρ·V·g = -1000·2.0944e-3·9.81 = -20.546 N along z (down,
    # against the new gravity). The surface was left at the top face z = 1, and the ball counted as wholly
    # immersed below it: twice that force.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sup = Supervisor(simulation=Simulation(load_world_text(
            f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity {G} }}\n{POOL}\n"
            "DEF BALL Solid { boundingObject Sphere { radius 0.1 } physics Physics { density -1 mass 1 } "
            f"immersionProperties [ {IMMERSION} ] }}\nRobot {{ supervisor TRUE }}\n")))
    try:
        sup.getRoot().getField("children").getMFNode(0).getField("gravity").setSFFloat(-G)
        sup.step(TS)  # (the first step: the force is reckoned with the ball where the world put it)
        ((_, force, _),) = sup.simulation.extensions["buoyancy"].last_forces
        assert force == pytest.approx((0.0, 0.0, -1000 * (2 / 3) * math.pi * 0.1**3 * G), rel=1e-6)
    finally:
        sup.simulation.close()
