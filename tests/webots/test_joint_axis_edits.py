"""A supervisor's edit of a joint's ``axis`` or ``anchor`` acts on the joint from the next step, as in Webots, for
every joint type and axis that has the field.

S = /work/shared/reference/webots-on-ode.md. S §4.1: axis and anchor are in the closest upper Pose's frame, ODE's
zero is the configuration when the axis or anchor is set (creation or re-anchoring) and Webots keeps the offset
= the joint's position then (position = sign·ODE measure + offset), so the positions read on without a jump. The
endPoint is placed where the current position puts it about the new axis through the new anchor, from its zero
pose (the load pose undone by the load position, §4.1), as a ``position`` edit does. In these worlds the endPoint's
load rotation is the identity at position 0, so after an edit its orientation is R(new axis, position) and its
origin that rotation applied to its offset from the anchor (hand computations, each test says which). Positive
positions turn about +axis (right hand); a motor at velocity v in zero gravity turns its endPoint at v about the
axis (maxTorque far above what the 1 kg endPoint needs in a step: ω reaches v in one step). Each test checks the
behaviour before the edit (the control)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import pytest

from dualtwin.webots import _math3 as m3
from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, G, load_arm
from tests.support.quiet_worlds import quiet_supervisor

TS = 4
DT = TS / 1000.0
HEAVY = "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1e6 }"
END = "boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }"
MOTOR = 'RotationalMotor { name "m" maxVelocity 10 maxTorque 100 } PositionSensor { name "s" }'


def _world(joint: str, parent: str = "") -> tuple[Supervisor, Any, Any]:
    """A supervisor robot (``parent``: its own body, or none: a static parent) holding ``joint``, in zero
    gravity; its motor "m" (turning at 1 unit/s) and its enabled position sensor "s"."""
    sup = quiet_supervisor(
        f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 physicsDisableTime 0 }}\n"
        f"Robot {{ supervisor TRUE {parent} children [ {joint} ] }}\n")
    motor, sensor = sup.getDevice("m"), sup.getDevice("s")
    sensor.enable(TS)
    motor.setPosition(math.inf)
    motor.setVelocity(1.0)
    return sup, motor, sensor


def _hinge(params: str = "", end: str = END) -> str:
    return (f"HingeJoint {{ jointParameters DEF P HingeJointParameters {{ axis 0 0 1 {params} }} "
            f"device [ {MOTOR} ] endPoint DEF END Solid {{ translation 0.2 0 0 {end} }} }}")


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _spin(sup: Supervisor) -> list[float]:
    return sup.getFromDef("END").getVelocity()[3:]


def _orientation(sup: Supervisor) -> list[float]:
    return sup.getFromDef("END").getOrientation()


def _turn(axis: m3.Vec3, angle: float) -> list[float]:
    return list(m3.rot_axis_angle((*axis, angle)))


def _set_axis(sup: Supervisor, axis: list[float], params: str = "P") -> None:
    sup.getFromDef(params).getField("axis").setSFVec3f(axis)


# ------------------------------------------------------------------------------------------ HingeJoint


@pytest.mark.parametrize("parent", ["", HEAVY], ids=["static parent", "body parent"])
def test_a_driven_hinge_turns_about_its_edited_axis_and_reads_on(parent: str) -> None:
    sup, _, s = _world(_hinge(), parent)
    _steps(sup, 50)
    assert _spin(sup) == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)  # control: about the load axis z
    before = s.getValue()
    assert before == pytest.approx(50 * DT, abs=1e-3)
    _set_axis(sup, [1.0, 0.0, 0.0])
    _steps(sup, 1)
    # the motor (1 rad/s) now turns the endPoint about x; its position read on without a jump: one step more
    assert _spin(sup) == pytest.approx([1.0, 0.0, 0.0], abs=1e-3)
    after = s.getValue()
    assert after == pytest.approx(before + DT, abs=1e-4)
    # the zero pose (identity at (0.2, 0, 0)) turned by the position about x through the anchor (the origin):
    # the endPoint's origin lies on the new axis, at (0.2, 0, 0)
    assert _orientation(sup) == pytest.approx(_turn((1.0, 0.0, 0.0), after), abs=1e-3)
    assert sup.getFromDef("END").getPosition() == pytest.approx([0.2, 0.0, 0.0], abs=1e-4)


@pytest.mark.parametrize("stop", [0.3, 3.0])
def test_hinge_stops_hold_at_their_positions_about_the_edited_axis(stop: float) -> None:
    # S §4.2: the stops are Webots positions (−maxStop + offset in ODE, the offset the position when the axis is
    # set): the motor pushing past maxStop keeps the arm on it before and after the edit; 3 rad lies beyond
    # the ±π/2 where ODE's zero is moved along a hinge with stops
    sup, m, s = _world(_hinge(f"minStop {-stop} maxStop {stop}"))
    m.setVelocity(5.0)
    _steps(sup, 300)
    assert s.getValue() == pytest.approx(stop, abs=2e-3)  # control
    _set_axis(sup, [1.0, 0.0, 0.0])
    _steps(sup, 300)
    assert s.getValue() == pytest.approx(stop, abs=2e-3)
    assert _orientation(sup) == pytest.approx(_turn((1.0, 0.0, 0.0), stop), abs=3e-3)


def test_a_kinematic_hinge_turns_its_endpoint_about_the_edited_axis() -> None:
    # S §4.1: no Physics on the endPoint: the motor moves it directly, now about x
    sup, _, s = _world(_hinge(end=""))
    _steps(sup, 50)
    before = s.getValue()
    assert _orientation(sup) == pytest.approx(_turn((0.0, 0.0, 1.0), before), abs=1e-6)  # control
    _set_axis(sup, [1.0, 0.0, 0.0])
    _steps(sup, 10)
    assert s.getValue() == pytest.approx(before + 10 * DT, abs=1e-6)
    assert _orientation(sup) == pytest.approx(_turn((1.0, 0.0, 0.0), s.getValue()), abs=1e-6)


def test_a_zero_axis_written_at_run_time_is_refused_with_one_warning() -> None:
    # Webots: "'axis' must be non zero"; the joint keeps its axis
    sup, _, _ = _world(_hinge())
    _steps(sup, 5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _set_axis(sup, [0.0, 0.0, 0.0])
    lines = [str(w.message) for w in caught]
    assert len(lines) == 1 and "'axis' must be non zero" in lines[0]
    _steps(sup, 5)
    assert _spin(sup) == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)


def test_a_reset_gives_the_hinge_its_load_axis_again() -> None:
    sup, m, s = _world(_hinge())
    _set_axis(sup, [1.0, 0.0, 0.0])
    _steps(sup, 10)
    assert _spin(sup) == pytest.approx([1.0, 0.0, 0.0], abs=1e-3)
    sup.simulationReset()
    _steps(sup, 1)
    assert sup.getFromDef("P").getField("axis").getSFVec3f() == [0.0, 0.0, 1.0]
    m.setPosition(math.inf)
    m.setVelocity(1.0)
    _steps(sup, 10)
    assert _spin(sup) == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)
    assert _orientation(sup) == pytest.approx(_turn((0.0, 0.0, 1.0), s.getValue()), abs=1e-3)


def test_a_hinge_spring_pulls_back_about_the_edited_axis() -> None:
    # S §4.5: the spring's rest is the joint's zero position, its row about the joint's axis. The motor holds the
    # arm at 0.5 rad about z; after the edit it is at 0.5 about x; let go, the spring (K 4, B 0.8, I ≈ 0.041:
    # about critically damped, settled well within 2 s) brings it back to 0 about x
    sup, m, s = _world(_hinge("springConstant 4 dampingConstant 0.8"))
    m.setPosition(0.5)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.5, abs=1e-3)  # control
    _set_axis(sup, [1.0, 0.0, 0.0])
    _steps(sup, 1)
    assert _orientation(sup) == pytest.approx(_turn((1.0, 0.0, 0.0), 0.5), abs=1e-3)
    m.setAvailableTorque(0.0)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.0, abs=1e-3)
    assert _orientation(sup) == pytest.approx(list(m3.IDENTITY), abs=1e-3)


# ------------------------------------------------------------------------------------------ anchor


PENDULUM_JOINTS = {
    "hinge": "HingeJoint { jointParameters DEF P HingeJointParameters { axis 0 1 0 } ",
    "ball": "BallJoint { jointParameters DEF P BallJointParameters { } ",
}


def _pendulum(kind: str = "hinge") -> tuple[Supervisor, Any]:
    """A 1 kg bob 0.5 m along x from a hinge about y (or a BallJoint) at the robot's origin (1 m up), released
    horizontal."""
    joint = (PENDULUM_JOINTS[kind] + 'device [ PositionSensor { name "s" } ] endPoint DEF END '
             + BOB.format(t="0.5 0 0") + " }")
    _, sup = load_arm(joint, gravity=G)
    sensor = sup.getDevice("s")
    sensor.enable(TS)
    return sup, sensor


def _distances(sup: Supervisor, pivot: list[float], n: int) -> tuple[list[float], float]:
    """The bob's distances to ``pivot`` (world) over ``n`` steps, and the lowest height it reaches."""
    out, lowest = [], math.inf
    for _ in range(n):
        assert sup.step(TS) != -1
        p = sup.getFromDef("END").getPosition()
        out.append(m3.norm(m3.sub(tuple(p), tuple(pivot))))  # type: ignore[arg-type]
        lowest = min(lowest, p[2])
    return out, lowest


