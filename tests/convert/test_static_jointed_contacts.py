"""A body jointed to the static environment does not touch the static environment (on-ODE §2.3 rule 6: ODE reports
it as connected to body 0 and Webots skips its contacts with every static geom; "a pendulum hinged to a static base
passes through a static floor"); the Webots twin does this, and the converted model now too, through MuJoCo
``<exclude>`` pairs between such a body and every body welded to the world. MuJoCo's own parent filter spares the
world, so the converted pendulum stopped on the floor where Webots' swings through it.

Hand computation: a 1 kg ball (radius 0.03 m) on a 0.2 m arm hinged about +y at 0.15 m above the floor, released
from the horizontal. Its bottom would reach the floor at 0.15 - 0.2 sin(q) - 0.03 = 0, q = asin(0.6) = 0.64 rad;
it passes the vertical (q = pi/2) at a quarter of the large-amplitude period, 1.18 (pi/2) sqrt(0.2 / 9.81) = 0.265 s
(the ball's own inertia adds under 1 %), so at 0.32 s it is past pi/2 in both twins, which agree within 0.02 rad.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text

PENDULUM = world_text(
    'DEF R Robot { controller "<extern>" translation 0 0 0.15 children [ DEF J HingeJoint {\n'
    '  jointParameters HingeJointParameters { axis 0 1 0 } device [ PositionSensor { name "s" } ]\n'
    "  endPoint DEF P Solid { translation 0.2 0 0 physics Physics { density -1 mass 1 } "
    "boundingObject Sphere { radius 0.03 } } } ] }\n"
    "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }", "basicTimeStep 4")


def test_the_hinged_body_is_excluded_from_the_static_bodies() -> None:
    model = convert_world_text(PENDULUM, "pendulum.wbt").compile()
    excluded = {(int(model.exclude_signature[i]) >> 16, int(model.exclude_signature[i]) & 0xFFFF)
                for i in range(model.nexclude)}
    world, base, ball = 0, model.body("R").id, model.body("P").id
    assert excluded == {(world, ball), (base, ball)}


def test_both_twins_swing_the_pendulum_through_the_floor(tmp_path: Path) -> None:
    with converted_twins(PENDULUM, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(40):  # 0.32 s
            webots.step()
            mujoco_twin.step()
        assert webots.sensor("s") > math.pi / 2
        assert mujoco_twin.sensor("s") == pytest.approx(webots.sensor("s"), abs=0.02)
