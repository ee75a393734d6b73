"""Robot battery: energy drained by cpuConsumption and by each motor's consumptionFactor × |output torque|
(Webots' documented model), read through the battery sensor the Robot API uses."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world

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


# -- out of power: Webots' Robot docs, "when the current energy value reaches zero, the corresponding controller
# process terminates and the simulated robot stops all motion"

# a wheel on a vertical axis (gravity does not turn it), driven in velocity control; its motor draws nothing, so
# only the CPU drains the battery: 10 W × 16 ms = 0.16 J a step
WHEEL = """HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }
  device [ RotationalMotor { name "m" maxTorque 10 consumptionFactor 0 } ]
  endPoint Solid { translation 0.2 0 0 physics Physics { mass 1 density -1 centerOfMass [ 0 0 0 ]
    inertiaMatrix [ 1e-3 1e-3 1e-3 0 0 0 ] } } }"""


def _spin(robot: Robot, steps: int) -> list[int]:
    motor = robot.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(5.0)
    return [robot.step(TS) for _ in range(steps)]


def _wheel_speed(robot: Robot) -> float:
    """rad/s over 10 more basic steps of the world, after 5 to settle, run without the controller (the test reads
    the joint's state, not the API's)."""
    sim = robot._Robot__link._sim  # type: ignore[attr-defined]
    joint = sim.motors[0].joint
    sim.step(5)
    before = joint.positions[0]
    sim.step(10)
    return float((joint.positions[0] - before) / (10 * TS / 1000))


def test_the_step_that_empties_the_battery_ends_the_controller_and_the_motors_stop() -> None:
    robot = _robot("0.5 1 0", WHEEL)  # 0.5 J: three steps leave 0.02 J, the fourth empties it
    assert _spin(robot, 6) == [0, 0, 0, -1, -1, -1]
    assert abs(_wheel_speed(robot)) < 1e-6  # held still
    assert robot._Robot__link._sim.robots[0].node.fields["battery"][0] == 0.0  # type: ignore[attr-defined]


def test_control_with_energy_left_the_controller_runs_and_the_wheel_turns() -> None:
    robot = _robot("100 100 0", WHEEL)
    assert _spin(robot, 6) == [0] * 6
    assert _wheel_speed(robot) == pytest.approx(5.0, abs=0.01)


# a robot on the ground with a Propeller and a Track, both driven in velocity control (their motors draw nothing)
DRIVES = """Propeller { shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0
  device RotationalMotor { name "prop" maxVelocity 100 consumptionFactor 0 } }
Track { boundingObject Box { size 0.4 0.2 0.05 } physics Physics { mass 1 }
  device [ LinearMotor { name "belt" consumptionFactor 0 } ] }"""


@pytest.mark.parametrize(("battery", "stopped"), [("0.5 1 0", True), ("100 100 0", False)])
def test_out_of_power_the_tracks_and_propellers_stop_too(battery: str, stopped: bool) -> None:
    robot = _robot(battery, DRIVES)  # 0.5 J: the fourth step empties it (10 W of CPU); 100 J: the control
    for name, speed in (("prop", 50.0), ("belt", 0.5)):
        robot.getDevice(name).setPosition(math.inf)
        robot.getDevice(name).setVelocity(speed)
    for _ in range(6):
        robot.step(TS)
    sim = robot._Robot__link._sim  # type: ignore[attr-defined]
    sim.step(100)  # the world goes on without the controller (it ended at -1): 1.7 s in all
    spin, belt = sim.extensions["propellers"].recs[0].omega, sim.extensions["tracks"].recs[0].velocity
    # with power the propeller spins up at 10 rad/s² (maxTorque 10, webots-devices.md §8): 17 rad/s after 1.7 s
    assert (spin, belt) == ((0.0, 0.0) if stopped else (pytest.approx(10 * 106 * TS / 1000), pytest.approx(0.5)))


CONTROLLER = """
from controller import Robot
robot = Robot()
motor = robot.getDevice("m")
motor.setPosition(float("inf"))
motor.setVelocity(5.0)
steps = 0
while robot.step(16) != -1:
    steps += 1
