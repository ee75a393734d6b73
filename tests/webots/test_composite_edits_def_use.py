"""A supervisor's edit of a DEF'd node reaches its USEs wherever they are read: a PointLight DEF'd in one Solid and
USE'd in another is one light node in two places (the twin's DEF/USE rule, docs/webots-coverage.md Solid and Pose
rows; S §7.1: USE of non-Solid nodes is fine), so an intensity written through the DEF lights both places from the
next sample. ``simulationReset`` puts both back (S §6: all fields).

The LightSensor reads ``E`` through the table [0 0 0, 100 100 0] (the identity), with
``E = intensity·cos θ/(a1 + a2·d + a3·d²)`` for white light (the LightSensor page's irradiance, as in
tests/webots/test_composite_lights_led_sensor.py). S = shared/reference/webots-on-ode.md."""

from __future__ import annotations

import pytest

from tests.support.quiet_worlds import quiet_supervisor

STEP = 8

# the sensor looks along +x; the DEF'd light 1 m ahead, its USE 2 m ahead, both on the axis (cos θ = 1)
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {STEP} gravity 0 }}
Solid {{ translation 1 0 0 children [ DEF LAMP PointLight {{ intensity 1 attenuation 0 0 1 }} ] }}
Solid {{ translation 2 0 0 name "far" children [ USE LAMP ] }}
Robot {{ supervisor TRUE children [ LightSensor {{ name "light" lookupTable [ 0 0 0, 100 100 0 ] }} ] }}
"""


@pytest.mark.parametrize("edit", [True, False])
def test_an_intensity_written_through_a_def_light_reaches_its_use(edit: bool) -> None:
    sup = quiet_supervisor(WORLD)
    sensor = sup.getDevice("light")
    sensor.enable(STEP)
    assert sup.step(STEP) != -1
    assert sensor.getValue() == pytest.approx(1.0 / 1.0 + 1.0 / 4.0)  # E = I/d² summed: 1.25
    if edit:
        sup.getFromDef("LAMP").getField("intensity").setSFFloat(3.0)
    assert sup.step(STEP) != -1
    intensity = 3.0 if edit else 1.0
    assert sensor.getValue() == pytest.approx(intensity / 1.0 + intensity / 4.0)  # 3.75 edited, 1.25 control
    sup.simulationReset()
    assert sup.step(STEP) != -1
    assert sup.step(STEP) != -1
    assert sensor.getValue() == pytest.approx(1.25)
