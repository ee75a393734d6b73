"""Section 4 (joints) of the Webots-on-ODE specification, one fact per test.

S = /work/shared/reference/webots-on-ode.md (line numbers as of this writing); the project's restatement is
docs/reference/webots-on-ode.md. Expected values come from the specification or from hand computation (each test
says which), never from running this code. Facts already pinned elsewhere (reverse flag, file pose = pose at the
position, stops holding, spring period, slider spring equilibrium, Hinge2 position signs, kinematic Hinge2) are
not repeated here.
"""

from __future__ import annotations

import math

import pytest

from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.hinge_arm import BOB, DT, TS, G, load_arm


def _hinge(params: str = "axis 0 1 0", devices: str = "", bob_at: str = "0.5 0 0", extra: str = "") -> str:
    jp = f"jointParameters HingeJointParameters {{ {params} }}" if params is not None else ""
    return (
        f"HingeJoint {{ {jp} {extra} device [ {devices} PositionSensor {{ name \"s\" }} ] "
        f"endPoint {BOB.format(t=bob_at)} }}"
    )


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _sensor(sup: Supervisor) -> float:
    s = sup.getDevice("s")
    s.enable(TS)
    return s


def _bob_avel(sim: Simulation) -> tuple[float, float, float]:
    return tuple(sim.bodies[0].avel[i] for i in range(3))  # type: ignore[return-value]


# ------------------------------------------------------------------------------------------ §4.1 common structure


def test_joint_axis_is_expressed_in_the_closest_upper_pose() -> None:
    # S l.313: world axis = R_upper·axis; a Pose turned 90° about z maps the hinge axis x onto world y, and a
    # velocity-controlled motor turns the endPoint about +axis (right hand)
    body = (
        "Pose { rotation 0 0 1 1.5707963267948966 children [ "
        + _hinge("axis 1 0 0", 'RotationalMotor { name "m" maxTorque 1000 }', bob_at="0 0 0.5")
        + " ] }"
    )
    sim, sup = load_arm(body)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 5)
    assert _bob_avel(sim) == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)


def test_hinge_without_joint_parameters_turns_about_x() -> None:
    # S l.333: without jointParameters the hinge axis is 1 0 0
    sim, sup = load_arm(
        'HingeJoint { device [ RotationalMotor { name "m" maxTorque 1000 } ] endPoint ' + BOB.format(t="0 0 0.5") + " }"
    )
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 5)
    assert _bob_avel(sim) == pytest.approx((1.0, 0.0, 0.0), abs=1e-6)


def test_endpoint_without_physics_makes_a_kinematic_joint() -> None:
    # S l.315: the ODE joint is created only if the endPoint has Physics and a body
    sim, _ = load_arm('HingeJoint { endPoint Solid { translation 0.5 0 0 name "bob" } }')
    assert sim.joints[0].kinematic and not sim.joints[0].ptr


def test_hidden_position_field_is_the_offset_without_joint_parameters() -> None:
    # S l.321: the offset is the hidden `position` field when jointParameters is NULL
    sim, sup = load_arm(_hinge(None, bob_at="0 0 0.5", extra="position 0.4"))  # type: ignore[arg-type]
    s = _sensor(sup)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.4, abs=1e-9)


def test_position_field_is_the_initial_sensor_value() -> None:
    # S l.321/l.466: Webots position = ODE measure + offset, the offset being the `position` field at creation
    _, sup = load_arm(_hinge("axis 0 1 0 position 0.7"))
    s = _sensor(sup)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.7, abs=1e-9)


def test_setting_position_at_run_time_keeps_the_motor_target() -> None:
    # S l.327: changing `position` teleports the endPoint; the motor target is not changed once the controller
    # is configured, so a position-controlled motor pulls the joint back to its previous target (0 here)
    _, sup = load_arm(_hinge("axis 0 1 0", 'RotationalMotor { name "m" maxTorque 100 }'))
    s = _sensor(sup)
    sup.getDevice("m").setPosition(0.0)
    _steps(sup, 1)
    joint = sup.getSelf().getField("children").getMFNode(0)
    joint.getField("jointParameters").getSFNode().getField("position").setSFFloat(0.5)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.5, abs=0.05)  # teleported
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(0.0, abs=1e-3)  # pulled back to the unchanged target
    assert sup.getDevice("m").getTargetPosition() == 0.0


# ------------------------------------------------------------------------------------------ §4.2 HingeJoint


def test_hinge_axis_length_is_normalised_by_ode() -> None:
    # S l.337: Webots does not normalise the hinge axis, ODE does: axis 0 3 0 turns at the commanded rate
    sim, sup = load_arm(_hinge("axis 0 3 0", 'RotationalMotor { name "m" maxTorque 1000 }'))
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(2.0)
    s = _sensor(sup)
    _steps(sup, 10)
    assert _bob_avel(sim) == pytest.approx((0.0, 2.0, 0.0), abs=1e-6)
    assert s.getValue() == pytest.approx(2.0 * 10 * DT, rel=1e-3)  # the first step lags by the motor row's CFM


