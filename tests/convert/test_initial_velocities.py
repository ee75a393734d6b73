"""Solids' initial velocities (``linearVelocity``/``angularVelocity``, PROTO ``hidden linearVelocity_N``...) reach the
converted model as its ``webots_initial`` keyframe, which the MuJoCo twin (and ``mj_resetDataKeyframe`` in any MuJoCo
program) starts from: a thrown ball flies, a wheel spins, as in the Webots twin.

Expected values are hand computations: with one step size h, MuJoCo's free body (implicitfast, no damping) and
ODE's ``dWorldStep`` both integrate semi-implicit Euler, v += h a then x += h v, so after n steps
x = x0 + v0 n h - g h^2 n (n + 1) / 2 exactly (tolerance 1e-9 m: float rounding only). The dual-twin test runs the
Webots twin on the same world at the same step (basicTimeStep 2 ms = the converted model's timestep).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

H = 0.002  # basicTimeStep 2 ms: the converted model steps at the same h
PERIOD = 0.008
G = 9.81
BALL = 'DEF BALL Solid {{ translation 0 0 1 name "ball" boundingObject Sphere {{ radius 0.1 }} physics Physics {{ mass 1 }} {v} }}'
THROWN = "linearVelocity 2 0 1.5 angularVelocity 0 0 3"
WHEEL = """DEF R Robot {{ translation 0 3 0 controller "<extern>" children [
  DEF SPIN HingeJoint {{
    jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 0 0.5 }}
    device [ PositionSensor {{ name "spin sensor" }} ]
    endPoint DEF WHEEL Solid {{ translation 0 0 0.5 physics Physics {{ }} boundingObject Cylinder {{ radius 0.1 height 0.05 }} {v} }}
  }}
] }}"""
SPINNING = "angularVelocity 0 5 0"


def _world(ball: str = THROWN, wheel: str = SPINNING) -> str:
    return world_text(BALL.format(v=ball) + "\n" + WHEEL.format(v=wheel), "basicTimeStep 2")


def _ball_by_hand(n: int, v0: tuple[float, float] = (2.0, 1.5)) -> tuple[float, float]:
    """(x, z) of the ball after n steps of semi-implicit Euler from (0, 1) at (vx, vz) = v0."""
    return v0[0] * n * H, 1.0 + v0[1] * n * H - G * H * H * n * (n + 1) / 2


def test_the_keyframe_carries_the_velocities_into_any_mujoco_program() -> None:
    conv = convert_world_text(_world(), "thrown.wbt")
    model = mujoco.MjModel.from_xml_string(conv.xml)  # the written MJCF, as another program reads it
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("webots_initial").id)
    ball = model.jnt_dofadr[model.joint("BALL_free").id]
    spin = model.jnt_dofadr[model.joint("SPIN").id]
    # The ball is not rotated, so its body-frame angular velocity is the world one.
    assert data.qvel[ball:ball + 6] == pytest.approx([2, 0, 1.5, 0, 0, 3], abs=1e-12)
    assert data.qvel[spin] == pytest.approx(5.0, abs=1e-12)
    assert data.qpos == pytest.approx(model.qpos0)  # the joints' positions are the model's qpos0


def test_the_twin_starts_from_them_at_every_reset() -> None:
    conv = convert_world_text(_world(), "thrown.wbt")
    twin = MuJoCoTwin(conv.spec, PERIOD)
    for _ in range(2):
        for _ in range(40):  # 0.32 s, 160 steps
            twin.step()
        x, z = _ball_by_hand(160)
        assert twin.body_position("BALL") == pytest.approx([x, 0.0, z], abs=1e-9)
        assert twin.joint_position("SPIN") == pytest.approx(5.0 * 0.32, abs=1e-9)
        twin.reset()
        assert twin.joint_velocity("SPIN") == pytest.approx(5.0, abs=1e-12)


def test_without_velocities_no_keyframe_and_the_bodies_start_at_rest() -> None:
    conv = convert_world_text(_world(ball="", wheel=""), "still.wbt")
    assert "<keyframe" not in conv.xml
    twin = MuJoCoTwin(conv.spec, PERIOD)
    for _ in range(40):
        twin.step()
    assert twin.body_position("BALL") == pytest.approx([0.0, 0.0, _ball_by_hand(160, (0.0, 0.0))[1]], abs=1e-9)
    assert twin.joint_position("SPIN") == pytest.approx(0.0, abs=1e-12)


def test_the_frame_origin_of_an_off_centre_body_moves_with_its_spin() -> None:
    # Webots' linearVelocity is the centre of mass's (the ODE body's); MuJoCo's free joint moves the frame
    # origin: with the CoM 0.1 m along x, spinning at 2 rad/s about z with a still CoM, the origin moves at
    # w x (origin - com) = (0, 0, 2) x (-0.1, 0, 0) = (0, -0.2, 0).
    ball = ('DEF BALL Solid { translation 0 0 1 name "ball" boundingObject Sphere { radius 0.1 } '
            "physics Physics { mass 1 centerOfMass [ 0.1 0 0 ] } angularVelocity 0 0 2 }")
    conv = convert_world_text(world_text(ball + "\n" + WHEEL.format(v=""), "gravity 0"), "offset.wbt")
    model = conv.compile()
    key = model.key("webots_initial")
    assert key.qvel[:6] == pytest.approx([0, -0.2, 0, 0, 0, 2], abs=1e-12)


def test_proto_hidden_velocities_are_the_instance_solids(tmp_path: Path) -> None:
    (tmp_path / "Ball.proto").write_text(
        "#VRML_SIM R2023b utf8\nPROTO Ball [ field SFVec3f translation 0 0 1 ] {\n"
        "  Solid { translation IS translation boundingObject Sphere { radius 0.1 } physics Physics { mass 1 } }\n}\n")
    scene = ('EXTERNPROTO "Ball.proto"\nDEF BALL Ball { hidden linearVelocity_0 0 3 0 hidden angularVelocity_0 1 0 0 }\n'
             + WHEEL.format(v=""))
    (tmp_path / "w.wbt").write_text(world_text(scene), encoding="utf-8")
    from dualtwin.convert import convert_world

    model = convert_world(tmp_path / "w.wbt").compile()
    assert model.key("webots_initial").qvel[:6] == pytest.approx([0, 3, 0, 1, 0, 0], abs=1e-12)


def test_a_merged_solid_s_velocity_is_reported_not_converted() -> None:
    merged = ('Solid { translation 0 0 0.1 name "part" physics Physics { } boundingObject Sphere { radius 0.01 } '
              "linearVelocity 1 0 0 }")
    wheel = WHEEL.format(v="children [ " + merged + " ]")
    conv = convert_world_text(world_text(BALL.format(v="") + "\n" + wheel), "merged.wbt")
    assert "<keyframe" not in conv.xml
    assert any("'part' not converted" in w and "merged" in w for w in conv.warnings), conv.warnings


def test_the_webots_twin_flies_and_spins_them_the_same(tmp_path: Path) -> None:
    # Same step, same integrator for the ball's centre (1e-9 m). Rotations: MuJoCo integrates a constant spin
    # exactly (w t), ODE's dWorldStep turns a body's quaternion by q += h/2 w q and normalises, i.e. by
    # 2 atan(w h / 2) a step (hand value, 1.3e-5 rad less than w t for the wheel over 160 steps). The wheel turns
    # about a principal axis through its centre of mass (no gyroscopic or gravity torque), so both keep 5 rad/s;
    # 1e-8 rad leaves room for ODE's hinge rows, which hold the axis to solver precision.
    with converted_twins(_world(), tmp_path, PERIOD) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            for _ in range(40):
                twin.step()
        x, z = _ball_by_hand(160)
        spin = {"mujoco": 5.0 * 160 * H, "webots": 160 * 2 * math.atan(5.0 * H / 2)}
        yaw = {"mujoco": 3.0 * 160 * H, "webots": 160 * 2 * math.atan(3.0 * H / 2)}
        for twin in (webots, mujoco_twin):
            assert twin.body_position("BALL") == pytest.approx([x, 0.0, z], abs=1e-9), twin.name
            assert twin.joint_position("SPIN") == pytest.approx(spin[twin.name], abs=1e-8), twin.name
            assert twin.joint_velocity("SPIN") == pytest.approx(5.0, abs=1e-8), twin.name
            R = twin.body_orientation("BALL")
            assert math.atan2(R[1, 0], R[0, 0]) == pytest.approx(yaw[twin.name], abs=1e-8), twin.name


def test_velocities_the_joints_cannot_follow_are_projected_as_ode_s_first_step_does(tmp_path: Path) -> None:
    # A free robot moving along x, its wheel spinning and moving up on its own: no joint motion gives both. ODE's
    # joint rows pull them together in its first step; the keyframe projects them by momentum. They agree to
    # 2e-3 (ODE's rows are soft: world ERP 0.2, CFM 1e-5) where the bodies' own values differ by up to 7 rad/s.
    # By hand: the projection keeps the linear momentum, 2 kg x (0.5, 0, 0) + 1 kg x (0, 0, 1) = (1, 0, 1).
    scene = ('DEF R Robot { translation 0 0 1 controller "<extern>" physics Physics { mass 2 } '
             "boundingObject Box { size 0.2 0.2 0.2 } linearVelocity 0.5 0 0 children [\n"
             "  DEF SPIN HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 anchor 0.3 0 0 }\n"
             '    device [ PositionSensor { name "spin sensor" } ]\n'
             "    endPoint DEF WHEEL Solid { translation 0.3 0 0 physics Physics { mass 1 } "
             "boundingObject Cylinder { radius 0.1 height 0.05 } angularVelocity 0 5 0 linearVelocity 0 0 1 } } ] }")
    with converted_twins(world_text(scene, "basicTimeStep 2 gravity 0"), tmp_path, H) as (_, webots, mujoco_twin):
        momentum = 2.0 * mujoco_twin.body_velocity("R")[:3] + 1.0 * mujoco_twin.body_velocity("WHEEL")[:3]
        assert momentum == pytest.approx([1.0, 0.0, 1.0], abs=1e-5)  # 1e-5: the MJCF's 6 significant digits
        webots.step()
        mujoco_twin.step()
        assert mujoco_twin.joint_velocity("SPIN") == pytest.approx(webots.joint_velocity("SPIN"), abs=2e-3)
        assert mujoco_twin.body_velocity("R") == pytest.approx(webots.body_velocity("R"), abs=2e-3)


def test_proto_hidden_joint_position_and_endpoint_spin(tmp_path: Path) -> None:
    # A saved PROTO robot: hidden position_0_0 (its hinge, already the joint's ref before this change) and the
    # hidden velocities of the hinge's endPoint (Solid 1 in pre-order), turning about the hinge at 2 rad/s: its
    # centre 0.2 m from the axis moves at w x r = (0, 0, 2) x (0.2, 0, 0) = (0, 0.4, 0). By hand the hinge rate
    # is 2; without the linear velocity the joints cannot follow both, and the projection keeps the angular
    # momentum about the axis: 2 I / (I + m r^2) = 2 x (1/600) / (1/600 + 0.04) = 0.08 (1 kg box of 0.1 m).
    (tmp_path / "Arm.proto").write_text(
        "#VRML_SIM R2023b utf8\nPROTO Arm [ ] {\n  Robot { children [ HingeJoint {\n"
        "    jointParameters HingeJointParameters { axis 0 0 1 }\n"
        '    device [ PositionSensor { name "arm sensor" } ]\n'
        "    endPoint Solid { translation 0.2 0 0 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }\n"
        "  } ] }\n}\n")
    from dualtwin.convert import convert_world

    for linear, rate in (("hidden linearVelocity_1 0 0.4 0", 2.0), ("", 0.08)):
        scene = f'EXTERNPROTO "Arm.proto"\nDEF ARM Arm {{ hidden position_0_0 0.4 hidden angularVelocity_1 0 0 2 {linear} }}'
        (tmp_path / "w.wbt").write_text(world_text(scene, "gravity 0"), encoding="utf-8")
        model = convert_world(tmp_path / "w.wbt").compile()
        assert model.qpos0 == pytest.approx([0.4])
        assert model.key("webots_initial").qvel == pytest.approx([rate], abs=1e-12)
