"""Kinematic joint motors (a joint whose endPoint has no Physics) ramp their speed as Webots' kinematic controller does.

Webots (docs/reference/webots-on-ode.md §5.3, webots-devices.md §8, ``WbMotor.runKinematicControl``): with no ODE
joint the motor moves the endPoint itself, and its current velocity changes by at most ``a·h`` per basic step, ``a``
being the motor's ``acceleration`` field, or its available torque when the field is -1 or larger than that. The
expected positions below are sums of those ramps by hand (basicTimeStep 16 ms); moving at full speed from the first
step (what the twin did before) is far off in every case.
"""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

H = 0.016


def _robot(motor: str) -> tuple[Supervisor, Simulation]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 }}
Robot {{
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 0 1 }}
      device [ RotationalMotor {{ name "m" {motor} }} PositionSensor {{ name "ps" }} ]
      endPoint Solid {{ translation 0.5 0 0 children [ Shape {{ geometry Box {{ size 0.1 0.1 0.1 }} }} ] }}
    }}
  ]
  supervisor TRUE
}}
"""
    sim = Simulation(load_world_text(text))
    assert sim.joints[0].kinematic
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node), sim


def _readings(robot: Supervisor, steps: int) -> list[float]:
    sensor = robot.getDevice("ps")
    sensor.enable(16)
    out = []
    for _ in range(steps):
        robot.step(16)
        out.append(sensor.getValue())
    return out


@pytest.mark.parametrize(
    ("fields", "slew", "speed"),
    [
        ("maxVelocity 2 acceleration 5", 5.0 * H, 2.0),  # the acceleration field
        ("maxVelocity 1 maxTorque 3", 3.0 * H, 1.0),  # -1: the available torque, read as rad/s²
        ("maxVelocity 1 maxTorque 3 acceleration 50", 3.0 * H, 1.0),  # larger than the torque: the torque
    ],
    ids=["acceleration", "unlimited", "above-torque"],
)
def test_velocity_control_ramps_the_speed(fields: str, slew: float, speed: float) -> None:
    robot, _ = _robot(fields)
    motor = robot.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(speed)
    readings = _readings(robot, 40)
    expected, position = [], 0.0
    for k in range(1, 41):
        position += min(k * slew, speed) * H
        expected.append(position)
    assert readings == pytest.approx(expected, abs=1e-12)
    assert readings[-1] < 40 * speed * H - 0.01  # control: full speed from the first step covers more


def test_setting_available_torque_lowers_the_ramp() -> None:
    robot, _ = _robot("maxVelocity 1 maxTorque 3")
    motor = robot.getDevice("m")
    motor.setAvailableTorque(1.0)  # a = min(-1 -> available, ...) = 1 rad/s²
    motor.setPosition(math.inf)
    motor.setVelocity(1.0)
    readings = _readings(robot, 10)
    assert readings[-1] == pytest.approx(sum(k * H * H for k in range(1, 11)), abs=1e-12)


def test_position_control_ramps_then_stops_on_the_target() -> None:
    robot, sim = _robot("maxVelocity 2 acceleration 5")
    motor = robot.getDevice("m")
    motor.setPosition(0.3)
    readings = _readings(robot, 30)
    # speed 0.08·k after step k, so 0.016·0.08·k(k+1)/2 = 0.00064·k(k+1) rad: 0.29568 after 21 steps; the 22nd step
    # (0.02816 rad) would pass the target, so the motor stops on it and its velocity drops to 0
    assert readings[:21] == pytest.approx([0.00064 * k * (k + 1) for k in range(1, 22)], abs=1e-12)
    assert readings[21:] == [0.3] * 9
    assert sim.joint_velocity(sim.joints[0]) == 0.0
    motor.setPosition(0.0)  # back: the speed ramps again from rest, the other way
    back = _readings(robot, 2)
    assert back == pytest.approx([0.3 - 0.00128, 0.3 - 0.00384], abs=1e-12)
    assert sim.joint_velocity(sim.joints[0]) == pytest.approx(-0.16)


HINGE2 = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 }}
Robot {{
  translation 0 0 1
  children [
    Hinge2Joint {{
      jointParameters HingeJointParameters {{ axis 0 0 1 }}
      jointParameters2 JointParameters {{ axis 0 1 0 }}
      device [ RotationalMotor {{ name "steer" }} PositionSensor {{ name "steer sensor" }} ]
      device2 [ RotationalMotor {{ name "spin" }} PositionSensor {{ name "spin sensor" }} ]
      endPoint DEF WHEEL Solid {{
        translation 0.3 0 0
        boundingObject Box {{ size 0.1 0.1 0.1 }}
        physics Physics {{ }}
      }}
    }}
  ]
  {robot_physics}
  supervisor TRUE
}}
"""


