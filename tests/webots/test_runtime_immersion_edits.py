"""Buoyancy follows a supervisor's run-time edits of what makes a Solid immersed: ImmersionProperties imported into
or removed from a Solid's ``immersionProperties``, and Physics given to a Solid that has them, act from the next
step, as every field write reaches the physics at the next step in Webots. Before, the immersed Solids were those
of the load (a world with no immersed Solid at load had no buoyancy at all).

Expected values by hand (webots-devices Fluid: Archimedes, ρ·V·g): a box of density 500 wholly under water (a
Fluid's default density 1000) is pushed up by 1000·V·g against a weight of 500·V·g, so it rises at g and gains
g·h per step (ODE: v ← v + h·F/m); without buoyancy it loses g·h per step.
"""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots.controller import Supervisor
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
