"""Section 5 (motors and PositionSensor) of the Webots-on-ODE specification, one fact per test.

S = /work/shared/reference/webots-on-ode.md (line numbers as of this writing); the project's restatement is
docs/reference/webots-on-ode.md. Expected values come from the specification or from hand computation (each test
says which). Facts pinned elsewhere (initial hold, PID first step and derivative kick, acceleration ramp, velocity
reached, torque-limited velocity, torque sign, NaN before the first sample, resolution, seeded noise, kinematic
motors, coupled motors) are not repeated.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, DT, INERTIA, TS, G, load_arm


def _hinge(motor: str = 'RotationalMotor { name "m" }', params: str = "axis 0 1 0", bob_at: str = "0.5 0 0",
           static_parent: bool = True) -> str:
    hinge = (
        f"HingeJoint {{ jointParameters HingeJointParameters {{ {params} }} "
        f'device [ {motor} PositionSensor {{ name "s" }} ] endPoint {BOB.format(t=bob_at)} }}'
    )
    if static_parent:
        return hinge
    return ('Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '
            f"children [ {hinge} ] }}")


def _slider(motor: str = 'LinearMotor { name "m" }', params: str = "axis 1 0 0", static_parent: bool = True) -> str:
    slider = (
        f"SliderJoint {{ jointParameters JointParameters {{ {params} }} "
        f'device [ {motor} PositionSensor {{ name "s" }} ] endPoint {BOB.format(t="0 0 0")} }}'
    )
    if static_parent:
        return slider
    return ('Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '
            f"children [ {slider} ] }}")


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _sensor(sup: Supervisor):  # type: ignore[no-untyped-def]
    s = sup.getDevice("s")
    s.enable(TS)
    return s


# ------------------------------------------------------------------------------------------ §5.1 defaults


def test_rotational_motor_defaults() -> None:
    # S l.411-419: maxVelocity 10, maxTorque 10, acceleration −1, controlPID 10 0 0, min/maxPosition 0,
    # multiplier 1, consumptionFactor 10
    _, sup = load_arm(_hinge("RotationalMotor { }"))
    m = sup.getDevice("rotational motor")
    assert (m.getMaxVelocity(), m.getMaxTorque(), m.getAcceleration()) == (10.0, 10.0, -1.0)
    assert (m.getMinPosition(), m.getMaxPosition(), m.getMultiplier()) == (0.0, 0.0, 1.0)
    node = sup.getSelf().getField("children").getMFNode(0).getField("device").getMFNode(0)
    assert node.getField("controlPID").getSFVec3f() == [10.0, 0.0, 0.0]
    assert node.getField("consumptionFactor").getSFFloat() == 10.0


def test_linear_motor_defaults() -> None:
    # S l.411-419: maxVelocity 10 m/s, maxForce 10 N, acceleration −1, controlPID 10 0 0, no soft limits
    _, sup = load_arm(_slider("LinearMotor { }"))
    m = sup.getDevice("linear motor")
    assert (m.getMaxVelocity(), m.getMaxForce(), m.getAcceleration()) == (10.0, 10.0, -1.0)
    assert (m.getMinPosition(), m.getMaxPosition(), m.getMultiplier()) == (0.0, 0.0, 1.0)
    node = sup.getSelf().getField("children").getMFNode(0).getField("device").getMFNode(0)
    assert node.getField("controlPID").getSFVec3f() == [10.0, 0.0, 0.0]
    assert node.getField("consumptionFactor").getSFFloat() == 10.0


def test_position_sensor_defaults() -> None:
    # S l.421: noise 0, resolution −1; §6 l.488: default name "position sensor"
    _, sup = load_arm("HingeJoint { device [ PositionSensor { } ] endPoint " + BOB.format(t="0.5 0 0") + " }")
    s = sup.getDevice("position sensor")
    assert s is not None
    node = sup.getSelf().getField("children").getMFNode(0).getField("device").getMFNode(0)
    assert node.getField("noise").getSFFloat() == 0.0
    assert node.getField("resolution").getSFFloat() == -1.0


def test_initial_targets_are_current_position_max_velocity_and_max_torque() -> None:
    # S l.423-425: target position = current joint position (its `position` field), target velocity = maxVelocity,
    # available torque = maxTorque
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxVelocity 3 maxTorque 7 }', params="axis 0 1 0 position 0.4",
                          bob_at=f"{0.5 * math.cos(0.4)} 0 {-0.5 * math.sin(0.4)}"))
    m = sup.getDevice("m")
    assert m.getTargetPosition() == pytest.approx(0.4)
    assert m.getVelocity() == 3.0
    assert m.getAvailableTorque() == 7.0


# ------------------------------------------------------------------------------------------ §5.2 API → targets


def test_set_position_is_multiplied_by_the_multiplier() -> None:
    # S l.430: target = p·multiplier: setPosition(0.25) with multiplier 2 servoes the joint to 0.5
    _, sup = load_arm(_hinge('RotationalMotor { name "m" multiplier 2 maxTorque 100 }'))
    s = _sensor(sup)
    sup.getDevice("m").setPosition(0.25)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.5, abs=1e-4)


def test_set_position_is_clamped_to_the_soft_limits() -> None:
    # S l.430-431: with minPosition ≠ maxPosition a finite target is clamped into [minPosition, maxPosition]
    _, sup = load_arm(_hinge('RotationalMotor { name "m" minPosition -0.5 maxPosition 0.5 maxTorque 100 }'))
    s = _sensor(sup)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sup.getDevice("m").setPosition(2.0)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.5, abs=1e-4)


def test_infinite_target_is_kept_despite_soft_limits() -> None:
    # S l.430: ±inf is kept (only a finite p is clamped): velocity control runs past maxPosition 0.5
    _, sup = load_arm(_hinge('RotationalMotor { name "m" minPosition -0.5 maxPosition 0.5 maxTorque 100 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 250)  # 1 s at 1 rad/s
    assert m.getTargetPosition() == math.inf
    assert s.getValue() == pytest.approx(1.0, rel=1e-3)


def test_set_position_leaves_torque_mode() -> None:
    # S l.431: setPosition leaves torque mode: after a torque push, setPosition(0) brings the joint back
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 100 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setTorque(5.0)
    _steps(sup, 50)
    assert s.getValue() > 0.1
    m.setPosition(0.0)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.0, abs=1e-4)


def test_set_velocity_is_clamped_to_max_velocity() -> None:
    # S l.432: target velocity = v·multiplier clamped to ±maxVelocity
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxVelocity 2 maxTorque 1000 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m.setVelocity(5.0)
    assert m.getVelocity() == 2.0
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(2.0, rel=1e-3)


def test_set_velocity_is_multiplied_by_the_multiplier() -> None:
    # S l.432: target velocity = v·multiplier: 1 rad/s with multiplier 2 turns at 2 rad/s
    _, sup = load_arm(_hinge('RotationalMotor { name "m" multiplier 2 maxTorque 1000 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(2.0, rel=1e-3)


def test_set_acceleration_replaces_the_field() -> None:
    # S l.433: setAcceleration replaces `acceleration` (−1 = unlimited)
    _, sup = load_arm(_hinge('RotationalMotor { name "m" acceleration 3 }'))
    m = sup.getDevice("m")
    assert m.getAcceleration() == 3.0
    m.setAcceleration(-1)
    assert m.getAcceleration() == -1.0


def test_available_torque_is_capped_at_max_torque() -> None:
    # S l.434: available = min(f, maxTorque)
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 7 }'))
    m = sup.getDevice("m")
    m.setAvailableTorque(20.0)
    assert m.getAvailableTorque() == 7.0
    m.setAvailableTorque(3.0)
    assert m.getAvailableTorque() == 3.0


def test_zero_available_torque_releases_the_joint() -> None:
    # S l.434-435 and l.448: available 0 ⇒ no control: a held arm falls under gravity (torque 4.9 N·m about +y)
    _, sup = load_arm(_hinge(), gravity=G)
    s = _sensor(sup)
    _steps(sup, 50)
    assert abs(s.getValue()) < 0.01  # initially servoed
    sup.getDevice("m").setAvailableTorque(0.0)
    _steps(sup, 100)
    assert s.getValue() > 0.2


@pytest.mark.parametrize("static_parent", [True, False])
def test_torque_is_clamped_to_the_available_torque(static_parent: bool) -> None:
    # S l.436-437: raw input = τ·multiplier clamped to ±available: 5 N·m asked with 1 available gives
    # ω = (1/I)·t (hand computation, I = 0.2510; base 1000 kg, its recoil neglected at 0.1 %)
    sim, sup = load_arm(_hinge(static_parent=static_parent))
    m = sup.getDevice("m")
    m.setAvailableTorque(1.0)
    m.setTorque(5.0)
    _steps(sup, 100)
    bob = next(b for b in sim.bodies if b.root.name == "bob")
    assert bob.avel[1] == pytest.approx(100 * DT / INERTIA, rel=2e-3)


def test_torque_is_multiplied_by_the_multiplier() -> None:
    # S l.437: raw input = τ·multiplier: 0.5 N·m with multiplier 2 is 1 N·m
    sim, sup = load_arm(_hinge('RotationalMotor { name "m" multiplier 2 }'))
    sup.getDevice("m").setTorque(0.5)
    _steps(sup, 100)
    assert sim.bodies[0].avel[1] == pytest.approx(100 * DT / INERTIA, rel=1e-3)  # joint rows' CFM


def test_set_control_pid_resets_integral_and_previous_error() -> None:
    # S l.438: setControlPID replaces the gains and resets the integral and the previous error
    sim, sup = load_arm(_hinge('RotationalMotor { name "m" controlPID 10 5 0 }'))
    m = sup.getDevice("m")
    m.setPosition(0.3)
    _steps(sup, 5)
    rec = sim.motors[0]
    assert rec.integral != 0.0 and rec.prev_error != 0.0
    m.setControlPID(4, 1, 0)
    assert (rec.kp, rec.ki, rec.kd) == (4.0, 1.0, 0.0)
    assert rec.integral == 0.0 and rec.prev_error == 0.0


# ------------------------------------------------------------------------------------------ §5.3 per-step law


def test_position_control_is_the_p_law_step_by_step() -> None:
    # S l.451-454: unloaded (gravity 0, enough torque), u = Kp·e each step and the joint moves u·ts, so
    # e_n = e_0·(1 − Kp·ts)^n (hand computation), here 0.1·0.96^n
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 1e5 }'))
    s = _sensor(sup)
    sup.getDevice("m").setPosition(0.1)
    for n in range(1, 11):
        _steps(sup, 1)
        assert 0.1 - s.getValue() == pytest.approx(0.1 * 0.96**n, rel=1e-3)


def test_position_control_output_is_clamped_to_the_target_velocity() -> None:
    # S l.454: |out| ≥ |Vt| ⇒ u = sign(out)·|Vt|: a far target (Kp·e = 100) moves at Vt = 1 rad/s
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 1000 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setVelocity(1.0)
    m.setPosition(-10.0)
    _steps(sup, 100)
    assert s.getValue() == pytest.approx(-100 * DT, rel=1e-3)


@pytest.mark.parametrize("static_parent", [True, False])
def test_slider_position_control_converges(static_parent: bool) -> None:
    # S l.458-459: slider dParamVel = +u (Webots sign): the P law drives it onto its target from either parent
    _, sup = load_arm(_slider('LinearMotor { name "m" maxForce 100 }', static_parent=static_parent))
    s = _sensor(sup)
    sup.getDevice("m").setPosition(0.05)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.05, abs=1e-4)


@pytest.mark.parametrize("static_parent", [True, False])
def test_slider_velocity_control_sign(static_parent: bool) -> None:
    # S l.458-459 and l.448: velocity control u = Vt, positive along +axis
    _, sup = load_arm(_slider('LinearMotor { name "m" maxForce 1000 }', static_parent=static_parent))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(0.2)
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(0.2, rel=1e-2)


# ------------------------------------------------------------------------------------------ §5.4 PositionSensor


def test_position_sensor_reads_after_the_physics_step() -> None:
    # S l.471-472 and §6 l.483: a command issued before step k acts in step k and the sample taken at the end of
    # step k sees it: one step of 1 rad/s velocity control reads 1·ts (to the motor row's CFM lag)
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 1e5 }'))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(DT, rel=1e-3)


def test_position_sensor_includes_the_initial_offset_over_turns() -> None:
    # S l.466-467: continuous, multi-turn, includes the initial `position` offset: 1 + 8 rad/s · 2 s = 17 rad
    _, sup = load_arm(_hinge('RotationalMotor { name "m" maxTorque 1000 }', params="axis 0 1 0 position 1",
                          bob_at=f"{0.5 * math.cos(1)} 0 {-0.5 * math.sin(1)}"))
    s = _sensor(sup)
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(8.0)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(17.0, rel=1e-3)