print("steps", steps, "time", round(robot.getTime(), 3))
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_controller_process_ends_when_its_battery_runs_out(tmp_path: Path, isolation: str,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    world = tmp_path / "worlds" / "battery.wbt"
    world.parent.mkdir()
    world.write_text(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ battery [ 0.5 1 0 ] cpuConsumption 10 children [ {WHEEL} ] controller "spin" }}
""")
    script = tmp_path / "controllers" / "spin" / "spin.py"
    script.parent.mkdir(parents=True)
    script.write_text(CONTROLLER)
    assert run_world(world, None, 5.0, isolation=isolation) == 0
    # three steps returned 0, the fourth -1; the simulation had reached 64 ms, not the 5 s limit
    assert "steps 3 time 0.064" in capsys.readouterr().out


# -- Charger: a battery itself, filling at its own charging speed and recharging a robot within its radius

def _charging(robot_battery: str, charger_battery: str, *, at: float = 0.0, radius: float = 0.5,
              second_robot: str = "") -> tuple[Robot, Simulation]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ battery [ {robot_battery} ] cpuConsumption 0 }}
{second_robot}
Charger {{ translation {at} 0 0 battery [ {charger_battery} ] radius {radius} }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node), sim


def _levels(sim: Simulation) -> tuple[list[float], ...]:
    robots = [list(r.node.fields["battery"]) for r in sim.robots]
    charger = next(s for s in sim.solids if s.node.type_name == "Charger")
    return (*robots, list(charger.node.fields["battery"]))


SECONDS = 1.024  # 64 steps of 16 ms


def test_a_robot_in_the_charger_radius_takes_its_recharge_speed_from_the_charger() -> None:
    robot, sim = _charging("1 100 2", "10 50 1", at=0.3)
    assert _energy_after(robot, SECONDS) == pytest.approx(1 + 2 * SECONDS, abs=1e-9)
    mine, charger = _levels(sim)
    assert mine[1:] == [100, 2] and charger[1:] == [50, 1]
    # the charger filled itself by 1 W and gave 2 W
    assert charger[0] == pytest.approx(10 + (1 - 2) * SECONDS, abs=1e-9)


def test_control_a_robot_outside_the_radius_gains_nothing_and_the_charger_fills_itself() -> None:
    robot, sim = _charging("1 100 2", "10 50 1", at=0.6)
    assert _energy_after(robot, SECONDS) == pytest.approx(1.0, abs=1e-12)
    assert _levels(sim)[1][0] == pytest.approx(10 + 1 * SECONDS, abs=1e-9)


def test_the_robot_takes_at_most_what_the_charger_holds_and_what_its_battery_lacks() -> None:
    robot, sim = _charging("1 100 2", "0 50 1")  # an empty charger passes on only what it gains
    assert _energy_after(robot, SECONDS) == pytest.approx(1 + 1 * SECONDS, abs=1e-9)
    assert _levels(sim)[1][0] == pytest.approx(0.0, abs=1e-12)
    robot, sim = _charging("99.5 100 2", "10 50 0")  # a nearly full robot stops at its maximum
    assert _energy_after(robot, SECONDS) == pytest.approx(100.0, abs=1e-12)
    assert _levels(sim)[1][0] == pytest.approx(9.5, abs=1e-9)


def test_a_charger_serves_one_robot_the_first_in_world_order() -> None:
    other = 'Robot { translation 0.1 0 0 battery [ 1 100 2 ] cpuConsumption 0 name "second" }'
    _robot_api, sim = _charging("1 100 2", "10 50 0", second_robot=other)
    _energy_after(_robot_api, SECONDS)
    first, second, charger = _levels(sim)
    assert first[0] == pytest.approx(1 + 2 * SECONDS, abs=1e-9)
    assert second[0] == 1.0
    assert charger[0] == pytest.approx(10 - 2 * SECONDS, abs=1e-9)


def test_a_world_with_a_charger_loads_without_a_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Charger {{ battery [ 1 2 3 ] }}
"""))
    try:
        assert sim.build_warnings == []
    finally:
        sim.close()
