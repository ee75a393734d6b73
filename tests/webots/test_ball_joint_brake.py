"""BallJoint motors and sensors on its three axes, the Brake device, and motor torque feedback, on small worlds of
our own; expected values derived by hand (rotation chains, damper rows, statics), each with a control."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import _math3 as m3
from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation


def _sup(body: str, info: str = "gravity 0") -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep 8 {info} }}\n{body}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _ball_robot(physics: str) -> str:
    devices = ""
    for i, suffix in enumerate(("", " 2", " 3")):
        brake = f'Brake {{ name "brake{suffix}" }}' if i < 2 else ""
        devices += f"""device{'' if i == 0 else i + 1} [ {brake} PositionSensor {{ name "sensor{suffix}" }}
            RotationalMotor {{ name "motor{suffix}" maxVelocity 2 maxTorque 50 }} ]\n"""
    return f"""Robot {{ supervisor TRUE physics Physics {{ density -1 mass 1000 }} boundingObject Box {{ size 0.1 0.1 0.1 }}
  children [ BallJoint {{
    jointParameters BallJointParameters {{ anchor 0 0 0.2 }}
    jointParameters2 JointParameters {{ axis 1 0 1 }}
    jointParameters3 JointParameters {{ axis 0 1 0 }}
    {devices}
    endPoint DEF END Solid {{ translation 0 0 0.4 {physics} }} }} ] }}"""


DYNAMIC = "boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }"
TARGETS = (0.5, -0.4, 1.2)


def _expected_rotation() -> m3.Mat3:
    # a chain of three hinges: axis1 = (1 0 1), axis3 = (0 1 0), axis2 = axis3 × axis1 = (1 0 -1)
    a1, a3 = m3.normalized((1.0, 0.0, 1.0)), (0.0, 1.0, 0.0)
    a2 = m3.cross(a3, a1)
    R = m3.IDENTITY
    for axis, p in zip((a1, a2, a3), TARGETS, strict=True):
        R = m3.mat_mul(R, m3.rot_axis_angle((*axis, p)))
    return R


def _drive(sup: Supervisor, steps: int = 400) -> list[float]:
    sensors = [sup.getDevice(n) for n in ("sensor", "sensor 2", "sensor 3")]
    for s in sensors:
        s.enable(8)
    for name, target in zip(("motor", "motor 2", "motor 3"), TARGETS, strict=True):
        sup.getDevice(name).setPosition(target)
    for _ in range(steps):
        sup.step(8)
    return [s.getValue() for s in sensors]


@pytest.mark.parametrize("physics", [DYNAMIC, ""], ids=["dynamic", "kinematic"])
def test_ball_joint_motors_turn_the_endpoint_about_its_three_axes(physics: str) -> None:
    sup = _sup(_ball_robot(physics))
    positions = _drive(sup)
    assert positions == pytest.approx(list(TARGETS), abs=2e-3)
    end = sup.getFromDef("END")
    robot = sup.getSelf()
    R_robot = robot.getOrientation()
    rel = m3.mat_mul(m3.mat_t(R_robot), end.getOrientation())
    assert rel == pytest.approx(_expected_rotation(), abs=5e-3)
    # the endPoint turned about the anchor (0 0 0.2): its origin, 0.2 above the anchor, moved with it
    expected_origin = m3.add((0.0, 0.0, 0.2), m3.mat_vec(_expected_rotation(), (0.0, 0.0, 0.2)))
    origin = m3.mat_t_vec(R_robot, m3.sub(end.getPosition(), robot.getPosition()))
    assert origin == pytest.approx(expected_origin, abs=5e-3)


def test_ball_joint_holds_its_initial_pose_without_commands() -> None:
    sup = _sup(_ball_robot(DYNAMIC))  # control: motors hold the initial positions (§5.1)
    sensors = [sup.getDevice(n) for n in ("sensor", "sensor 2", "sensor 3")]
    for s in sensors:
        s.enable(8)
    for _ in range(50):
        sup.step(8)
    assert [s.getValue() for s in sensors] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)


def test_ball_joint_device_lists_link_their_siblings() -> None:
    sup = _sup(_ball_robot(DYNAMIC))
    for suffix in ("", " 2", " 3"):
        sensor = sup.getDevice(f"sensor{suffix}")
        assert sensor.getMotor().getName() == f"motor{suffix}"
        assert sup.getDevice(f"motor{suffix}").getPositionSensor().getName() == f"sensor{suffix}"
    assert sup.getDevice("sensor 2").getBrake().getName() == "brake 2"
    assert sup.getDevice("motor").getBrake().getName() == "brake"
    assert sup.getDevice("sensor 3").getBrake() is None  # device3 has no Brake
    assert sup.getDevice("brake 2").getMotor().getName() == "motor 2"


WHEEL = """Robot { supervisor TRUE children [ HingeJoint {
  jointParameters HingeJointParameters { axis 0 0 1 }
  device [ Brake { name "brake" } ]
  endPoint DEF WHEEL Solid { angularVelocity 0 0 10 boundingObject Sphere { radius 0.1 }
                             physics Physics { density -1 mass 1 } } } ] }"""


def test_brake_damping_acts_on_the_joint_from_the_next_step() -> None:
    sup = _sup(WHEEL)
    wheel = sup.getFromDef("WHEEL")
    for _ in range(5):
        sup.step(8)
    assert wheel.getVelocity()[5] == pytest.approx(10.0, rel=1e-9)  # control: a brake at 0 does nothing
    brake = sup.getDevice("brake")
    assert brake.getType() == brake.ROTATIONAL
    brake.setDampingConstant(0.04)
    sup.step(8)
    w0 = wheel.getVelocity()[5]
    assert w0 == pytest.approx(10.0 / 1.08, rel=1e-3)  # implicit damper: ω / (1 + h·B/I), I = 0.004 kg·m²
    for _ in range(10):
        sup.step(8)
    assert wheel.getVelocity()[5] / w0 == pytest.approx(1.08**-10, rel=2e-3)


ARM = """Robot { supervisor TRUE children [ HingeJoint {
  jointParameters HingeJointParameters { axis 0 1 0 }
  device [ RotationalMotor { name "m" maxTorque 100 } ]
  endPoint Solid { translation 0.5 0 0 boundingObject Sphere { radius 0.05 }
                   physics Physics { density -1 mass 2 } } } ] }"""


def test_torque_feedback_is_the_torque_holding_the_arm() -> None:
    sup = _sup(ARM, info="gravity 9.81")
    motor = sup.getDevice("m")
    assert math.isnan(motor.getTorqueFeedback())  # control: NaN until enabled and sampled
    motor.enableTorqueFeedback(8)
    assert motor.getTorqueFeedbackSamplingPeriod() == 8
    for _ in range(100):
        sup.step(8)
    # statics: the motor holds a 2 kg mass 0.5 m from the axis: |τ| = m·g·L about the hinge axis (+y); gravity
    # would turn the arm about +y (positive), so the motor pushes about −y
    assert motor.getTorqueFeedback() == pytest.approx(-2 * 9.81 * 0.5, rel=2e-2)
    assert motor.torque_feedback == motor.getTorqueFeedback()


def _ball_spin(damping3: float) -> float:
    sup = _sup(f"""Robot {{ supervisor TRUE children [ BallJoint {{
  jointParameters BallJointParameters {{ anchor 0 0 0.3 }}
  jointParameters3 JointParameters {{ axis 0 0 1 dampingConstant {damping3} }}
  endPoint DEF BALL Solid {{ translation 0 0 0.3 angularVelocity 0 0 10 boundingObject Sphere {{ radius 0.1 }}
                             physics Physics {{ density -1 mass 1 }} }} }} ] }}""")
    ball = sup.getFromDef("BALL")
    for _ in range(10):
        sup.step(8)
    return ball.getVelocity()[5]


def test_ball_joint_damping_acts_on_its_axis() -> None:
    # implicit damper row on the third axis: ω ← ω / (1 + h·B/I) per step, I = 2/5·m·r² = 0.004 kg·m²
    assert _ball_spin(0.04) == pytest.approx(10.0 * 1.08**-10, rel=2e-3)
    assert _ball_spin(0.0) == pytest.approx(10.0, rel=1e-9)  # control: a free ball joint keeps the spin
