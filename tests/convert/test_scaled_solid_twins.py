"""A Solid (or a jointed one) below a scaled Transform in a Robot, in both twins: the converter scaled it (its
translation, its boundingObject and its mass, dualtwin.convert.scales) while the Webots twin ignored the scale above
Solids with a warning, so the two twins of one world rested the robot at different heights and swung a pendulum of
different lengths (webots-on-ode.md §3.1: a world frame is the product of its ancestors' matrices, a Transform's
included; §3.2: "with a scaled Transform ancestor, sizes scale, mass ∝ s³ and inertia ∝ s⁵"; §3.4: "geometries
inside a scaled Transform use scaled dimensions").

Hand computation: the robot (0.5 m up, a 1 cm ball at its origin, 1000·4/3·π·0.01³ = 0.0041888 kg) holds in
``Transform { scale 2 2 2 }`` a Solid at 0 0 -0.1 with a 0.1 m cube and a 1 kg mass: the Solid sits 0.2 m below
the robot's origin, its cube is 0.2 m wide and weighs 1·2³ = 8 kg, merged into the robot's body. The cube's bottom
is 0.3 m below the robot's origin, so the robot rests 0.3 m above the floor (unscaled: 0.1 + 0.05 = 0.15 m).
Contacts sink a few millimetres at most in either engine: 5 mm allowed.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.support.converted_twins import converted_twins, world_text

BALL = 1000 * 4 / 3 * math.pi * 0.01**3


def scaled_robot(scale: float) -> str:
    return world_text(
        'DEF R Robot { controller "<extern>" translation 0 0 0.5 physics Physics { } '
        "boundingObject Sphere { radius 0.01 } children [ "
        f"Transform {{ scale {scale} {scale} {scale} children [ Solid {{ translation 0 0 -0.1 "
        "physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 } } ] } "
        'GPS { name "gps" } ] }\n'
        "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }", "basicTimeStep 4")


@pytest.mark.parametrize(("scale", "rest", "mass"), [
    (2.0, 0.3, BALL + 8.0),
    (1.0, 0.15, BALL + 1.0),  # control: no scale
])
def test_both_twins_weigh_and_rest_the_scaled_solid_alike(tmp_path: Path, scale: float, rest: float,
                                                           mass: float) -> None:
    with converted_twins(scaled_robot(scale), tmp_path, 0.008) as (conv, webots, mujoco_twin):
        for _ in range(100):  # 0.8 s: a 0.35 m fall at most takes 0.27 s, then it settles
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("R")[2] == pytest.approx(rest, abs=5e-3)
        assert mujoco_twin.body_position("R")[2] == pytest.approx(rest, abs=5e-3)
        # the given 1 kg is scaled as the whole distribution is (§3.2: mass ∝ s³), in both twins' shared mass rules
        assert conv.compile().body("R").mass[0] == pytest.approx(mass, rel=1e-9)


def scaled_pendulum(scale: float, theta: float) -> str:
    """A fixed robot holding, in a Transform scaled by ``scale``, a hinge (axis y) anchored 0.25 m up and a 2 cm bob
    0.5 m from the anchor, started ``theta`` from the vertical (lengths before the scale)."""
    x, z = 0.5 * math.sin(theta), 0.25 - 0.5 * math.cos(theta)
    return world_text(
        f'DEF R Robot {{ controller "<extern>" translation 0 0 2 children [ Transform {{ scale {scale} {scale} '
        f"{scale} children [ HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 0 0.25 }} "
        f'device [ PositionSensor {{ name "ps" }} ] endPoint DEF BOB Solid {{ translation {x!r} 0 {z!r} '
        "boundingObject Sphere { radius 0.02 } physics Physics { } } } ] } ] }", "basicTimeStep 2")


@pytest.mark.parametrize(("scale", "half_period_x"), [
    # scaled: a 1 m pendulum (anchor 2·0.25 m up, bob 2·0.5 m from it) started 0.3 rad out, at x = sin 0.3 = 0.2955;
    # T = 2π·√((1 + 0.4·0.04²)/9.81)·(1 + 0.3²/16) = 2.0067·1.0056 = 2.0180 s, so at 1 s (half a period less
    # 9 ms, the bob nearly still) it is back near x = -0.2955
    (2.0, -0.2955),
    (1.0, None),  # control: a 0.5 m pendulum, the twins' agreement checked
])
def test_both_twins_swing_a_pendulum_below_a_scaled_transform_alike(tmp_path: Path, scale: float,
                                                                    half_period_x: float | None) -> None:
    theta = 0.3
    with converted_twins(scaled_pendulum(scale, theta), tmp_path, 0.004) as (_, webots, mujoco_twin):
        start = (scale * 0.5 * math.sin(theta), 0.0, 2 + scale * (0.25 - 0.5 * math.cos(theta)))
        assert webots.body_position("BOB") == pytest.approx(start, abs=1e-9)
        assert mujoco_twin.body_position("BOB") == pytest.approx(start, abs=1e-6)
        for _ in range(250):  # 1 s
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("BOB") == pytest.approx(mujoco_twin.body_position("BOB"), abs=1e-4)
        if half_period_x is not None:
            assert webots.body_position("BOB")[0] == pytest.approx(half_period_x, abs=2e-3)


def test_a_non_positive_scale_above_a_solid_is_reset_to_1_in_both_twins(tmp_path: Path) -> None:
    # zero and negative components are reset to 1 (solid_scale.positive_scale): the robot rests as unscaled, at
    # 0.15 m (the converter used to read 0 -1 0 as a non-uniform scale and refuse the world)
    text = scaled_robot(1.0).replace("scale 1.0 1.0 1.0", "scale 0 -1 0")
    with converted_twins(text, tmp_path, 0.008) as (conv, webots, mujoco_twin):
        for _ in range(100):
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("R")[2] == pytest.approx(0.15, abs=5e-3)
        assert mujoco_twin.body_position("R")[2] == pytest.approx(0.15, abs=5e-3)
    assert sum("Transform scale 0 -1 0: a scale component must be positive; reset to 1" in w
               for w in conv.warnings) == 1


def test_a_non_uniform_scale_above_a_solid_acts_as_its_largest_factor_in_both_twins(tmp_path: Path) -> None:
    # scale 1 2 1 above the box Solid: both twins take 2 (webots.solid_scale.body_factor), so the robot rests at
    # 0.3 m as with scale 2 2 2 (the converter refused the world before), with one warning in the conversion
    text = scaled_robot(1.0).replace("scale 1.0 1.0 1.0", "scale 1 2 1")
    with converted_twins(text, tmp_path, 0.008) as (conv, webots, mujoco_twin):
        for _ in range(100):
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("R")[2] == pytest.approx(0.3, abs=5e-3)
        assert mujoco_twin.body_position("R")[2] == pytest.approx(0.3, abs=5e-3)
    assert sum("Transform scale 1 2 1 is not uniform above a Solid or joint" in w for w in conv.warnings) == 1
