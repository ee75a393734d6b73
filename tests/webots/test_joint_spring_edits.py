"""A supervisor's edit of a joint's ``springConstant`` or ``dampingConstant`` reaches ODE from the next step on
every joint type and axis (Webots: the joint's spring and damper applied again; S §4.5: CFM = 1/(hK + B),
ERP = hK/(hK + B), an implicit spring and damper whose rest is the joint's position 0).

S = /work/shared/reference/webots-on-ode.md. Expected values by hand: at rest an ERP/CFM row's force is
ERP·err/(h·CFM) = K·err, so a spring balances gravity where K·x = m·g (slider) or K·θ = m·g·r·cos θ (an arm
horizontal at θ = 0); a damper alone (K = 0: ERP 0, CFM 1/B) is an implicit damper, ω ← ω/(1 + h·B/I) per step.
Each test runs the same joint before the edit (the control)."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.hinge_arm import BOB, TS, G, load_arm

H = TS / 1000


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _params(sup: Supervisor) -> object:
    return sup.getSelf().getField("children").getMFNode(0).getField("jointParameters").getSFNode()


def test_hinge_spring_edited_at_run_time_holds_the_arm_where_it_balances_gravity() -> None:
    hinge = (f"HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }} device [ PositionSensor "
             f"{{ name \"s\" }} ] endPoint {BOB.format(t='0.5 0 0')} }}")
    _, sup = load_arm(hinge, gravity=G)
    s = sup.getDevice("s")
    s.enable(TS)
    _steps(sup, 50)
    assert s.getValue() > 0.3  # control: falling
    params = _params(sup)
    params.getField("springConstant").setSFFloat(50.0)  # type: ignore[attr-defined]
    params.getField("dampingConstant").setSFFloat(5.0)  # type: ignore[attr-defined]
    _steps(sup, 2500)
    theta = 0.0
    for _ in range(50):  # K·θ = m·g·r·cos θ, by fixed-point iteration
        theta = 1.0 * G * 0.5 * math.cos(theta) / 50.0
    assert s.getValue() == pytest.approx(theta, abs=1e-4)


def test_slider_spring_edited_at_run_time_holds_the_bob_where_it_balances_gravity() -> None:
    slider = (f"SliderJoint {{ jointParameters JointParameters {{ axis 0 0 1 }} device [ PositionSensor "
              f"{{ name \"s\" }} ] endPoint {BOB.format(t='0 0 0')} }}")
    _, sup = load_arm(slider, gravity=G)
    s = sup.getDevice("s")
    s.enable(TS)
    _steps(sup, 50)
    assert s.getValue() < -0.01  # control: falling
    params = _params(sup)
    params.getField("springConstant").setSFFloat(100.0)  # type: ignore[attr-defined]
    params.getField("dampingConstant").setSFFloat(20.0)  # type: ignore[attr-defined]
    _steps(sup, 2500)
    assert s.getValue() == pytest.approx(-1.0 * G / 100.0, abs=1e-4)


BALL = """Robot { supervisor TRUE children [ BallJoint {
  jointParameters DEF P1 BallJointParameters { }
  jointParameters2 DEF P2 JointParameters { axis 1 0 0 }
  jointParameters3 DEF P3 JointParameters { axis 0 0 1 }
  endPoint DEF BALL Solid { angularVelocity SPIN boundingObject Sphere { radius 0.1 }
                            physics Physics { density -1 mass 2 } }
} ] }"""
HINGE2 = """Robot { supervisor TRUE children [ Solid { children [ Solid {
  physics Physics { density -1 mass 50 } boundingObject Box { size 0.1 0.1 0.1 }
  children [ Hinge2Joint {
    jointParameters DEF P1 HingeJointParameters { axis 1 0 0 }
    jointParameters2 DEF P2 JointParameters { axis 0 0 1 }
    endPoint DEF BALL Solid { angularVelocity SPIN boundingObject Sphere { radius 0.1 }
                              physics Physics { density -1 mass 2 } }
  } ] } ] } ] }"""
SPINS = {1: "1 0 0", 2: "0 1 0", 3: "0 0 1"}  # axis1 x, axis3 z, axis2 = axis3 × axis1 = y (S §4.4)


@pytest.mark.parametrize(("world", "axis"), [("ball", 1), ("ball", 2), ("ball", 3), ("hinge2", 1)])
def test_damping_edited_at_run_time_damps_the_axis(world: str, axis: int) -> None:
    # a 2 kg sphere (r 0.1, I = 0.4·2·0.1² = 0.008) spinning at 1 rad/s about the axis, centred on the anchor
    scene = (BALL if world == "ball" else HINGE2).replace("SPIN", SPINS[axis])
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 physicsDisableTime 0 }}\n{scene}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    ball = sup.getFromDef("BALL")
    _steps(sup, 10)
    spin = ball.getVelocity()[3:]
    assert math.hypot(*spin) == pytest.approx(1.0, rel=1e-6)  # control: no damping
    sup.getFromDef(f"P{axis}").getField("dampingConstant").setSFFloat(0.08)
    _steps(sup, 1)  # the edit acts from this step
    w0 = math.hypot(*ball.getVelocity()[3:])
    _steps(sup, 10)
    assert math.hypot(*ball.getVelocity()[3:]) / w0 == pytest.approx((1 + H * 0.08 / 0.008) ** -10, rel=1e-3)