@pytest.mark.parametrize("kind", ["hinge", "ball"])
def test_an_anchor_edited_before_the_first_step_is_the_pivot_of_the_swing(kind: str) -> None:
    # the bob swings about (0.25, 0, 1), 0.25 m from it, and (energy kept, released level with the pivot) reaches
    # 1 − 0.25 m at the bottom; about the load anchor it would reach 0.5 m (hand computation)
    sup, _ = _pendulum(kind)
    sup.getFromDef("P").getField("anchor").setSFVec3f([0.25, 0.0, 0.0])
    distances, lowest = _distances(sup, [0.25, 0.0, 1.0], 200)
    assert max(abs(d - 0.25) for d in distances) < 1e-3
    assert lowest == pytest.approx(0.75, abs=2e-3)


def test_an_anchor_edited_mid_swing_places_the_bob_about_the_new_pivot() -> None:
    # the zero pose (bob at (0.5, 0, 0) in the robot) turned by the current position p about y through the new
    # anchor a = (0.25, 0, 0): bob = a + R(y, p)·(0.25, 0, 0); it then swings 0.25 m from the new pivot
    sup, s = _pendulum()
    distances, _ = _distances(sup, [0.0, 0.0, 1.0], 50)
    assert max(abs(d - 0.5) for d in distances) < 1e-3  # control: about the load anchor
    sup.getFromDef("P").getField("anchor").setSFVec3f([0.25, 0.0, 0.0])
    _steps(sup, 1)
    p = s.getValue()
    assert p > 0.1  # it has swung down
    expected = m3.add((0.25, 0.0, 1.0), m3.mat_vec(m3.rot_axis_angle((0.0, 1.0, 0.0, p)), (0.25, 0.0, 0.0)))
    assert sup.getFromDef("END").getPosition() == pytest.approx(list(expected), abs=2e-3)
    distances, _ = _distances(sup, [0.25, 0.0, 1.0], 200)
    assert max(abs(d - 0.25) for d in distances) < 1e-3


