"""Track × WorldInfo.coordinateSystem (webots-devices.md §7.2 with webots-on-ode.md §1.1): the belt's contact
surface velocity takes its sign from the raw contact normal's component and the unit gravity's component along
"the dominant gravity axis" (§7.2, D:305-308): z in an ENU world, y in a NUE world, whose gravity is (0, −g, 0)
(webots-on-ode.md:44 "coordinateSystem ... gravity direction").

Hand computation: turning a whole ENU world by Rx(−π/2) gives the same world in NUE axes (its z becomes y). Every
dot product of the rule (c = n·ẑ_track) is unchanged by the turn, the raw normal's y in the turned world is its z
in the ENU one, and the unit gravity's y there is the ENU one's z (−1): the rule gives the same surface speed, so
a box lying on the belt is carried the same way in both worlds. The belt runs at v = 0.2 m/s (velocity control,
maxVelocity 1, maxForce 10 on a 50 kg Track resting on the ground); the 1 kg box on it (friction 1) catches up
in v/(μ·g) ≈ 0.02 s, so after 1 s it has moved 0.2·1 − 0.2·0.02/2 ≈ 0.198 m along the Track's x axis (world
x in both worlds); nothing moves it across or up.
"""

from __future__ import annotations

import math

import pytest

from tests.support.quiet_worlds import quiet_supervisor

TS = 4


def _box_travel(coordinate_system: str, turn: str) -> list[float]:
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} coordinateSystem "{coordinate_system}" }}
Pose {{ rotation {turn} children [
  Solid {{ translation 0 0 -0.5 boundingObject Box {{ size 10 10 1 }} }}
  Robot {{ supervisor TRUE children [
    Track {{ translation 0 0 0.05 boundingObject Box {{ size 2 0.4 0.1 }} physics Physics {{ mass 50 }}
      device [ LinearMotor {{ maxVelocity 1 }} ] }} ] }}
  DEF BOX Solid {{ translation 0 0 0.15 boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ mass 1 }} }}
] }}
""")
    motor = sup.getDevice("linear motor")
    motor.setPosition(math.inf)
    motor.setVelocity(0.2)
    box = sup.getFromDef("BOX")
    start = box.getPosition()
    for _ in range(250):  # 1 s
        sup.step(TS)
    return [b - a for a, b in zip(start, box.getPosition(), strict=True)]


def test_a_belt_carries_a_box_in_an_enu_world() -> None:
    dx, dy, dz = _box_travel("ENU", "0 0 1 0")
    assert abs(dx) == pytest.approx(0.198, abs=0.005)
    assert abs(dy) < 1e-3 and abs(dz) < 1e-3


def test_a_belt_carries_a_box_in_a_nue_world_as_in_the_same_enu_world() -> None:
    # the ENU world turned by Rx(-pi/2): its up axis z is the NUE world's y, the gravity axis there
    enu = _box_travel("ENU", "0 0 1 0")
    dx, dy, dz = _box_travel("NUE", "1 0 0 -1.5707963267948966")
    assert abs(dx) == pytest.approx(0.198, abs=0.005)
    assert math.copysign(1.0, dx) == math.copysign(1.0, enu[0])
    assert abs(dy) < 1e-3 and abs(dz) < 1e-3