def _rotation(axis: tuple[float, float, float], angle: float) -> list[list[float]]:
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    return [
        [c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
        [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)],
    ]


def test_a_hinge2_on_a_parent_without_body_moves_its_endpoint_kinematically() -> None:
    """A static Robot's Hinge2Joint gets no ODE joint (§4.4) and is handled kinematically (§4.1): its motors turn the
    endPoint, which has Physics of its own, about the first axis (steering) and the carried second axis (spin), and
    gravity does not pull it off the joint. Before, the endPoint fell as a free body and never turned."""
    with pytest.warns(UserWarning, match="handled kinematically"):
        sim = Simulation(load_world_text(HINGE2.format(robot_physics="")))
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    steer, spin = robot.getDevice("steer"), robot.getDevice("spin")
    sensors = [robot.getDevice("steer sensor"), robot.getDevice("spin sensor")]
    for sensor in sensors:
        sensor.enable(16)
    steer.setPosition(0.5)
    spin.setPosition(math.inf)
    spin.setVelocity(2.0)
    wheel = robot.getFromDef("WHEEL")
    for _ in range(40):
        robot.step(16)
    a, b = (sensor.getValue() for sensor in sensors)
    assert a == 0.5  # reached and stopped
    assert b == pytest.approx(sum(min(0.16 * k, 2.0) * H for k in range(1, 41)), abs=1e-12)  # 10 rad/s² ramp
    z, y = _rotation((0.0, 0.0, 1.0), a), _rotation((0.0, 1.0, 0.0), b)
    expected = [sum(z[i][k] * y[k][j] for k in range(3)) for i in range(3) for j in range(3)]
    assert wheel.getOrientation() == pytest.approx(expected, abs=1e-9)
    # both axes pass through the anchor (the Robot's origin): the wheel's centre is turned about it
    assert wheel.getPosition() == pytest.approx([0.3 * expected[0], 0.3 * expected[3], 1.0 + 0.3 * expected[6]], abs=1e-9)
    assert wheel.getVelocity() == pytest.approx([0.0] * 6, abs=1e-9)


def test_a_hinge2_on_a_body_stays_dynamic() -> None:
    """Control: with a body as parent the Hinge2 is an ODE joint and its endPoint a free-moving body under gravity."""
    text = HINGE2.format(robot_physics="physics Physics { }\n  boundingObject Box { size 0.1 0.1 0.1 }")
    sim = Simulation(load_world_text(text))
    assert not sim.joints[0].kinematic
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    wheel = robot.getFromDef("WHEEL")
    for _ in range(10):
        robot.step(16)
    assert wheel.getPosition()[2] < 0.99  # robot and wheel fall together


def test_a_propeller_in_position_mode_ramps_its_speed_too() -> None:
    """A Propeller's motor runs the same kinematic controller: in position mode its speed ramps by the acceleration
    (500 rad/s², 2 rad/s more per 4 ms step) and drops to 0 on the target, so the thrust t1·ω² a 1 kg drone feels
    (no gravity) grows step by step and stops. Before, ω jumped to the commanded 100 rad/s at once."""
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 4 gravity 0 }
DEF DRONE Robot {
  supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 }
  children [ Propeller { shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0
    device RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 acceleration 500 } } ]
}
"""
    sim = Simulation(load_world_text(text))
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    prop = robot.getDevice("prop")
    prop.setPosition(1.0)  # the angle moves 0.004·2·k(k+1)/2 rad in k steps: 0.96 after 15, on 1.0 at the 16th
    prop.setVelocity(100.0)
    drone = robot.getFromDef("DRONE")
    speeds, vz = [], 0.0
    for k in range(1, 21):
        robot.step(4)
        if k < 16:
            vz += 1e-4 * (2.0 * k) ** 2 * 0.004  # m = 1 kg
        speeds.append(drone.getVelocity()[2])
        assert speeds[-1] == pytest.approx(vz, rel=1e-9, abs=1e-15)
    assert speeds[15:] == [speeds[14]] * 5
