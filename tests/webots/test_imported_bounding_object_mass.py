"""A boundingObject a supervisor imports alone into a Solid with Physics gives that Solid's body its mass, as at
load (Webots §3.2: without an inertiaMatrix the mass distribution, the centre of mass and, from the density,
the mass itself come from the boundingObject); removing it goes back to the rule for a Physics node without one
(mass = density / 1000 kg, or ``mass``, with an identity inertia). The Solid stays where it is: the body's
origin moves to the new centre of mass, and a joint on the body keeps its anchor.

Expectations by hand (no gravity, basicTimeStep h = 4 ms). The imported boundingObject is a 0.2 m cube 0.1 m out
along x: reference mass 1000·0.008 = 8 kg, inertia 8·(0.2² + 0.2²)/12 = 0.05333 kg·m² about each axis through
its centre, which becomes the centre of mass. Density 500 halves both; ``mass 2`` keeps 2 kg, so the inertia is
2/8 of it. A force F along x for one step adds F·h/m to the speed, a torque τ about z adds τ·h/I to the spin;
before the import (no boundingObject) m = density / 1000 (or ``mass``) and I = 1 (times density / 1000)."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.kicks import kick, supervisor_in

TS = 4
H = TS / 1000
CUBE = "Pose { translation 0.1 0 0 children [ Box { size 0.2 0.2 0.2 } ] }"


def _supervisor(physics: str) -> Supervisor:
    return supervisor_in(f'DEF BODY Solid {{ translation 0 0 1 name "body" physics Physics {{ {physics} }} }}', TS)


def _kick(sup: Supervisor) -> tuple[float, float]:
    return kick(sup, TS)


@pytest.mark.parametrize(
    ("physics", "mass", "inertia", "bare_mass", "bare_inertia"),
    [
        ("", 8.0, 8.0 * 0.08 / 12, 1.0, 1.0),
        ("density 500", 4.0, 4.0 * 0.08 / 12, 0.5, 0.5),
        ("density -1 mass 2", 2.0, 2.0 * 0.08 / 12, 2.0, 1.0),
    ],
)
def test_imported_bounding_object_gives_the_body_its_mass_and_removing_it_takes_it_back(
    physics: str, mass: float, inertia: float, bare_mass: float, bare_inertia: float
) -> None:
    control = _supervisor(physics)  # without the import
    assert _kick(control) == pytest.approx((H / bare_mass, 0.01 * H / bare_inertia), rel=1e-6)
    sup = _supervisor(physics)
    body = sup.getFromDef("BODY")
    body.getField("boundingObject").importSFNodeFromString(CUBE)
    at = body.getPosition()
    assert body.getCenterOfMass() == pytest.approx([at[0] + 0.1, at[1], at[2]], abs=1e-9)
    sup.step(TS)
    assert body.getPosition() == pytest.approx(at, abs=1e-9)  # the Solid did not jump
    dv, dw = _kick(sup)
    assert dv == pytest.approx(H / mass, rel=1e-6)
    assert dw == pytest.approx(0.01 * H / inertia, rel=1e-6)
    body.getField("boundingObject").removeSF()
    assert body.getCenterOfMass() == pytest.approx(body.getPosition(), abs=1e-9)
    dv, dw = _kick(sup)
    assert dv == pytest.approx(H / bare_mass, rel=1e-6)
    assert dw == pytest.approx(0.01 * H / bare_inertia, rel=1e-6)


PENDULUM_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{
  translation 0 0 1
  supervisor TRUE
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      device [ PositionSensor {{ name "sensor" }} ]
      endPoint DEF ARM Solid {{ name "arm" physics Physics {{ }} }}
    }}
  ]
}}
"""


def test_bounding_object_imported_on_a_jointed_body_makes_it_a_pendulum_about_the_same_anchor() -> None:
    # ARM's origin is on the hinge axis and, without a boundingObject, so is its 1 kg: it hangs anywhere. A
    # 0.05 m ball imported 0.5 m from the axis, 0.1 rad out, moves the centre of mass there (0.5236 kg): the arm
    # swings about the same anchor as a physical pendulum, T = 2π·sqrt((2/5·r² + L²) / (g·L)) = 1.4213 s.
    # Left anchored where the old centre of mass was, the joint would hold the new one still.
    sup = Supervisor(simulation=Simulation(load_world_text(PENDULUM_WORLD)))
    sensor = sup.getDevice("sensor")
    sensor.enable(TS)
    sup.step(TS)
    x, z = -0.5 * math.sin(0.1), -0.5 * math.cos(0.1)
    sup.getFromDef("ARM").getField("boundingObject").importSFNodeFromString(
        f"Pose {{ translation {x} 0 {z} children [ Sphere {{ radius 0.05 }} ] }}")
    crossings, previous = [], sensor.getValue()
    for _ in range(round(4.5 / H)):
        sup.step(TS)
        value = sensor.getValue() + 0.1  # straight down is 0.1 rad from where the ball was put
        if previous < 0.0 <= value:
            crossings.append(sup.getTime() - H * value / (value - previous))
        previous = value
        assert math.dist(sup.getFromDef("ARM").getPosition(), (0.0, 0.0, 1.0)) < 1e-3  # the origin stays on the axis
    assert len(crossings) >= 3
    expected = 2 * math.pi * math.sqrt((0.4 * 0.05**2 + 0.25) / (9.81 * 0.5))
    assert (crossings[-1] - crossings[0]) / (len(crossings) - 1) == pytest.approx(expected, rel=0.01)
