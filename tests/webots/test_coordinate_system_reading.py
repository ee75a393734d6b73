"""One reading of ``WorldInfo.coordinateSystem`` for gravity and the devices (webots-on-ode.md §1.1: the field
sets the gravity direction; webots-devices.md: the Compass's north, the GPS's and InertialUnit's frames).

The devices read the value in any case and take anything but ENU, NUE or EUN as ENU (Webots' default); gravity
used to test for the exact text "ENU", so a world written ``coordinateSystem "enu"`` fell along -y while its
Compass read an ENU north. Whether Webots matches the text in any case or falls back to its ENU default for an
unknown one, "enu" is an ENU world: things fall along -z.
"""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor


def _world(system: str) -> Supervisor:
    return quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ coordinateSystem "{system}" basicTimeStep 10 }}
Robot {{ supervisor TRUE children [ Compass {{ name "c" }} ] }}
DEF BALL Solid {{ translation 0 0 5 children [ Shape {{ geometry Sphere {{ radius 0.1 }} }} ]
  boundingObject Sphere {{ radius 0.1 }} physics Physics {{ }} }}
""")


@pytest.mark.parametrize("system", ["enu", "Enu", "unknown", "ENU"])
def test_an_enu_world_falls_along_minus_z_whatever_the_case(system: str) -> None:
    sup = _world(system)
    compass = sup.getDevice("c")
    compass.enable(10)
    ball = sup.getFromDef("BALL")
    for _ in range(10):
        sup.step(10)
    x, y, z = ball.getPosition()
    # free fall for 0.1 s (ODE's semi-implicit Euler, 10 steps of 10 ms): z = 5 - g·h²·(1+2+...+10) = 5 - 0.05395
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert z == pytest.approx(5.0 - 9.81 * 0.01**2 * 55, abs=1e-9)
    assert list(compass.getValues()) == pytest.approx([0.0, 1.0, 0.0], abs=1e-9)  # the same world: north +y


def test_a_nue_world_in_lower_case_falls_along_minus_y_as_its_compass_reads_it() -> None:
    # the devices read "nue" as NUE (north +x, up +y): gravity now agrees with them
    sup = _world("nue")
    compass = sup.getDevice("c")
    compass.enable(10)
    for _ in range(10):
        sup.step(10)
    x, y, z = sup.getFromDef("BALL").getPosition()
    assert (x, z) == pytest.approx((0.0, 5.0), abs=1e-12)
    assert y == pytest.approx(-9.81 * 0.01**2 * 55, abs=1e-9)
    assert list(compass.getValues()) == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