# ------------------------------------------------------------------------------------------ SliderJoint


def test_a_driven_slider_moves_along_its_edited_axis() -> None:
    joint = ('SliderJoint { jointParameters DEF P JointParameters { axis 0 0 1 } device [ LinearMotor { name "m" '
             f'maxVelocity 1 maxForce 100 }} PositionSensor {{ name "s" }} ] endPoint DEF END Solid {{ {END} }} }}')
    sup, m, s = _world(joint)
    m.setVelocity(0.1)
    _steps(sup, 50)
    before = s.getValue()
    assert sup.getFromDef("END").getPosition() == pytest.approx([0.0, 0.0, before], abs=1e-4)  # control
    _set_axis(sup, [2.0, 0.0, 0.0])  # S §4.3: normalised
    _steps(sup, 1)
    after = s.getValue()
    assert after == pytest.approx(before + 0.1 * DT, abs=1e-5)
    # the zero pose (the origin) slid by the position along x
    assert sup.getFromDef("END").getPosition() == pytest.approx([after, 0.0, 0.0], abs=1e-4)
    assert sup.getFromDef("END").getVelocity()[:3] == pytest.approx([0.1, 0.0, 0.0], abs=1e-3)


# ------------------------------------------------------------------------------------------ Hinge2Joint, BallJoint


