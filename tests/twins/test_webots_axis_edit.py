"""The Webots twin reads a joint about its current axis: a supervisor's run-time edit of a joint parameters'
``axis`` turns the joint about the new axis from the next step (reference webots-on-ode.md §4.1: axis and anchor in
the closest upper Pose's frame, ODE's zero and the offsets set again so the position reads on without a jump), and
the twin's state reader follows it (before, it read each axis once, when the joint was resolved).

Hand values: in zero gravity a motor at velocity 1 rad/s with maxTorque 100 brings its 1 kg endPoint to 1 rad/s
within a step, on a 1e6 kg body parent that barely moves (its reaction turns it by ~1e-6 rad/s). After the edit the
endPoint turns about the new axis, which is orthogonal to the old one: the rate read about the new axis is 1, about
the old one 0. The position read is the joint's ``position`` field, which the PositionSensor reads too (§5.4).
"""

from __future__ import annotations

import math

import pytest

from dualtwin.twins.webots import WebotsTwin
from tests.support.quiet_worlds import quiet_supervisor

TS = 4
PERIOD = 0.008
END = "boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }"
MOTOR = 'RotationalMotor {{ name "{m}" maxVelocity 10 maxTorque 100 }} PositionSensor {{ name "{s}" }}'
RATE_TOL = 1e-3  # the heavy parent's reaction and ODE's constraint error, far below the 1 rad/s read


def _twin(joint: str) -> WebotsTwin:
    sup = quiet_supervisor(
        f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 physicsDisableTime 0 }}\n"
        'Robot { supervisor TRUE controller "<extern>" boundingObject Box { size 0.1 0.1 0.1 } '
        f"physics Physics {{ density -1 mass 1e6 }} children [ {joint} ] }}\n")
    return WebotsTwin(sup, PERIOD)


def _steps(twin: WebotsTwin, n: int) -> None:
    for _ in range(n):
        twin.step()


def test_a_hinge_is_read_about_its_edited_axis() -> None:
    twin = _twin("DEF J HingeJoint { jointParameters DEF P HingeJointParameters { axis 0 0 1 } "
                 f"device [ {MOTOR.format(m='m', s='s')} ] "
                 "endPoint Solid { translation 0.2 0 0 " + END + " } }")
    twin.command("m", "velocity", 1.0)
    _steps(twin, 10)
    assert twin.joint_velocity("J") == pytest.approx(1.0, abs=RATE_TOL)  # the control, about z
    assert twin.get_state().joint_velocities["J"] == pytest.approx(1.0, abs=RATE_TOL)
    twin.sup.getFromDef("P").getField("axis").setSFVec3f([0.0, 2.0, 0.0])  # not unit: the reader normalises
    _steps(twin, 10)
    state = twin.get_state()
    assert twin.joint_velocity("J") == pytest.approx(1.0, abs=RATE_TOL)
    assert state.joint_velocities["J"] == pytest.approx(1.0, abs=RATE_TOL)
    # The reading goes on from the position before the edit (0.16 rad after 20 steps of 8 ms at 1 rad/s, the
    # first period's acceleration aside): the sensor's value, the same field.
    assert state.joint_positions["J"] == pytest.approx(twin.sensor("s"), abs=1e-12)
    assert state.joint_positions["J"] == pytest.approx(0.16, abs=0.01)


def test_a_zero_axis_edit_is_refused_and_the_joint_is_read_about_its_axis() -> None:
    # Webots refuses a zero axis ("'axis' must be non zero", a warning) and the joint keeps its axis.
    twin = _twin("DEF J HingeJoint { jointParameters DEF P HingeJointParameters { axis 0 0 1 } "
                 f"device [ {MOTOR.format(m='m', s='s')} ] "
                 "endPoint Solid { translation 0.2 0 0 " + END + " } }")
    twin.command("m", "velocity", 1.0)
    _steps(twin, 5)
    assert twin.get_state().joint_velocities["J"] == pytest.approx(1.0, abs=RATE_TOL)  # the control
    with pytest.warns(UserWarning, match="must be non zero"):
        twin.sup.getFromDef("P").getField("axis").setSFVec3f([0.0, 0.0, 0.0])
        _steps(twin, 5)
    assert twin.get_state().joint_velocities["J"] == pytest.approx(1.0, abs=RATE_TOL)


def test_a_hinge2_second_axis_is_read_about_its_edited_axis() -> None:
    # The second axis at zero first-axis angle is the edited field's (§4.4: axis 2 is carried by axis 1, which
    # stays at 0 here: its motor holds it). Axis 2 from y to x: the endPoint turns at 1 rad/s about x.
    twin = _twin("DEF H Hinge2Joint { jointParameters HingeJointParameters { axis 0 0 1 } "
                 "jointParameters2 DEF P2 JointParameters { axis 0 1 0 } "
                 f"device [ {MOTOR.format(m='m1', s='s1')} ] device2 [ {MOTOR.format(m='m2', s='s2')} ] "
                 "endPoint Solid { translation 0 0 -0.2 " + END + " } }")
    twin.command("m1", "position", 0.0)
    twin.command("m2", "velocity", 1.0)
    _steps(twin, 10)
    assert twin.get_state().joint_velocities["H2"] == pytest.approx(1.0, abs=RATE_TOL)  # the control
    twin.sup.getFromDef("P2").getField("axis").setSFVec3f([1.0, 0.0, 0.0])
    _steps(twin, 10)
    state = twin.get_state()
    assert state.joint_velocities["H2"] == pytest.approx(1.0, abs=RATE_TOL)
    assert state.joint_velocities["H"] == pytest.approx(0.0, abs=RATE_TOL)
    assert state.joint_positions["H2"] == pytest.approx(twin.sensor("s2"), abs=1e-12)
    assert math.isfinite(state.joint_positions["H"])
