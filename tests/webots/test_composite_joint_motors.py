"""Joints × motors × supervisor compositions (webots-on-ode.md §4–§6, webots-devices.md §11): a motor's acceleration
across a simulationReset and a supervisor's write of its field, a kinematic motor's speed across resetPhysics and a
joint position write, and a hinge's stops across a position write.

Worlds: the one-link arm of tests/support/hinge_arm.py (a 1 kg bob 0.5 m from a hinge about y, no gravity, 4 ms
steps; its inertia about the hinge is I = 0.25 + 0.4·0.05² ≈ 0.251 kg·m²), or a kinematic arm (no Physics)."""

from __future__ import annotations

from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, DT, INERTIA, TS, load_arm
from tests.support.quiet_worlds import quiet_supervisor


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _ramp(acceleration: float, velocity: float, n: int) -> float:
    """Hand computation of §5.3 step 2: the commanded velocity grows by acceleration·dt a step up to ``velocity``;
    each step the joint turns by that velocity times dt (the motor's maxTorque 1000 N·m is more than the
    I·(1 rad/s)/dt ≈ 63 N·m that reaching 1 rad/s within one step needs, so the motor row reaches it)."""
    total, u = 0.0, 0.0
    for _ in range(n):
        u = min(velocity, u + acceleration * DT)
        total += u * DT
    return total


def test_simulation_reset_restores_the_acceleration_a_controller_changed() -> None:
    # §5.2: setAcceleration replaces the motor's `acceleration` field; §6: simulationReset restores the fields to
    # their load state and webots-devices.md §11.3 lists the motors' "position, velocity, acceleration, available
    # force" among what it resets. So after a reset the motor ramps at the file's 2 rad/s² again: 25 steps of
    # velocity control at 1 rad/s turn the joint by Σ 0.008·k·0.004 (k = 1..25) = 0.0104 rad, not the 25·0.004 =
    # 0.1 rad of an unlimited motor.
    _, sup = load_arm(f'HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }} '
                      f'device [ RotationalMotor {{ name "m" acceleration 2 maxTorque 1000 }} PositionSensor {{ name "s" }} ] '
                      f'endPoint {BOB.format(t="0.5 0 0")} }}')
    m, s = sup.getDevice("m"), sup.getDevice("s")
    s.enable(TS)
    m.setAcceleration(-1)
    m.setPosition(float("inf"))
    m.setVelocity(1.0)
    _steps(sup, 5)
    assert s.getValue() == pytest.approx(_ramp(1e9, 1.0, 5), rel=1e-3)  # unlimited: 1 rad/s from the first step
    sup.simulationReset()
    _steps(sup, 1)
    assert m.getAcceleration() == 2.0
    m.setPosition(float("inf"))
    m.setVelocity(1.0)
    start = s.getValue()
    _steps(sup, 25)
    assert s.getValue() - start == pytest.approx(_ramp(2.0, 1.0, 25), rel=1e-3)


def _kinematic_arm() -> Supervisor:
    """A robot without Physics whose hinge (about z) carries an endPoint without Physics: a kinematic joint (§4.1),
    its motor moving the joint itself (§5.3), at 10 ms steps."""
    return quiet_supervisor("""#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 10 gravity 0 }
DEF ROBOT Robot { supervisor TRUE children [
  HingeJoint { jointParameters DEF PARAMS HingeJointParameters { axis 0 0 1 }
    device [ RotationalMotor { name "m" acceleration 1 } PositionSensor { name "s" } ]
    endPoint Solid { translation 0.5 0 0 } } ] }
""")


def _turning_kinematic_arm() -> tuple[Supervisor, Any]:
    """:func:`_kinematic_arm` after 101 steps of 10 ms in velocity control at 1 rad/s (its motor at full speed),
    and its position sensor."""
    sup = _kinematic_arm()
    m, s = sup.getDevice("m"), sup.getDevice("s")
    s.enable(10)
    m.setPosition(float("inf"))
    m.setVelocity(1.0)
    for _ in range(101):
        assert sup.step(10) != -1
    return sup, s