SECOND_AXES = {
    # S §4.4: a Hinge2's axis 2 is carried by axis 1 (at position 0 here): the wheel turns about y, then about x
    "hinge2 second axis": ('Hinge2Joint { jointParameters HingeJointParameters { axis 0 0 1 } '
                           'jointParameters2 DEF P2 JointParameters { axis 0 1 0 } '
                           f'device2 [ {MOTOR} ] endPoint DEF END Solid {{ {END} }} }}',
                           (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),
    # S §4.4: a BallJoint's first axis is its jointParameters2's (the third jointParameters3's, z): from x to y
    "ball first axis": ('BallJoint { jointParameters BallJointParameters { } '
                        'jointParameters2 DEF P2 JointParameters { axis 1 0 0 } '
                        'jointParameters3 JointParameters { axis 0 0 1 } '
                        f'device [ {MOTOR} ] endPoint DEF END Solid {{ translation 0.2 0 0 {END} }} }}',
                        (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
}


@pytest.mark.parametrize("case", sorted(SECOND_AXES))
def test_an_edit_of_a_jointparameters2_axis_turns_the_endpoint_about_the_new_axis(case: str) -> None:
    joint, before_axis, after_axis = SECOND_AXES[case]
    sup, _, s = _world(joint, HEAVY)
    _steps(sup, 50)
    assert _spin(sup) == pytest.approx(list(before_axis), abs=1e-3)  # control: 1 rad/s about the load axis
    before = s.getValue()
    _set_axis(sup, list(after_axis), "P2")
    _steps(sup, 1)
    assert _spin(sup) == pytest.approx(list(after_axis), abs=1e-3)
    assert s.getValue() == pytest.approx(before + DT, abs=1e-4)
    assert _orientation(sup) == pytest.approx(_turn(after_axis, s.getValue()), abs=1e-3)


def test_a_hinge2_first_axis_edit_moves_its_suspension_along_the_new_axis() -> None:
    # S §4.4: the Hinge2's suspension is ODE's own, along its first axis (ERP/CFM from K and B, S §4.2: a spring
    # of stiffness K); a steady force F on the endPoint's centre (the anchor) along that axis moves it F/K =
    # 10/1000 = 0.01 m; across the axis the joint holds it. After the first axis goes from z to x, the same
    # force along x gives the 0.01 m, along z nothing
    joint = ('Hinge2Joint { jointParameters DEF P HingeJointParameters { axis 0 0 1 '
             'suspensionSpringConstant 1000 suspensionDampingConstant 50 } '
             'jointParameters2 JointParameters { axis 0 1 0 } '
             f'device [ {MOTOR} ] endPoint DEF END Solid {{ {END} }} }}')
    sup, m, _ = _world(joint, HEAVY)
    m.setVelocity(0.0)

    def sag(force: list[float]) -> list[float]:
        end = sup.getFromDef("END")
        for _ in range(300):
            end.addForce(force, False)
            assert sup.step(TS) != -1
        return list(m3.sub(tuple(end.getPosition()), tuple(sup.getSelf().getPosition())))  # type: ignore[arg-type]

    assert sag([0.0, 0.0, 10.0]) == pytest.approx([0.0, 0.0, 0.01], abs=1e-3)  # control
    assert sag([10.0, 0.0, 0.0]) == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)  # control
    _set_axis(sup, [1.0, 0.0, 0.0])
    assert sag([10.0, 0.0, 0.0]) == pytest.approx([0.01, 0.0, 0.0], abs=1e-3)
    assert sag([0.0, 0.0, 10.0]) == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)
