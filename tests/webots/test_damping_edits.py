"""A supervisor's edit of a body's damping reaches ODE at the next step, as in Webots: a ``Damping`` node's
``linear`` or ``angular`` written, a Damping node imported into or removed from ``Physics.damping`` (the body
then falls back on ``WorldInfo.defaultDamping``, or on none), and the world's default edited (bodies without
their own damping follow it).

Expectations by hand (no gravity, no contact, basicTimeStep h = 4 ms). Webots turns a fraction d of speed lost
per second into ODE's per-step scale c = 1 - (1 - d)^h (§1.4) and ODE multiplies the speed by (1 - c) at each
step: over n steps v = v0 (1 - c)^n = v0 (1 - d)^(n h). Each test checks the decay before the edit (the
control), so code that leaves the old damping in place fails the check after it."""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.kicks import supervisor_in

TS = 4
H = TS / 1000
N = 25  # steps per measurement


def _supervisor(physics: str) -> Supervisor:
    return supervisor_in(f"DEF BODY Solid {{ boundingObject Sphere {{ radius 0.1 }} {physics} }}", TS)


def _decay(sup: Supervisor) -> tuple[float, float]:
    """The fractions of speed and spin kept over N steps from 1 m/s along x and 1 rad/s about z."""
    body = sup.getFromDef("BODY")
    body.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    for _ in range(N):
        sup.step(TS)
    v = body.getVelocity()
    return v[0], v[5]


def _kept(d: float) -> float:
    return (1 - d) ** (N * H) if d > 0 else 1.0


def test_editing_a_damping_nodes_linear_and_angular_sets_the_bodys_damping_again() -> None:
    sup = _supervisor("physics Physics { damping DEF D Damping { linear 0.5 angular 0.2 } }")
    assert _decay(sup) == pytest.approx((_kept(0.5), _kept(0.2)), rel=1e-9)
    sup.getFromDef("D").getField("linear").setSFFloat(0.9)
    assert _decay(sup) == pytest.approx((_kept(0.9), _kept(0.2)), rel=1e-9)
    sup.getFromDef("D").getField("angular").setSFFloat(0.7)
    assert _decay(sup) == pytest.approx((_kept(0.9), _kept(0.7)), rel=1e-9)
    sup.getFromDef("D").getField("linear").setSFFloat(0.0)
    sup.getFromDef("D").getField("angular").setSFFloat(0.0)
    assert _decay(sup) == pytest.approx((1.0, 1.0), rel=1e-12)  # both 0: the world's default, none here


def test_a_damping_node_imported_into_physics_damps_the_body_and_its_removal_stops_it() -> None:
    sup = _supervisor("physics DEF P Physics { }")
    assert _decay(sup) == pytest.approx((1.0, 1.0), rel=1e-12)
    sup.getFromDef("P").getField("damping").importSFNodeFromString("Damping { linear 0.6 angular 0.4 }")
    assert _decay(sup) == pytest.approx((_kept(0.6), _kept(0.4)), rel=1e-9)
    sup.getFromDef("P").getField("damping").removeSF()
    assert _decay(sup) == pytest.approx((1.0, 1.0), rel=1e-12)


def test_a_body_without_its_own_damping_follows_the_worlds_default_and_its_edits() -> None:
    sup = _supervisor("physics DEF P Physics { damping Damping { linear 0.8 angular 0.8 } }")
    info = sup.getRoot().getField("children").getMFNode(0)
    assert info.getTypeName() == "WorldInfo"
    info.getField("defaultDamping").importSFNodeFromString("DEF W Damping { linear 0.3 angular 0.1 }")
    assert _decay(sup) == pytest.approx((_kept(0.8), _kept(0.8)), rel=1e-9)  # its own damping first
    sup.getFromDef("P").getField("damping").removeSF()
    assert _decay(sup) == pytest.approx((_kept(0.3), _kept(0.1)), rel=1e-9)
    sup.getFromDef("W").getField("linear").setSFFloat(0.5)
    assert _decay(sup) == pytest.approx((_kept(0.5), _kept(0.1)), rel=1e-9)


def test_a_reset_gives_the_body_its_load_damping_again() -> None:
    sup = _supervisor("physics Physics { damping DEF D Damping { linear 0.5 angular 0.2 } }")
    sup.getFromDef("D").getField("linear").setSFFloat(0.9)
    assert _decay(sup) == pytest.approx((_kept(0.9), _kept(0.2)), rel=1e-9)
    sup.simulationReset()
    sup.step(TS)
    assert _decay(sup) == pytest.approx((_kept(0.5), _kept(0.2)), rel=1e-9)


def test_a_shared_damping_node_edited_damps_every_body_using_it() -> None:
    sup = supervisor_in("DEF BODY Solid { boundingObject Sphere { radius 0.1 } physics DEF P Physics { damping "
                        'DEF D Damping { linear 0.5 } } } DEF OTHER Solid { translation 1 0 0 name "other" '
                        "boundingObject Sphere { radius 0.1 } physics USE P }", TS)  # fmt: skip
    sup.getFromDef("D").getField("linear").setSFFloat(0.9)
    bodies = [sup.getFromDef(name) for name in ("BODY", "OTHER")]
    for body in bodies:
        body.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    for _ in range(N):
        sup.step(TS)
    assert [body.getVelocity()[0] for body in bodies] == pytest.approx([_kept(0.9)] * 2, rel=1e-9)
