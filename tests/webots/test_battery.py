"""Robot battery: energy drained by cpuConsumption and by each motor's consumptionFactor × |output torque|
(Webots' documented model), read through the battery sensor the Robot API uses."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation

TS = 16
G = 9.81


def _robot(battery: str, arm: str = "") -> Robot:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ battery [ {battery} ] cpuConsumption 10 children [ {arm} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node)


# a 1 kg point-like mass 0.5 m out on a horizontal arm, held by a position-controlled hinge about y
ARM = """HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 }
  device [ RotationalMotor { name "m" maxTorque 100 consumptionFactor 10 } ]
  endPoint Solid { translation 0.5 0 0 physics Physics { mass 1 density -1 centerOfMass [ 0 0 0 ]
    inertiaMatrix [ 1e-4 1e-4 1e-4 0 0 0 ] } } }"""


def _energy_after(robot: Robot, seconds: float) -> float:
    robot.batterySensorEnable(TS)
    for _ in range(round(seconds * 1000 / TS)):  # callers pass whole multiples of 16 ms
        robot.step(TS)
    return robot.batterySensorGetValue()


def test_cpu_consumption_alone() -> None:
    robot = _robot("100 100 0")
    assert math.isnan(robot.batterySensorGetValue())  # nothing sampled yet
    assert _energy_after(robot, 1.024) == pytest.approx(100 - 10 * 1.024, abs=1e-9)


def test_holding_a_load_costs_consumption_factor_times_torque() -> None:
    robot = _robot("1000 1000 0", ARM)
    start = _energy_after(robot, 1.024)  # let the hold settle
    end = _energy_after(robot, 1.024)
    # 10 W of CPU plus 10 × (1 kg · g · 0.5 m) W for the motor, over 1.024 s
    assert start - end == pytest.approx((10 + 10 * G * 0.5) * 1.024, rel=0.01)


def test_empty_battery_stays_at_zero_and_no_battery_reads_nan() -> None:
    assert _energy_after(_robot("0.05 1 0"), 0.096) == 0.0
    assert math.isnan(_energy_after(_robot(""), 0.096))
