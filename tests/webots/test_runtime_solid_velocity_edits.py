"""A supervisor's write of a Solid's ``linearVelocity`` or ``angularVelocity`` acts from the next step, as the load
reads them: the velocity of the body the Solid roots (its centre of mass), or the kinematic motion of a Solid
without Physics that nothing carries. Before, a write reached neither (a body kept its velocity, and a Solid
without Physics at rest at load never moved); only a Solid already drifting at load followed its fields.

Expected values by hand: no gravity, no contact, basicTimeStep h = 8 ms: a body moving at v covers v·h per step
(ODE's step x ← x + h·v with v unchanged), and so does a drifting Solid (Webots' kinematic motion, one step of
its velocity per basic step).
"""

from __future__ import annotations

import math

import pytest

from tests.support.kicks import supervisor_in

TS = 8
H = TS / 1000
BALL = "DEF S Solid { boundingObject Sphere { radius 0.1 } physics Physics { density -1 mass 1 } }"
STATIC = "DEF S Solid { boundingObject Sphere { radius 0.1 } }"


def _moved(sup: object, steps: int) -> list[float]:
    s = sup.getFromDef("S")
    before = s.getPosition()
    for _ in range(steps):
        assert sup.step(TS) == 0
    return [a - b for a, b in zip(s.getPosition(), before, strict=True)]


@pytest.mark.parametrize("scene", [BALL, STATIC], ids=["body", "without-physics"])
def test_a_written_linear_velocity_moves_the_solid_from_the_next_step(scene: str) -> None:
    sup = supervisor_in(scene, TS)
    assert _moved(sup, 5) == [0.0, 0.0, 0.0]  # the control: at rest as loaded
    sup.getFromDef("S").getField("linearVelocity").setSFVec3f([1.0, -0.5, 0.0])
    assert _moved(sup, 10) == pytest.approx([10 * H, -5 * H, 0.0], abs=1e-12)  # (before: [0, 0, 0])
    assert sup.getFromDef("S").getVelocity() == pytest.approx([1.0, -0.5, 0.0, 0.0, 0.0, 0.0], abs=1e-12)
    sup.getFromDef("S").getField("linearVelocity").setSFVec3f([0.0, 0.0, 0.0])
    assert _moved(sup, 5) == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)


# a body turns by 2·atan(h·ω/2) per step (ODE integrates its quaternion: q ← normalised q + (h/2)·(0, ω)⊗q; the
# gyroscopic term is nil for a sphere), a Solid without Physics by h·ω (its kinematic motion)
@pytest.mark.parametrize(("scene", "turn"), [(BALL, 10 * 2 * math.atan(H * 2.0 / 2)), (STATIC, 10 * 2.0 * H)],
                         ids=["body", "without-physics"])
def test_a_written_angular_velocity_turns_the_solid_and_keeps_its_linear_velocity(scene: str, turn: float) -> None:
    sup = supervisor_in(scene, TS)
    solid = sup.getFromDef("S")
    solid.getField("linearVelocity").setSFVec3f([1.0, 0.0, 0.0])
    solid.getField("angularVelocity").setSFVec3f([0.0, 0.0, 2.0])
    for _ in range(10):
        sup.step(TS)
    assert solid.getVelocity() == pytest.approx([1.0, 0.0, 0.0, 0.0, 0.0, 2.0], abs=1e-9)
    o = solid.getOrientation()  # turned about z: its first column is (cos, sin, 0)
    assert (o[0], o[3]) == pytest.approx((math.cos(turn), math.sin(turn)), abs=1e-9)


def test_a_reset_takes_the_load_velocities_back() -> None:
    sup = supervisor_in(STATIC + " " + BALL.replace("DEF S", "DEF B").replace("Solid {", "Solid { translation 1 0 0"),
                        TS)
    for name in ("S", "B"):
        sup.getFromDef(name).getField("linearVelocity").setSFVec3f([1.0, 0.0, 0.0])
    sup.step(TS)
    for name in ("S", "B"):
        assert sup.getFromDef(name).getVelocity() == pytest.approx([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # the writes acted
    sup.simulationReset()
    sup.step(TS)
    assert sup.getFromDef("S").getField("linearVelocity").getSFVec3f() == [0.0, 0.0, 0.0]
    assert _moved(sup, 5) == [0.0, 0.0, 0.0]  # the Solid without Physics no longer drifts
    assert sup.getFromDef("B").getVelocity() == [0.0] * 6


def test_a_solid_merged_into_its_parents_body_has_no_velocity_of_its_own() -> None:
    # §3.3: a Solid with Physics right under a Solid with Physics is merged into its body; its velocity fields
    # are not read at load, and a write does not move the body
    sup = supervisor_in("DEF P Solid { children [ DEF S Solid { translation 0.3 0 0 boundingObject Sphere { "
                        "radius 0.1 } physics Physics { } } ] boundingObject Sphere { radius 0.1 } "
                        "physics Physics { } }", TS)
    sup.getFromDef("S").getField("linearVelocity").setSFVec3f([1.0, 0.0, 0.0])
    assert _moved(sup, 5) == [0.0, 0.0, 0.0]
    sup.getFromDef("P").getField("linearVelocity").setSFVec3f([1.0, 0.0, 0.0])  # the control: the body's root
    assert _moved(sup, 5) == pytest.approx([5 * H, 0.0, 0.0], abs=1e-12)


def test_a_reset_makes_a_solid_stopped_at_run_time_drift_again_as_loaded() -> None:
    sup = supervisor_in(STATIC.replace("Solid {", "Solid { linearVelocity 1 0 0"), TS)
    sup.getFromDef("S").getField("linearVelocity").setSFVec3f([0.0, 0.0, 0.0])
    assert _moved(sup, 5) == [0.0, 0.0, 0.0]  # stopped by the write
    sup.simulationReset()
    sup.step(TS)  # the reset happens at the end of this step
    assert sup.getFromDef("S").getPosition()[0] == 0.0  # back at its load place, time 0
    assert _moved(sup, 5) == pytest.approx([5 * H, 0.0, 0.0], abs=1e-12)  # (without the edit applied again: 0)
