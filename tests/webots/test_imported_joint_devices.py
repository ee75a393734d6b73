"""A motor, position sensor or brake a supervisor imports into a joint's ``device`` field joins its robot's device
list (``getDevice`` finds it, ``getNumberOfDevices`` counts it) and acts on the joint from the next step; removing
it takes it out of the list and ends its effect (also from controllers in their own processes).

Expectations by hand (no gravity, basicTimeStep h = 4 ms). The rotor is a sphere (r = 0.1 m, density 1000:
m = 4.18879 kg) centred on a hinge about z, so its moment of inertia about the axis is I = 2/5·m·r² = 0.0167552
kg·m² and a 0.01 N·m torque about z held for one step adds 0.01·h/I = 0.00238732 rad/s to its spin (a pure
couple: the hinge's reaction has no moment about its own axis). A motor holding the joint (its state after the
import, §5.1: the current position at maxVelocity with 10 N·m) takes that torque: the spin does not change.
Driven at 2 rad/s (setPosition(inf)), the rotor needs 2·I/h = 8.4 N·m to get there in one step, within the
10 N·m it has: it turns at 2 rad/s from the next step. A brake with damping c makes the axis' implicit damper:
one step takes the spin ω to ω·I/(I + c·h)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world
from tests.support.webots_scene import write_controllers

TS = 4
H = TS / 1000
R = 0.1
I_AXIS = 0.4 * (1000 * 4 / 3 * math.pi * R**3) * R * R
TAU = 0.01
ROTOR = f"DEF ROTOR Solid {{ boundingObject Sphere {{ radius {R} }} physics Physics {{ }} }}"
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BOT Robot {{
  supervisor TRUE
  children [
    DEF HINGE HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 0 1 }}
      endPoint {ROTOR}
    }}
  ]
}}
"""


def _supervisor() -> Supervisor:
    sup = Supervisor(simulation=Simulation(load_world_text(WORLD)))
    sup.step(TS)
    return sup


def _spin(sup: Supervisor) -> float:
    return float(sup.getFromDef("ROTOR").getVelocity()[5])


def _kick(sup: Supervisor) -> float:
    """What one step of TAU about z adds to the rotor's spin."""
    before = _spin(sup)
    sup.getFromDef("ROTOR").addTorque([0.0, 0.0, TAU], False)
    sup.step(TS)
    return _spin(sup) - before


def test_an_imported_motor_is_a_device_and_drives_the_joint_and_its_removal_lets_it_go() -> None:
    sup = _supervisor()
    assert sup.getNumberOfDevices() == 0
    assert _kick(sup) == pytest.approx(TAU * H / I_AXIS, rel=1e-6)  # control: nothing holds the joint
    sup.getFromDef("ROTOR").resetPhysics()
    device = sup.getFromDef("HINGE").getField("device")
    device.importMFNodeFromString(-1, 'RotationalMotor { name "m2" }')
    assert sup.getNumberOfDevices() == 1
    motor = sup.getDevice("m2")
    assert motor is not None and sup.getDeviceByIndex(0).getName() == "m2"
    assert abs(_kick(sup)) < 1e-4 * TAU * H / I_AXIS  # the motor holds the joint (§5.1)
    motor.setPosition(math.inf)
    motor.setVelocity(2.0)
    for _ in range(5):
        sup.step(TS)
    assert _spin(sup) == pytest.approx(2.0, abs=1e-9)
    device.removeMF(0)
    assert sup.getDevice("m2") is None
    assert sup.getNumberOfDevices() == 0
    motor.setVelocity(0.0)  # a handle on the removed motor commands nothing
    assert _kick(sup) == pytest.approx(TAU * H / I_AXIS, rel=1e-6)  # free again: the torque adds its spin
    assert _spin(sup) == pytest.approx(2.0 + TAU * H / I_AXIS, rel=1e-9)


