"""TouchSensor (bumper) × a joint below it (webots-devices.md §2.3): the flag is set when "dCollide between one of
the sensor's geoms and another Solid's geom returns ≥1 contact" (D:128-129). A HingeJoint's endPoint below the
sensor is another Solid, with its own body: its bounding object touching something is not the sensor touching.

Hand computation: no gravity; the sensor's 0.1 m box is at the origin (it spans x ≤ 0.05), the endPoint's 0.1 m
box at x = 0.5 (0.45…0.55). A static 0.1 m box at x = 0.6 (0.55…0.65) overlaps only the endPoint's box, so the
bumper reads 0 (D:131 "otherwise 0.0"); the same static box at x = 0.09 (0.04…0.14) overlaps the sensor's box by
1 cm: the bumper reads 1 (D:130).
"""

from __future__ import annotations

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

TS = 8


def _bumper(static_x: float) -> Supervisor:
    return quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ supervisor TRUE children [
  TouchSensor {{ name "bumper" boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} children [
    HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 }}
      endPoint Solid {{ translation 0.5 0 0 boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} }} }}
  ] }}
] }}
Solid {{ translation {static_x} 0 0 boundingObject Box {{ size 0.1 0.1 0.1 }} }}
""")


def _reading(sup: Supervisor) -> float:
    bumper = sup.getDevice("bumper")
    bumper.enable(TS)
    sup.step(TS)
    return float(bumper.getValue())


def test_a_bumper_does_not_feel_what_touches_the_solid_jointed_below_it() -> None:
    assert _reading(_bumper(0.6)) == 0.0


def test_a_bumper_feels_what_touches_its_own_bounding_object() -> None:
    assert _reading(_bumper(0.09)) == 1.0