@pytest.mark.parametrize("static_parent", [True, False])
def test_hinge_position_is_continuous_over_several_turns(static_parent: bool) -> None:
    # S l.341-345: the measured angle is unwrapped to within ±π of the prediction: multi-turn positions
    hinge = _hinge("axis 0 1 0", 'RotationalMotor { name "m" maxTorque 1000 }', bob_at="0 0 0.5")
    body = hinge if static_parent else (
        'Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '
        f"children [ {hinge} ] }}"
    )
    _, sup = load_arm(body)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(8.0)
    s = _sensor(sup)
    _steps(sup, 500)  # 2 s at 8 rad/s: 16 rad, more than two turns
    assert s.getValue() == pytest.approx(16.0, rel=1e-3)


def test_equal_min_and_max_stops_set_no_stop() -> None:
    # S l.346: stops only when minStop ≠ maxStop; gravity (torque +m·g·0.5 about +y) swings the bob past 0.5
    _, sup = load_arm(_hinge("axis 0 1 0 minStop 0.5 maxStop 0.5"), gravity=G)
    s = _sensor(sup)
    _steps(sup, 150)
    assert s.getValue() > 0.8


@pytest.mark.parametrize("static_parent", [True, False])
def test_hinge_stops_are_webots_positions_with_an_offset(static_parent: bool) -> None:
    # S l.346: dParamLoStop = −maxStop + offset, HiStop = −minStop + offset, i.e. the stops are Webots positions
    # even when the joint starts at position 0.2; gravity pushes toward +: the joint rests on maxStop 0.3
    hinge = _hinge("axis 0 1 0 position 0.2 minStop -0.3 maxStop 0.3",
                   bob_at=f"{0.5 * math.cos(0.2)} 0 {-0.5 * math.sin(0.2)}")
    body = hinge if static_parent else (
        'Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '
        f"children [ {hinge} ] }}"
    )
    _, sup = load_arm(body, gravity=G)
    s = _sensor(sup)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=0.01)


def _driven_to_stop(max_stop: float) -> float:
    _, sup = load_arm(_hinge(f"axis 0 1 0 minStop -1 maxStop {max_stop}", 'RotationalMotor { name "m" maxTorque 1 }'))
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    s = _sensor(sup)
    _steps(sup, 1500)  # 6 s at 1 rad/s would reach 6 rad without the stop
    return float(s.getValue())


def test_hinge_stop_below_pi_holds_a_driven_joint() -> None:
    # S l.346: a motor (1 N·m) driving toward maxStop 3 rests on it: the stop is a hard limit
    assert _driven_to_stop(3.0) == pytest.approx(3.0, abs=0.02)


def test_hinge_stop_beyond_pi_is_clamped_to_pi() -> None:
    # S l.347: both stops are clamped into [−π, π]: a motor driving toward maxStop 4 stops at π. Webots' ODE fork
    # unwraps the angle across ±π when it tests the limit (S l.350, Appendix A.3); upstream ODE's hinge angle wraps
    # there, so ODE's zero follows the joint instead (physics/joints.py _rebase_hinge)
    assert _driven_to_stop(4.0) == pytest.approx(math.pi, abs=0.02)


# ------------------------------------------------------------------------------------------ §4.3 SliderJoint


def _slider(params: str | None, devices: str = "", bob_at: str = "0 0 0") -> str:
    jp = f"jointParameters JointParameters {{ {params} }}" if params is not None else ""
    return (
        f"SliderJoint {{ {jp} device [ {devices} PositionSensor {{ name \"s\" }} ] "
        f"endPoint {BOB.format(t=bob_at)} }}"
    )


def test_slider_without_joint_parameters_slides_along_z() -> None:
    # S l.359: JointParameters axis default 0 0 1
    sim, sup = load_arm(_slider(None, 'LinearMotor { name "m" maxForce 1000 }'))
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(0.1)
    _steps(sup, 5)
    assert tuple(sim.bodies[0].lvel[i] for i in range(3)) == pytest.approx((0.0, 0.0, 0.1), abs=1e-9)


def test_slider_axis_is_normalised() -> None:
    # S l.359: the slider axis is normalised by Webots: axis 0 0 5 moves 0.1 m/s, positions in metres
    sim, sup = load_arm(_slider("axis 0 0 5", 'LinearMotor { name "m" maxForce 1000 }'))
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(0.1)
    s = _sensor(sup)
    _steps(sup, 10)
    assert sim.bodies[0].lvel[2] == pytest.approx(0.1, abs=1e-9)
    assert s.getValue() == pytest.approx(0.1 * 10 * DT, rel=1e-3)  # the first step lags by the motor row's CFM