def test_reset_physics_of_a_kinematic_robot_restarts_its_motors_ramp() -> None:
    # §6: resetting a Solid's physics zeroes the joint motors' current velocity (WbSolid.resetSingleSolidPhysics,
    # run for each Solid of the subtree, webots-python-api.md: "the Solid and descendants"), a kinematic joint's
    # too: its motor then ramps up again from rest (§5.3: "acceleration limited by min(acceleration, available
    # torque)"). Hand computation, 10 ms steps, acceleration 1 rad/s², velocity control at 1 rad/s: after 100 steps
    # the motor turns at 1 rad/s; from rest, the next 10 steps turn the joint by Σ 0.01·k·0.01 (k = 1..10) =
    # 0.0055 rad, where a motor still at 1 rad/s turns it by 10·0.01 = 0.1 rad.
    sup, s = _turning_kinematic_arm()
    before = s.getValue()
    for _ in range(10):
        assert sup.step(10) != -1
    assert s.getValue() - before == pytest.approx(0.1, rel=1e-9)  # at full speed
    sup.getFromDef("ROBOT").resetPhysics()
    before = s.getValue()
    for _ in range(10):
        assert sup.step(10) != -1
    assert s.getValue() - before == pytest.approx(0.0055, rel=1e-9)


def test_a_position_edit_of_a_kinematic_joint_restarts_its_motors_ramp() -> None:
    # §4.1: a supervisor's write of a joint's `position` teleports its endPoint and resets its subtree's physics,
    # the motor's current velocity zeroed (WbJoint.resetPhysics), a kinematic joint's as a dynamic one's; in
    # velocity control the motor then carries the joint on from the new position, ramping up from rest (§5.3).
    # Hand computation as in the test above: 0.0055 rad in the 10 steps after the edit, not 0.1 rad.
    sup, s = _turning_kinematic_arm()
    sup.getFromDef("PARAMS").getField("position").setSFFloat(2.0)
    for _ in range(10):
        assert sup.step(10) != -1
    assert s.getValue() - 2.0 == pytest.approx(0.0055, rel=1e-9)


def test_a_supervisor_write_of_a_motors_acceleration_field_limits_its_ramp() -> None:
    # §5.2: the motor's `acceleration` field is its acceleration (setAcceleration replaces the field), so a
    # supervisor's write of the field acts as the call would. Unlimited at load, 2 rad/s² once written: 25 steps
    # of velocity control at 1 rad/s then turn the joint by 0.0104 rad (hand computation in _ramp), not 0.1 rad.
    _, sup = load_arm(f'HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }} '
                      f'device [ DEF MOTOR RotationalMotor {{ name "m" maxTorque 1000 }} PositionSensor {{ name "s" }} ] '
                      f'endPoint {BOB.format(t="0.5 0 0")} }}')
    m, s = sup.getDevice("m"), sup.getDevice("s")
    s.enable(TS)
    sup.getFromDef("MOTOR").getField("acceleration").setSFFloat(2.0)
    m.setPosition(float("inf"))
    m.setVelocity(1.0)
    _steps(sup, 25)
    assert s.getValue() == pytest.approx(_ramp(2.0, 1.0, 25), rel=1e-3)


def test_a_position_edit_across_a_hinges_range_keeps_its_stops() -> None:
    # §4.1 with §4.2: a hinge with stops [−2.5, 3] driven onto its low stop, then a supervisor writes its
    # `position` 2.0 (4.5 rad away, within the stops). Webots' stops are hard limits tested on an unwrapped angle
    # (§4.2, fork difference), so the joint stays between them: teleported to 2.0 at rest (§4.1: velocities and
    # the motor's current velocity zeroed), the motor (velocity control, −3 rad/s, 20 N·m) accelerates it at
    # 20/I ≈ 79.7 rad/s², so one step later it is at 2.0 − 79.7·0.004² ≈ 1.99873 rad (hand computation); driven
    # up at +3 rad/s it rests on the high stop at 3.
    _, sup = load_arm(f'HingeJoint {{ jointParameters DEF PARAMS HingeJointParameters {{ axis 0 1 0 minStop -2.5 '
                      f'maxStop 3 }} device [ RotationalMotor {{ name "m" maxTorque 20 }} PositionSensor {{ name "s" }} ] '
                      f'endPoint {BOB.format(t="0.5 0 0")} }}')
    m, s = sup.getDevice("m"), sup.getDevice("s")
    s.enable(TS)
    m.setPosition(float("inf"))
    m.setVelocity(-3.0)
    _steps(sup, 300)
    assert s.getValue() == pytest.approx(-2.5, abs=1e-3)
    sup.getFromDef("PARAMS").getField("position").setSFFloat(2.0)
    _steps(sup, 1)
    assert s.getValue() == pytest.approx(2.0 - 20.0 / INERTIA * DT * DT, abs=1e-5)
    m.setVelocity(3.0)
    _steps(sup, 300)
    assert s.getValue() == pytest.approx(3.0, abs=1e-3)
