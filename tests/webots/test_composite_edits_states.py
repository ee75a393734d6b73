"""Supervisor field edits meeting ``Node.saveState``/``loadState``: a state restore takes an edited motor and edited
devices back to the saved configuration, and the scene's nodes stay the ones the physics and the devices know.

Webots saves a state field by field and restores it as field changes (the load state ``"__init__"`` is the one
``simulationReset`` restores, S §6: "all fields ... restored"), so a restored ``maxVelocity``, ``lookupTable`` or
``channel`` acts as a supervisor's write of it does (the ``update*`` slots of the motor and the devices). The
reference names a state only as a "snapshot of the node subtree" (P, Node.saveState); our reading: its fields, poses,
velocities and joint positions (see ``dualtwin.webots.node_states``).

S = shared/reference/webots-on-ode.md, D = webots-devices.md, P = webots-python-api.md. Expected values are hand
computations from these rules; each test has its control (the same run without the restore)."""

from __future__ import annotations

from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, DT, TS, load_arm
from tests.support.sensor_worlds import sensor_world

STEP = 8
# a wall whose near face is the plane x = 0.5, in front of the sensor (axis +x) at the robot's origin
WALL = "Solid { translation 0.6 0 0.1 boundingObject Box { size 0.2 4 4 } }"


def _arm() -> tuple[Supervisor, Any, Any]:
    """The arm: a strong RotationalMotor 'm' (maxVelocity 10) DEF MOT and its PositionSensor 's'."""
    _, sup = load_arm("HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 } "
                      'device [ DEF MOT RotationalMotor { name "m" maxTorque 1000 maxVelocity 10 } '
                      f'PositionSensor {{ name "s" }} ] endPoint {BOB.format(t="0.5 0 0")} }}')
    sensor = sup.getDevice("s")
    sensor.enable(TS)
    return sup, sup.getDevice("m"), sensor


def _speed(sup: Supervisor, sensor: Any) -> float:
    """The joint's speed over one step while the motor runs at its velocity limit toward a far target."""
    before = sensor.getValue()
    assert sup.step(TS) != -1
    return (sensor.getValue() - before) / DT


@pytest.mark.parametrize("restore", [True, False])
def test_load_state_gives_an_edited_motor_its_saved_max_velocity(restore: bool) -> None:
    # S §5.2: setVelocity(5) is clamped to ±maxVelocity; S §5.3 step 2: the target 3 rad away asks u = Kp·e =
    # 30 rad/s, clipped to the target velocity: the joint turns at it (the 1000 N·m motor reaches it within a step,
    # see test_runtime_motor_edits). Saved at maxVelocity 10, edited to 2: after a restore setVelocity(5) gives
    # 5 rad/s, the control's is clamped to 2
    sup, motor, sensor = _arm()
    robot = sup.getSelf()
    assert sup.step(TS) != -1
    robot.saveState("fast")
    sup.getFromDef("MOT").getField("maxVelocity").setSFFloat(2.0)
    motor.setPosition(-3.0)
    assert sup.step(TS) != -1
    assert _speed(sup, sensor) == pytest.approx(-2.0, rel=1e-2)
    if restore:
        robot.loadState("fast")  # (the joint is put back at 0 too)
        assert sup.step(TS) != -1
    motor.setVelocity(5.0)
    assert sup.step(TS) != -1
    assert _speed(sup, sensor) == pytest.approx(-5.0 if restore else -2.0, rel=1e-2)
    assert motor.getMaxVelocity() == (10.0 if restore else 2.0)
    assert sup.getFromDef("MOT").getField("maxVelocity").getSFFloat() == (10.0 if restore else 2.0)


@pytest.mark.parametrize("restore", [True, False])
def test_load_state_gives_edited_devices_their_saved_fields(restore: bool) -> None:
    # D §1.4: the default table [0 0 0, 0.1 1000 0] reaches 0.1 m, short of the wall at 0.5 m: the sensor reads the
    # last output, 1000; edited to [0 0 0, 1 3000 0] it reads 0.5·3000 = 1500. The Emitter saved on channel 0
    # (its default, D §5) and written 3 is on 0 again after the restore
    sup = sensor_world('DEF DS DistanceSensor { name "ds" } DEF TX Emitter { name "tx" }', WALL, step=STEP)
    ds, tx = sup.getDevice("ds"), sup.getDevice("tx")
    ds.enable(STEP)
    robot = sup.getSelf()
    assert sup.step(STEP) != -1
    robot.saveState("plain")
    table = sup.getFromDef("DS").getField("lookupTable")
    table.setMFVec3f(1, [1.0, 3000.0, 0.0])
    sup.getFromDef("TX").getField("channel").setSFInt32(3)
    assert sup.step(STEP) != -1
    assert (ds.getValue(), tx.getChannel()) == (pytest.approx(1500.0), 3)
    if restore:
        robot.loadState("plain")
    assert sup.step(STEP) != -1
    assert ds.getValue() == pytest.approx(1000.0 if restore else 1500.0)
    assert ds.getLookupTable() == [0.0, 0.0, 0.0, 0.1, 1000.0, 0.0] if restore else [0.0, 0.0, 0.0, 1.0, 3000.0, 0.0]
    assert tx.getChannel() == (0 if restore else 3)


@pytest.mark.parametrize("restore", [True, False])
def test_after_load_state_the_scene_nodes_are_those_the_motor_follows(restore: bool) -> None:
    # a restore keeps the subtree's nodes: the motor node a supervisor reaches afterwards (getFromDef) is the one the
    # motor reads, so its edit to 2 rad/s turns the joint at 2 rad/s (same rule as the first test) with or without a
    # restore before it
    sup, motor, sensor = _arm()
    robot = sup.getSelf()
    assert sup.step(TS) != -1
    robot.saveState("start")
    if restore:
        robot.loadState("start")
    assert sup.step(TS) != -1
    sup.getFromDef("MOT").getField("maxVelocity").setSFFloat(2.0)
    motor.setPosition(3.0)
    assert sup.step(TS) != -1
    assert _speed(sup, sensor) == pytest.approx(2.0, rel=1e-2)
    assert motor.getMaxVelocity() == 2.0


@pytest.mark.parametrize("restore", [True, False])
def test_load_state_init_gives_the_load_configuration(restore: bool) -> None:
    # "__init__" is the load state (P, Node.loadState; the state simulationReset restores, S §6): an edit of
    # maxVelocity to 2 is undone, setVelocity(5) is not clamped and the joint turns at 5 rad/s (same rules as the
    # first test); the control's is clamped to 2
    sup, motor, sensor = _arm()
    robot = sup.getSelf()
    assert sup.step(TS) != -1
    sup.getFromDef("MOT").getField("maxVelocity").setSFFloat(2.0)
    assert sup.step(TS) != -1
    if restore:
        robot.loadState("__init__")
        assert sup.step(TS) != -1
    motor.setVelocity(5.0)
    motor.setPosition(3.0)
    assert sup.step(TS) != -1
    assert _speed(sup, sensor) == pytest.approx(5.0 if restore else 2.0, rel=1e-2)
    assert motor.getMaxVelocity() == (10.0 if restore else 2.0)
