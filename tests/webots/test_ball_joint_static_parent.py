"""A BallJoint whose parent is static (a Robot without Physics) turns, stops and takes torques on each of its
three axes as one whose parent is a body.

On a static parent ODE has only the endPoint to attach the joint's Euler AMotor to. Attached as (none, endPoint)
ODE flags the AMotor reversed, which its Euler mode does not follow: the second axis' motor drove the joint away
from its target (position control ran to about −1.4 rad for a 0.7 rad target), the stops of the first and third
axes never held and torques on them turned the joint backwards. The endPoint sphere is centred on the anchor, so
each motion is a pure rotation whose angle follows by hand.
"""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

H = 0.016
INERTIA = 0.4 * 2.0 * 0.1**2  # a 2 kg sphere of radius 0.1 m about its centre
HEAVY_PARENT = "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1e6 }"


def _robot(parent: str, stops_on: int = 0) -> tuple[Simulation, Supervisor]:
    stops = ["", "", ""]
    if stops_on:
        stops[stops_on - 1] = "minStop -0.2 maxStop 0.5"
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 physicsDisableTime 0 }}
Robot {{
  children [
    BallJoint {{
      jointParameters BallJointParameters {{ anchor 1 0 0 {stops[0]} }}
      jointParameters2 JointParameters {{ axis 1 0 0 {stops[1]} }}
      jointParameters3 JointParameters {{ axis 0 0 1 {stops[2]} }}
      device [ RotationalMotor {{ name "m1" maxTorque 1000 }} PositionSensor {{ name "s1" }} ]
      device2 [ RotationalMotor {{ name "m2" maxTorque 1000 }} PositionSensor {{ name "s2" }} ]
      device3 [ RotationalMotor {{ name "m3" maxTorque 1000 }} PositionSensor {{ name "s3" }} ]
      endPoint Solid {{
        translation 1 0 0
        boundingObject Sphere {{ radius 0.1 }}
        physics Physics {{ density -1 mass 2 }}
      }}
    }}
  ]
  {HEAVY_PARENT if parent == "body" else ""}
  supervisor TRUE
}}
"""
    sim = Simulation(load_world_text(text))
    assert sim.joints[0].reverse is (parent == "static")
    return sim, Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _positions(robot: Supervisor) -> list[float]:
    return [robot.getDevice(f"s{i}").getValue() for i in (1, 2, 3)]


def _run(robot: Supervisor, steps: int) -> list[float]:
    for i in (1, 2, 3):
        robot.getDevice(f"s{i}").enable(16)
    for _ in range(steps):
        robot.step(16)
    return _positions(robot)


@pytest.mark.parametrize("parent", ["static", "body"])
@pytest.mark.parametrize("axis", [1, 2, 3])
def test_position_control_reaches_the_target_on_each_axis(parent: str, axis: int) -> None:
    _, robot = _robot(parent)
    robot.getDevice(f"m{axis}").setPosition(0.7)
    expected = [0.0, 0.0, 0.0]
    expected[axis - 1] = 0.7
    assert _run(robot, 100) == pytest.approx(expected, abs=1e-5)


@pytest.mark.parametrize("parent", ["static", "body"])
@pytest.mark.parametrize("axis", [1, 2, 3])
@pytest.mark.parametrize("velocity", [1.0, -1.0])
def test_stops_hold_each_axis_at_its_limits(parent: str, axis: int, velocity: float) -> None:
    _, robot = _robot(parent, stops_on=axis)
    motor = robot.getDevice(f"m{axis}")
    motor.setPosition(math.inf)
    motor.setVelocity(velocity)
    # driven at 1 rad/s for 0.96 s: it would reach ±0.96 rad; it rests on the stop (0.5 or −0.2, ERP-soft)
    assert _run(robot, 60)[axis - 1] == pytest.approx(0.5 if velocity > 0 else -0.2, abs=0.003)


@pytest.mark.parametrize("axis", [1, 2, 3])
def test_a_torque_turns_each_axis_its_own_way(axis: int) -> None:
    _, robot = _robot("static")
    robot.getDevice(f"m{axis}").setTorque(0.01)
    n = 60
    # ω grows by h·τ/I per step and the angle by h·ω: θ_n = h²·τ/I·n(n+1)/2 (small-angle quaternion steps)
    expected = [0.0, 0.0, 0.0]
    expected[axis - 1] = H * H * 0.01 / INERTIA * n * (n + 1) / 2
    assert _run(robot, n) == pytest.approx(expected, rel=1e-3, abs=1e-9)