def test_slider_position_field_is_the_offset() -> None:
    # S l.361: position = dJointGetSliderPosition + offset
    _, sup = load_arm(_slider("axis 0 0 1 position 0.25", bob_at="0 0 0.25"))
    s = _sensor(sup)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.25, abs=1e-9)


def test_slider_stops_are_webots_positions_with_an_offset() -> None:
    # S l.362: LoStop = minStop − offset, HiStop = maxStop − offset: gravity pulls the slider (axis +z) down
    # onto minStop −0.2 even though it starts at position 0.1
    _, sup = load_arm(_slider("axis 0 0 1 position 0.1 minStop -0.2 maxStop 0.3", bob_at="0 0 0.1"), gravity=G)
    s = _sensor(sup)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(-0.2, abs=0.005)


def test_slider_force_pushes_along_the_axis() -> None:
    # S l.364: force control dJointAddSliderForce(+force): F = 1 N on 1 kg, x = ½·a·t² up to O(h)
    _, sup = load_arm(_slider("axis 1 0 0", 'LinearMotor { name "m" }'))
    m = sup.getDevice("m")
    s = _sensor(sup)
    m.setForce(1.0)
    _steps(sup, 250)  # 1 s
    # ODE's semi-implicit Euler: x_n = a·h²·n(n+1)/2 (hand computation)
    assert s.getValue() == pytest.approx(1.0 * DT * DT * 250 * 251 / 2, rel=1e-6)


# ------------------------------------------------------------------------------------------ §4.4 Hinge2, Ball


def test_hinge2_second_axis_default_is_z() -> None:
    # S l.370: jointParameters2 is a JointParameters whose axis default is 0 0 1
    body = (
        'Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '
        "children [ Hinge2Joint { jointParameters HingeJointParameters { axis 1 0 0 } "
        'jointParameters2 JointParameters { } device2 [ RotationalMotor { name "m2" maxTorque 1000 } ] '
        f"endPoint {BOB.format(t='0 0 0')} }} ] }}"
    )
    sim, sup = load_arm(body)
    m = sup.getDevice("m2")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 5)
    bob = next(b for b in sim.bodies if b.root.name == "bob")
    base = next(b for b in sim.bodies if b.root.name == "base")
    rel = tuple(bob.avel[i] - base.avel[i] for i in range(3))
    assert rel == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)


def test_ball_joint_first_axis_default_is_x() -> None:
    # S l.378: BallJoint axes default axis1 = 1 0 0, axis3 = 0 0 1: a motor on the first axis turns about x
    body = (
        "BallJoint { jointParameters BallJointParameters { } "
        'device [ RotationalMotor { name "m1" maxTorque 1000 } ] '
        f"endPoint {BOB.format(t='0 0 -0.5')} }}"
    )
    sim, sup = load_arm(body)
    m = sup.getDevice("m1")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 5)
    assert _bob_avel(sim) == pytest.approx((1.0, 0.0, 0.0), abs=1e-3)


def test_ball_joint_third_axis_default_is_z() -> None:
    # S l.378: axis3 = 0 0 1
    body = (
        "BallJoint { jointParameters BallJointParameters { } "
        'device3 [ RotationalMotor { name "m3" maxTorque 1000 } ] '
        f"endPoint {BOB.format(t='0 0 -0.5')} }}"
    )
    sim, sup = load_arm(body)
    m = sup.getDevice("m3")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 5)
    assert _bob_avel(sim) == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)


# ------------------------------------------------------------------------------------------ §4.5 springs, friction


def test_damper_alone_gives_terminal_velocity_torque_over_damping() -> None:
    # S l.387-388: K = 0, B = 2 ⇒ ERP 0, CFM 1/B: the row's force is −B·ω, so a 1 N·m torque ends at 0.5 rad/s
    sim, sup = load_arm(_hinge("axis 0 1 0 dampingConstant 2", 'RotationalMotor { name "m" }'))
    sup.getDevice("m").setTorque(1.0)
    _steps(sup, 1000)
    assert _bob_avel(sim)[1] == pytest.approx(0.5, rel=1e-4)


def test_hinge_spring_equilibrium_under_a_constant_torque() -> None:
    # S l.387-394: ERP/CFM from K: at rest the row's force is K·(rest − position); 1 N·m against K = 10 ⇒ 0.1
    _, sup = load_arm(_hinge("axis 0 1 0 springConstant 10 dampingConstant 2", 'RotationalMotor { name "m" }'))
    s = _sensor(sup)
    sup.getDevice("m").setTorque(1.0)
    _steps(sup, 1500)
    assert s.getValue() == pytest.approx(0.1, abs=1e-4)


