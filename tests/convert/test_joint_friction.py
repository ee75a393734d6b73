"""A joint's ``staticFriction`` holds in the converted model as ODE's friction row does (on-ODE §4.5, §5.3).

Webots' static friction is a joint motor with target velocity 0 and force limit ``staticFriction`` at the world
CFM: below that limit the joint stays still. The converter wrote ``frictionloss`` with MuJoCo's default softness
(solref 0.02 s, impedance 0.9), which lets a loaded joint creep: the pendulum below slid at 0.034 rad/s where the
Webots twin holds it. The friction row now gets ODE's stiffness (:func:`dualtwin.convert.equivalences.friction_solref`).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text


def _pendulum(friction: float) -> str:
    # A 1 kg box 0.3 m out on a horizontal hinge axis: gravity pulls with 1 x 9.81 x 0.3 = 2.943 N·m.
    return world_text(
        'DEF R Robot { controller "<extern>" children [ DEF H HingeJoint {\n'
        f"  jointParameters HingeJointParameters {{ axis 0 1 0 staticFriction {friction} }}\n"
        '  device [ PositionSensor { name "s" } ]\n'
        "  endPoint DEF E Solid { translation 0.3 0 0 physics Physics { density -1 mass 1 } "
        "boundingObject Box { size 0.1 0.1 0.1 } } } ] }", "basicTimeStep 4")


def test_the_friction_row_is_odes() -> None:
    # h = 2 ms (MuJoCo's step at basicTimeStep 4): solreffriction (2h, 1); the joint's inertia 0.3² + 0.1²/6 =
    # 0.091667 kg·m² at the world CFM 1e-5 gives d = 1/(1 + 1e-5 x 0.091667 / 0.002) = 0.999542.
    model = convert_world_text(_pendulum(5.0), "f.wbt").compile()
    assert [float(v) for v in model.dof_solref[0]] == pytest.approx([0.004, 1.0])
    assert float(model.dof_solimp[0][0]) == pytest.approx(1 / (1 + 1e-5 * (0.09 + 0.01 / 6) / 0.002), rel=1e-9)


def test_a_loaded_joint_below_its_friction_holds_in_both_twins(tmp_path: Path) -> None:
    # 5 N·m of friction against 2.943 N·m of load: neither twin moves (ODE's CFM creep is far below 1e-4 rad).
    with converted_twins(_pendulum(5.0), tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(125):  # 1 s
            webots.step()
            mujoco_twin.step()
        for twin in (webots, mujoco_twin):
            assert abs(twin.joint_position("H")) < 1e-4, twin.name


def test_above_it_the_joint_slides_alike(tmp_path: Path) -> None:
    # Control: 0.5 N·m cannot hold 2.943 N·m; both pendulums swing down together (within 1 %: the two engines'
    # integration of the same swing, 0.3 s and about 0.8 rad).
    with converted_twins(_pendulum(0.5), tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(31):
            webots.step()
            mujoco_twin.step()
        assert webots.joint_position("H") > 0.5
        assert mujoco_twin.joint_position("H") == pytest.approx(webots.joint_position("H"), rel=0.01)
