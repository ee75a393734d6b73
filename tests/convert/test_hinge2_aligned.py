"""A Hinge2Joint whose two axes are aligned: Webots replaces them by the world's x and z axes, with a warning
(on-ODE §4.4; the Webots twin does the same), and the converter now does too. Before, it wrote two hinges about one
axis in one body: MuJoCo's mass matrix was singular and the MuJoCo twin went unstable in its first period.

The robot is turned 0.7 rad about z, so the world's x axis is (cos 0.7, -sin 0.7, 0) in the endPoint's frame (hand
computation); the dual-twin check runs both axes' velocity motors (Webots' motor rows, the MuJoCo twin's servos
tracking the same commands) and compares where the endPoint goes, within 1 mm over 0.32 s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.convert.equivalences import HINGE2_ALIGNED
from tests.support.converted_twins import converted_twins, world_text

WORLD = world_text(
    'DEF R Robot { rotation 0 0 1 0.7 controller "<extern>" physics Physics { density -1 mass 50 } '
    "boundingObject Box { size 0.1 0.1 0.1 } children [ DEF H Hinge2Joint {\n"
    "  jointParameters HingeJointParameters { axis 0 1 0 anchor 0 0 -0.1 } jointParameters2 JointParameters { axis 0 1 0 }\n"
    '  device [ PositionSensor { name "s" } RotationalMotor { name "m" } ]\n'
    '  device2 [ PositionSensor { name "s2" } RotationalMotor { name "m2" } ]\n'
    "  endPoint DEF E Solid { translation 0.1 0.05 -0.3 physics Physics { density -1 mass 1 } "
    "boundingObject Box { size 0.1 0.1 0.1 } } } ] }", "basicTimeStep 4 gravity 0")


def test_the_axes_fall_back_to_the_worlds_x_and_z() -> None:
    conv = convert_world_text(WORLD, "aligned.wbt")
    assert [w for w in conv.warnings if HINGE2_ALIGNED in w]
    model = conv.compile()
    np.testing.assert_allclose(model.joint("H").axis, [math.cos(0.7), -math.sin(0.7), 0.0], atol=1e-12)
    np.testing.assert_allclose(model.joint("H2").axis, [0.0, 0.0, 1.0], atol=1e-12)


def test_both_twins_turn_the_endpoint_alike(tmp_path: Path) -> None:
    with converted_twins(WORLD, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.command("m", "velocity", 1.0)
            twin.command("m2", "velocity", -0.5)
            for _ in range(40):
                twin.step()
        assert mujoco_twin.sensor("s2") == pytest.approx(webots.sensor("s2"), abs=1e-3)
        assert mujoco_twin.sensor("s") == pytest.approx(webots.sensor("s"), abs=3e-3)  # the first step's ramp
        np.testing.assert_allclose(mujoco_twin.body_position("E"), webots.body_position("E"), atol=1e-3)