def test_hinge_spring_rests_at_the_zero_position_not_the_initial_one() -> None:
    # S l.394: spring rest = the joint's zero position; the joint starts at position 0.3 and returns to 0
    _, sup = load_arm(_hinge("axis 0 1 0 position 0.3 springConstant 10 dampingConstant 3",
                          bob_at=f"{0.5 * math.cos(0.3)} 0 {-0.5 * math.sin(0.3)}"))
    s = _sensor(sup)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.3, abs=0.01)
    _steps(sup, 2000)
    assert s.getValue() == pytest.approx(0.0, abs=1e-3)


def test_slider_spring_rests_at_the_zero_position_not_the_initial_one() -> None:
    # S l.395: LoStop = HiStop = −offset: the slider returns to position 0 from its initial 0.2
    _, sup = load_arm(_slider("axis 1 0 0 position 0.2 springConstant 50 dampingConstant 10", bob_at="0.2 0 0"))
    s = _sensor(sup)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(0.2, abs=0.01)
    _steps(sup, 1000)
    assert s.getValue() == pytest.approx(0.0, abs=1e-3)


def test_static_friction_holds_when_available_torque_is_zero() -> None:
    # S l.397-399 and l.448: available torque 0 ⇒ u = 0 and FMax = max(staticFriction, 0) = 10 > m·g·0.5 = 4.9
    _, sup = load_arm(_hinge("axis 0 1 0 staticFriction 10", 'RotationalMotor { name "m" }'), gravity=G)
    s = _sensor(sup)
    sup.getDevice("m").setAvailableTorque(0.0)
    _steps(sup, 250)
    assert abs(s.getValue()) < 1e-3


def test_static_friction_is_the_motor_force_limit_when_larger() -> None:
    # S l.397: FMax = max(staticFriction, available torque): maxTorque 1 alone sags under 4.9 N·m, but with
    # staticFriction 10 the position servo holds
    for friction, held in ((0.0, False), (10.0, True)):
        _, sup = load_arm(_hinge(f"axis 0 1 0 staticFriction {friction}", 'RotationalMotor { name "m" maxTorque 1 }'),
                       gravity=G)
        s = _sensor(sup)
        _steps(sup, 250)
        assert (abs(s.getValue()) < 1e-3) is held


def test_static_friction_still_acts_in_torque_mode() -> None:
    # S l.400-401: in torque mode the motor row keeps Vel 0 / FMax staticFriction: a zero torque holds the arm
    for friction, held in ((0.0, False), (10.0, True)):
        _, sup = load_arm(_hinge(f"axis 0 1 0 staticFriction {friction}", 'RotationalMotor { name "m" }'), gravity=G)
        s = _sensor(sup)
        sup.getDevice("m").setTorque(0.0)
        _steps(sup, 250)
        assert (abs(s.getValue()) < 1e-3) is held


# ------------------------------------------------------------------------------------------ §4.2 stop ERP/CFM edits


def _resting_on_max_stop() -> tuple[Supervisor, object, object]:
    _, sup = load_arm(_hinge("axis 0 1 0 minStop -0.3 maxStop 0.3"), gravity=G)
    s = _sensor(sup)
    _steps(sup, 500)
    params = sup.getSelf().getField("children").getMFNode(0).getField("jointParameters").getSFNode()
    return sup, s, params


def _stop_sag(erp: float, cfm: float) -> float:
    """At rest on a stop row ODE's force is erp·err/(h·cfm) (the ERP/CFM spring of S l.387-388 with
    hK = erp/cfm); it balances gravity's m·g·r·cos(0.3 + err) (hand computation, one fixed-point pass)."""
    err = 0.0
    for _ in range(5):
        err = G * 0.5 * math.cos(0.3 + err) * DT * cfm / erp
    return err


def test_stop_cfm_edited_at_run_time_reaches_ode() -> None:
    # S l.349-351: stopCFM (−1 ⇒ WorldInfo CFM) is passed via dParamStopCFM when the field changes at run time:
    # a stop CFM of 0.1 (stop ERP still the world's 0.2) lets the arm sink into its stop
    sup, s, params = _resting_on_max_stop()
    assert s.getValue() == pytest.approx(0.3, abs=1e-4)
    params.getField("stopCFM").setSFFloat(0.1)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3 + _stop_sag(0.2, 0.1), abs=1e-5)


def test_stop_erp_edited_at_run_time_reaches_ode() -> None:
    # S l.349-351: stopERP is passed via dParamStopERP when the field changes at run time; −1 means the world's
    sup, s, params = _resting_on_max_stop()
    params.getField("stopCFM").setSFFloat(0.1)
    params.getField("stopERP").setSFFloat(0.8)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3 + _stop_sag(0.8, 0.1), abs=1e-5)
    params.getField("stopERP").setSFFloat(-1.0)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3 + _stop_sag(0.2, 0.1), abs=1e-5)
