"""A joint that Webots moves kinematically gets a conversion warning, since the converted model moves it
dynamically: an endPoint without Physics (on-ODE §4.1), and a Hinge2Joint whose parent has no body (§4.4: ODE's
hinge2 needs both bodies, Webots builds no ODE joint). The second was converted silently: on a fixed-base robot
the Webots twin turned the endPoint kinematically (a velocity command ramping at maxTorque rad/s², 10 by default)
while the MuJoCo twin reached the commanded velocity in one period, with no word from the converter.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text

HINGE2 = ('DEF H Hinge2Joint { jointParameters HingeJointParameters { axis 1 0 0 } '
          'device [ RotationalMotor { name "m" } PositionSensor { name "s" } ] endPoint DEF E Solid { translation 0 0 -0.3 physics Physics { } '
          'boundingObject Box { size 0.1 0.1 0.1 } } }')
STATIC_PARENT = "Hinge2Joint has no Physics above it (a static parent): Webots builds no ODE joint"


def _robot(physics: str, children: str) -> str:
    return world_text(f'DEF R Robot {{ controller "<extern>" {physics} boundingObject Box {{ size 0.1 0.1 0.1 }} '
                      f"children [ {children} ] }}", "basicTimeStep 4 gravity 0")


def _notes(text: str) -> list[str]:
    return [w for w in convert_world_text(text, "k.wbt").warnings if "kinematically" in w]


def test_a_hinge2_on_a_fixed_base_is_reported_kinematic() -> None:
    assert [n.split(": ", 1)[1].startswith(STATIC_PARENT) for n in _notes(_robot("", HINGE2))] == [True]


@pytest.mark.parametrize(("robot", "middle"), [("physics Physics { }", ""), ("", "physics Physics { }"),
                                                ("physics Physics { }", None)])
def test_a_hinge2_with_a_body_above_it_is_not(robot: str, middle: str | None) -> None:
    # A body above the Hinge2 anywhere up the chain (the nearest Solid with Physics, as Webots looks for it):
    # the robot, or a hinged Solid between them; with a body above, a Solid without Physics in between is
    # kinematic itself (its own warning) but the Hinge2 joins the robot's body.
    children = HINGE2 if middle == "" else (
        f'DEF K HingeJoint {{ endPoint DEF A Solid {{ {middle or ""} boundingObject Box {{ size 0.1 0.1 0.1 }} '
        f"children [ {HINGE2} ] }} }}")
    notes = _notes(_robot(robot, children))
    assert not [n for n in notes if STATIC_PARENT in n]
    assert len(notes) == (1 if middle is None else 0)  # the physics-less middle Solid's own warning
    if middle is None:
        assert "HingeJoint endPoint has no Physics: Webots moves it kinematically, MuJoCo dynamically" in notes[0]


def test_the_webots_twin_moves_it_kinematically(tmp_path: Path) -> None:
    # What the warning is about: Webots' kinematic motor ramps the speed by the available torque (10 rad/s²
    # here, on-ODE §5.3), by a·dt per 4 ms step, so after 25 steps it has turned Σ k·a·dt² = 10·0.004²·325 =
    # 0.052 rad, where the dynamic joint of the MuJoCo twin, at 1 rad/s within a step, has turned about 0.1 rad.
    with converted_twins(_robot("", HINGE2), tmp_path, 0.004) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.command("m", "velocity", 1.0)
            for _ in range(25):
                twin.step()
        assert webots.joint_position("H") == pytest.approx(0.052, abs=1e-9)
        assert mujoco_twin.joint_position("H") == pytest.approx(0.1, abs=5e-3)
