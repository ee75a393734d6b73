"""A supervisor's edit of a Hinge2Joint's or a BallJoint's ``position`` (any axis) teleports the endPoint, as
Webots does for a hinge.

S = /work/shared/reference/webots-on-ode.md. S §4.1: the endPoint is teleported to zero-pose ⊕ new position,
its subtree's physics reset (velocities and the motors' current velocity zeroed), the motor target not changed.
On the multi-axis joints the other axes keep their positions and the rotations compose as a chain of hinges
(S §4.4: Hinge2's second axis is turned by the first axis' position; a BallJoint's axes likewise, the second
being axis3 × axis1): the endPoint's rotation is R(axis1, p1)·R(axis2, p2)(·R(axis3, p3)) about the anchor. In
these worlds the endPoint's load rotation is the identity at positions 0, so its orientation is that product
and its origin the product applied to its offset from the anchor (hand computation). Zero gravity: nothing
moves the teleported endPoint in the step after the edit but its velocity, which the teleport zeroed."""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import _math3 as m3
from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 4
HEAVY_ROBOT = "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1e6 }"

HINGE2 = """Robot { supervisor TRUE children [ Solid { children [ Solid {
  physics Physics { density -1 mass 50 } boundingObject Box { size 0.1 0.1 0.1 }
  children [ Hinge2Joint {
    jointParameters DEF P1 HingeJointParameters { axis 1 0 0 }
    jointParameters2 DEF P2 JointParameters { axis 0 0 1 }
    device [ PositionSensor { name "s1" } ] device2 [ PositionSensor { name "s2" } ]
    endPoint DEF END Solid { angularVelocity 0 0 10 boundingObject Sphere { radius 0.1 }
                             physics Physics { density -1 mass 1 } }
  } ] } ] } ] }"""

BALL = """Robot {{ supervisor TRUE {parent} children [ BallJoint {{
  jointParameters DEF P1 BallJointParameters {{ }}
  jointParameters2 DEF P2 JointParameters {{ axis 1 0 0 }}
  jointParameters3 DEF P3 JointParameters {{ axis 0 0 1 }}
  device [ {motor} PositionSensor {{ name "s1" }} ]
  device2 [ PositionSensor {{ name "s2" }} ]
  device3 [ PositionSensor {{ name "s3" }} ]
  endPoint DEF END Solid {{ translation 0.5 0 0 linearVelocity 0 0.5 0 angularVelocity 0 0 1
                           boundingObject Sphere {{ radius 0.1 }}
                           physics Physics {{ density -1 mass 2 }} }}
}} ] }}"""


def _world(scene: str) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 physicsDisableTime 0 }}\n{scene}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    for i in (1, 2, 3):
        sensor = sup.getDevice(f"s{i}")
        if sensor is not None:
            sensor.enable(TS)
    return sup


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _positions(sup: Supervisor, n: int) -> list[float]:
    return [sup.getDevice(f"s{i}").getValue() for i in range(1, n + 1)]


def _chain(*turns: tuple[m3.Vec3, float]) -> m3.Mat3:
    R = m3.IDENTITY
    for axis, angle in turns:
        R = m3.mat_mul(R, m3.rot_axis_angle((*axis, angle)))
    return R


def _set(sup: Supervisor, axis: int, position: float) -> None:
    sup.getFromDef(f"P{axis}").getField("position").setSFFloat(position)


# ------------------------------------------------------------------------------------------ Hinge2Joint


def test_hinge2_second_axis_position_edited_teleports_the_endpoint_after_the_first_axis() -> None:
    sup = _world(HINGE2)
    end = sup.getFromDef("END")
    _steps(sup, 1)
    assert end.getVelocity()[5] == pytest.approx(10.0, rel=1e-6)  # control: spinning about axis 2 (z)
    _set(sup, 2, 0.7)
    _steps(sup, 1)
    assert _positions(sup, 2) == pytest.approx([0.0, 0.7], abs=1e-9)
    assert end.getVelocity() == pytest.approx([0.0] * 6, abs=1e-9)  # S §4.1: its physics reset
    assert end.getOrientation() == pytest.approx(list(_chain(((0, 0, 1), 0.7))), abs=1e-9)
    # the first axis next: the second axis (turned by 0.7 about z in the endPoint) is turned with it, §4.4
    _set(sup, 1, 0.4)
    _steps(sup, 1)
    assert _positions(sup, 2) == pytest.approx([0.4, 0.7], abs=1e-9)
    assert end.getOrientation() == pytest.approx(list(_chain(((1, 0, 0), 0.4), ((0, 0, 1), 0.7))), abs=1e-9)


def test_hinge2_first_axis_position_edited_keeps_the_second_axis_where_it_is() -> None:
    # the wheel spins about its second axis for 0.1 s; teleporting the first axis turns the spun wheel, whose
    # second axis keeps the position it reached (zero-pose ⊕ (0.4, p2)), its spin stopped (S §4.1)
    sup = _world(HINGE2)
    _steps(sup, 25)
    p2 = _positions(sup, 2)[1]
    assert p2 == pytest.approx(1.0, abs=0.01)  # control: 10 rad/s for 0.1 s
    _set(sup, 1, 0.4)
    _steps(sup, 1)
    assert _positions(sup, 2) == pytest.approx([0.4, p2], abs=1e-9)
    end = sup.getFromDef("END")
    assert end.getOrientation() == pytest.approx(list(_chain(((1, 0, 0), 0.4), ((0, 0, 1), p2))), abs=1e-9)
    assert end.getVelocity() == pytest.approx([0.0] * 6, abs=1e-9)