def test_an_imported_position_sensor_reads_the_joint() -> None:
    sup = _supervisor()
    sup.getFromDef("ROTOR").setVelocity([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    for _ in range(10):
        sup.step(TS)
    sup.getFromDef("HINGE").getField("device").importMFNodeFromString(-1, 'PositionSensor { name "s2" }')
    sensor = sup.getDevice("s2")
    sensor.enable(TS)
    sup.step(TS)
    assert sensor.getValue() == pytest.approx(11 * H, rel=1e-5)  # 1 rad/s since the first of 11 steps
    sup.getFromDef("HINGE").getField("device").removeMF(-1)
    assert sup.getNumberOfDevices() == 0


def test_an_imported_brake_damps_the_joint_and_its_removal_takes_the_damping_away() -> None:
    sup = _supervisor()
    sup.getFromDef("ROTOR").setVelocity([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    sup.step(TS)
    device = sup.getFromDef("HINGE").getField("device")
    device.importMFNodeFromString(-1, 'Brake { name "b" }')
    sup.getDevice("b").setDampingConstant(0.5)
    sup.step(TS)
    assert _spin(sup) == pytest.approx(I_AXIS / (I_AXIS + 0.5 * H), rel=1e-9)
    device.removeMF(0)
    before = _spin(sup)
    sup.step(TS)
    assert _spin(sup) == pytest.approx(before, rel=1e-12)  # undamped again


def test_a_reset_takes_an_imported_motor_away() -> None:
    sup = _supervisor()
    sup.getFromDef("HINGE").getField("device").importMFNodeFromString(-1, 'RotationalMotor { name "m2" }')
    assert abs(_kick(sup)) < 1e-4 * TAU * H / I_AXIS  # control: held
    sup.simulationReset()
    sup.step(TS)
    assert sup.getNumberOfDevices() == 0
    assert _kick(sup) == pytest.approx(TAU * H / I_AXIS, rel=1e-6)


ARM_CONTROLLER = """
    import os
    from controller import Robot
    HERE = os.path.dirname(os.path.abspath(__file__))  # (threads share one working folder)
    robot = Robot()
    sensor = robot.getDevice("s")
    sensor.enable(4)
    counts, values, driven = [], [], False
    while robot.step(4) != -1:
        counts.append(robot.getNumberOfDevices())
        if counts[-1] == 2 and not driven:
            motor = robot.getDevice("m2")
            motor.setPosition(float("inf"))
            motor.setVelocity(2.0)
            driven = True
        values.append(sensor.getValue())
    with open(os.path.join(HERE, "out.txt"), "w") as out:
        out.write(f"{counts[0]} {counts[-1]} {(values[-1] - values[-2]) / 0.004}")
"""
SUPERVISOR = """
    from controller import Supervisor
    sup = Supervisor()
    sup.step(4)
    sup.step(4)
    sup.getFromDef("HINGE").getField("device").importMFNodeFromString(-1, 'RotationalMotor { name "m2" }')
    while sup.step(4) != -1:
        pass
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_robot_controller_finds_a_motor_a_supervisor_imported_into_its_joint(tmp_path: Path, isolation: str) -> None:
    write_controllers(tmp_path, {"arm": ARM_CONTROLLER, "sup": SUPERVISOR})
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ name "boss" controller "sup" supervisor TRUE }}
Robot {{
  name "arm"
  controller "arm"
  children [
    DEF HINGE HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 0 1 }}
      device [ PositionSensor {{ name "s" }} ]
      endPoint {ROTOR}
    }}
  ]
}}
""")
    assert run_world(world, None, 0.2, isolation=isolation) == 0
    first, last, rate = (tmp_path / "controllers" / "arm" / "out.txt").read_text().split()
    assert (int(first), int(last)) == (1, 2)  # the sensor alone at first, then the imported motor too
    assert float(rate) == pytest.approx(2.0, abs=1e-4)  # the motor turns the joint at the commanded speed


def test_an_imported_linear_motor_drives_a_slider() -> None:
    # the slider's endPoint starts at the joint's origin; a LinearMotor imported into its device field takes it to
    # the commanded position along the axis (x here): its P control (§5.3) closes the last of the gap with a time
    # constant of 1/P = 0.1 s, so within 1 mm after a second
    world = WORLD.replace("HingeJointParameters { axis 0 0 1 }", "JointParameters { axis 1 0 0 }")
    sup = Supervisor(simulation=Simulation(load_world_text(world.replace("DEF HINGE HingeJoint", "DEF HINGE SliderJoint"))))
    sup.step(TS)
    sup.getFromDef("HINGE").getField("device").importMFNodeFromString(-1, 'LinearMotor { name "lm" }')
    sup.getDevice("lm").setPosition(0.1)
    for _ in range(250):
        sup.step(TS)
    assert sup.getFromDef("ROTOR").getPosition() == pytest.approx([0.1, 0.0, 0.0], abs=1e-3)
