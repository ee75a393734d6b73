"""A supervisor's write of a Connector's or VacuumGripper's fields at run time. ``isLocked`` and ``isOn`` are the
devices' states (the Connector and VacuumGripper pages: the states lock()/unlock() and turnOn()/turnOff()
change): a write acts as those calls would at the next step (the reference is silent on such writes; this is
the choice the modules' docstrings give). The other fields are read when used: their writes act from the next
step (guards: these pass on the code before the isLocked/isOn change too).

Worlds as in test_connector.py and test_vacuum_gripper.py: a gravity-free robot drifting away from a static
block (free: x = v·t; docked: held at x = 0), and a 1 kg box on a static suction plate pulled up by 20 N
(held: it stays; free: it rises)."""

from __future__ import annotations

import pytest

from tests.support.quiet_worlds import quiet_supervisor

TS = 16
DRIFT = 0.5  # m/s, the robot moving away from the block along -x
START_Z = 0.06  # the box's centre on the plate: plate top at 0.01, half size 0.05


def _docking(active: str = "", a_x: float = 0.0, velocity: float = DRIFT) -> tuple:  # type: ignore[type-arg]
    # the robot's connector faces +x at its origin; the static block's passive connector faces -x at x = 0
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BLOCK Solid {{ translation 0.1 0 0 children [
  Connector {{ translation -0.1 0 0 rotation 0 0 1 3.14159265 name "b" type "passive" }} ] }}
DEF BOT Robot {{ translation {a_x} 0 0 supervisor TRUE
  children [ DEF A Connector {{ name "a" type "active" {active} }} ]
  boundingObject Sphere {{ radius 0.01 }} physics Physics {{ mass 1 }} linearVelocity {-velocity} 0 0 }}
""")
    return sup, sup.getDevice("a"), sup.getFromDef("A")


def _run(sup, steps: int) -> float:  # type: ignore[no-untyped-def]
    for _ in range(steps):
        sup.step(TS)
    return float(sup.getSelf().getPosition()[0])


@pytest.mark.parametrize("write", [True, False])
def test_connector_is_locked_written_true_locks_it(write: bool) -> None:
    # in position at the start: a lock docks at the first step and the joint holds the robot at x = 0; the
    # control drifts 0.5 m/s · 10 · 16 ms = 0.08 m away
    sup, connector, node = _docking()
    if write:
        node.getField("isLocked").setSFBool(True)
    x = _run(sup, 10)
    assert connector.isLocked() is write
    assert x == (pytest.approx(0.0, abs=1e-3) if write else pytest.approx(-DRIFT * 10 * TS / 1000, abs=1e-6))


@pytest.mark.parametrize("write", [True, False])
def test_connector_is_locked_written_false_unlocks_it(write: bool) -> None:
    # docked at load (isLocked TRUE) and held at x = 0; isLocked FALSE written with the robot given 0.5 m/s away:
    # unilateralUnlock (default TRUE) frees it, 10 steps later it is 0.08 m away; the control stays held
    sup, connector, node = _docking("isLocked TRUE", velocity=0.0)
    _run(sup, 2)
    if write:
        node.getField("isLocked").setSFBool(False)
    sup.step(TS)  # the write acts at this step
    sup.getSelf().setVelocity([-DRIFT, 0, 0, 0, 0, 0])
    x = _run(sup, 10)
    assert connector.isLocked() is not write
    assert x == (pytest.approx(-DRIFT * 10 * TS / 1000, abs=1e-3) if write else pytest.approx(0.0, abs=1e-3))
    sup.simulationReset()  # the load's isLocked TRUE again: docked again at the first step after the reset
    sup.step(TS)
    assert connector.isLocked()


@pytest.mark.parametrize("write", [True, False])
def test_connector_distance_tolerance_write_sets_its_presence(write: bool) -> None:
    # 11 mm from the peer: outside the default distanceTolerance 0.01, inside 0.02 (guard: read when used)
    sup, connector, node = _docking(a_x=-0.011, velocity=0.0)
    connector.enablePresence(TS)
    sup.step(TS)
    assert connector.getPresence() == 0
    if write:
        node.getField("distanceTolerance").setSFFloat(0.02)
    sup.step(TS)
    assert connector.getPresence() == (1 if write else 0)


def _gripper(fields: str = "") -> tuple:  # type: ignore[type-arg]
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BOX Solid {{ translation 0 0 {START_Z} boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ mass 1 }} }}
Robot {{ supervisor TRUE children [
  DEF CUP VacuumGripper {{ name "cup" boundingObject Box {{ size 0.3 0.3 0.02 }} {fields} }} ] }}
""")
    for _ in range(10):  # the box settles on the plate
        sup.step(TS)
    return sup, sup.getDevice("cup"), sup.getFromDef("CUP")


def _pull(sup) -> float:  # type: ignore[no-untyped-def]
    # 20 N up on 1 kg against 9.81 N of weight: a free box rises; a held one stays within a millimetre
    box = sup.getFromDef("BOX")
    for _ in range(10):
        box.addForce([0, 0, 20.0], False)
        sup.step(TS)
    return float(box.getPosition()[2]) - START_Z


@pytest.mark.parametrize("write", [True, False])
def test_vacuum_gripper_is_on_written_true_turns_it_on(write: bool) -> None:
    sup, cup, node = _gripper()
    if write:
        node.getField("isOn").setSFBool(True)
    sup.step(TS)  # the box touching the plate is grasped at this step
    assert cup.isOn() is write
    rise = _pull(sup)
    assert abs(rise) < 1e-3 if write else rise > 0.01


@pytest.mark.parametrize("write", [True, False])
def test_vacuum_gripper_is_on_written_false_releases(write: bool) -> None:
    sup, cup, node = _gripper("isOn TRUE")
    if write:
        node.getField("isOn").setSFBool(False)
    sup.step(TS)
    assert cup.isOn() is not write
    rise = _pull(sup)
    assert rise > 0.01 if write else abs(rise) < 1e-3
    sup.simulationReset()  # the load's isOn TRUE again: the box back on the plate is held again
    for _ in range(10):
        sup.step(TS)
    assert cup.isOn()
    assert abs(_pull(sup)) < 1e-3


@pytest.mark.parametrize("write", [True, False])
def test_vacuum_gripper_contact_points_write_acts_at_the_next_grasp(write: bool) -> None:
    # 50 contact points are more than a box face on the plate gives: no grasp; 1 is enough (guard: read when used)
    sup, _, node = _gripper("contactPoints 50 isOn TRUE")
    if write:
        node.getField("contactPoints").setSFInt32(1)
    sup.step(TS)
    rise = _pull(sup)
    assert abs(rise) < 1e-3 if write else rise > 0.01