# ------------------------------------------------------------------------------------------ BallJoint


@pytest.mark.parametrize("parent", ["static", "body"])
def test_ball_positions_edited_teleport_the_endpoint_through_the_three_axes(parent: str) -> None:
    sup = _world(BALL.format(parent=HEAVY_ROBOT if parent == "body" else "", motor=""))
    end = sup.getFromDef("END")
    _steps(sup, 1)
    assert end.getVelocity()[5] == pytest.approx(1.0, rel=1e-3)  # control: turning about the third axis (z)
    for axis, position in ((1, 0.3), (2, 0.2), (3, 0.5)):
        _set(sup, axis, position)
    _steps(sup, 1)
    assert _positions(sup, 3) == pytest.approx([0.3, 0.2, 0.5], abs=1e-9)
    # axis1 = x, axis3 = z, axis2 = axis3 × axis1 = y (S §4.4)
    R = _chain(((1, 0, 0), 0.3), ((0, 1, 0), 0.2), ((0, 0, 1), 0.5))
    assert end.getOrientation() == pytest.approx(list(R), abs=1e-9)
    assert end.getPosition() == pytest.approx(list(m3.mat_vec(R, (0.5, 0.0, 0.0))), abs=1e-9)  # anchor at 0
    assert end.getVelocity() == pytest.approx([0.0] * 6, abs=1e-9)


def test_ball_position_edited_keeps_the_motor_target() -> None:
    # S §4.1: the motor target is not changed: a position-controlled motor pulls the axis back to it (0)
    sup = _world(BALL.format(parent="", motor='RotationalMotor { name "m1" maxTorque 100 }'))
    sup.getDevice("m1").setPosition(0.0)
    _steps(sup, 1)
    _set(sup, 1, 0.5)
    _steps(sup, 1)
    assert _positions(sup, 1)[0] == pytest.approx(0.5, abs=0.05)  # teleported
    _steps(sup, 250)
    assert _positions(sup, 1)[0] == pytest.approx(0.0, abs=1e-3)  # pulled back to the unchanged target
    assert sup.getDevice("m1").getTargetPosition() == 0.0


def test_ball_first_axis_teleported_past_pi_reads_the_position_set() -> None:
    # positions are continuous (S §4.2's unwrapping, as on every rotational axis): a first axis set to 4 rad
    # reads 4, not ODE's Euler angle 4 − 2π
    sup = _world(BALL.format(parent="", motor=""))
    _set(sup, 1, 4.0)
    _steps(sup, 1)
    assert _positions(sup, 3) == pytest.approx([4.0, 0.0, 0.0], abs=1e-9)
    assert sup.getFromDef("END").getOrientation() == pytest.approx(list(_chain(((1, 0, 0), 4.0))), abs=1e-9)


def test_set_joint_position_teleports_a_hinge2s_second_axis_without_parameters() -> None:
    # Node.setJointPosition(position, 2) on a Hinge2Joint without jointParameters2 (the hidden position2 field is
    # its position): the same teleport as the parameters' position. Its axis is then z here, JointParameters'
    # default (S §4.4 leaves the value Webots uses unverified; physics/build.py _joint_axes)
    sup = _world(HINGE2.replace("    jointParameters2 DEF P2 JointParameters { axis 0 0 1 }\n", "").replace(
        "children [ Hinge2Joint {", "children [ DEF H2 Hinge2Joint {"))
    _steps(sup, 1)
    sup.getFromDef("H2").setJointPosition(0.7, 2)
    _steps(sup, 1)
    assert _positions(sup, 2) == pytest.approx([0.0, 0.7], abs=1e-9)
    assert sup.getFromDef("END").getOrientation() == pytest.approx(list(_chain(((0, 0, 1), 0.7))), abs=1e-9)


def test_slider_position_edited_teleports_the_endpoint_along_the_axis() -> None:
    # S §4.1 on a SliderJoint: zero-pose ⊕ position is a translation by position along the axis (here x, from
    # position 0.1 at load where the endPoint is at x = 0.1)
    sup = _world("""Robot { supervisor TRUE children [ SliderJoint {
      jointParameters DEF P1 JointParameters { axis 1 0 0 position 0.1 }
      device [ PositionSensor { name "s1" } ]
      endPoint DEF END Solid { translation 0.1 0 0 linearVelocity 1 0 0 boundingObject Sphere { radius 0.1 }
                               physics Physics { density -1 mass 1 } } } ] }""")
    _steps(sup, 1)
    _set(sup, 1, 0.4)
    _steps(sup, 1)
    assert _positions(sup, 1) == pytest.approx([0.4], abs=1e-9)
    assert sup.getFromDef("END").getPosition() == pytest.approx([0.4, 0.0, 0.0], abs=1e-9)
    assert sup.getFromDef("END").getVelocity() == pytest.approx([0.0] * 6, abs=1e-9)
