"""A BallJoint's per-axis features that MuJoCo's ball joint cannot hold are reported, not dropped silently.

Webots turns a BallJoint through Euler AMotors (on-ODE §4.4): stops act on each of its three axes and springs on
a second AMotor per axis, while MuJoCo's ball joint has one stiffness for every rotation and limits only the
rotation angle. The converter dropped BallJoint stops without a word (a pendulum Webots holds within +-0.3 rad
swung freely in MuJoCo); it now says so, as it already did for the joint's devices and position.
"""

from __future__ import annotations

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text


def ball_world(parameters: str, extra: str = "") -> str:
    return world_text(
        'DEF R Robot { controller "<extern>" children [ DEF B BallJoint { '
        f"jointParameters BallJointParameters {{ {parameters} }} {extra} "
        "endPoint DEF P Solid { translation 0.2 0 0 physics Physics { density -1 mass 0.5 } "
        "boundingObject Box { size 0.1 0.05 0.02 } } } ] }", "basicTimeStep 4")


def notes(text: str) -> list[str]:
    return [w for w in convert_world_text(text, "ball.wbt").warnings if "BallJoint" in w]


def test_stops_are_reported() -> None:
    assert [w for w in notes(ball_world("minStop -0.3 maxStop 0.3")) if "stops are not converted" in w]
    assert [w for w in notes(ball_world("", "jointParameters3 JointParameters { minStop -1 maxStop 1 }"))
            if "stops are not converted" in w]


def test_per_axis_dynamics_are_reported() -> None:
    assert [w for w in notes(ball_world("", "jointParameters2 JointParameters { springConstant 2 }"))
            if "springConstant/dampingConstant/staticFriction" in w]
    assert [w for w in notes(ball_world("dampingConstant 0.1")) if "springConstant/dampingConstant" in w]


def test_an_anchor_alone_converts_without_remarks() -> None:
    assert notes(ball_world("anchor 0 0 0.1")) == []
