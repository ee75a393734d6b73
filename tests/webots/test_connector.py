"""Connector: presence (compatibility and the three tolerances), lock/unlock with a fixed joint, autoLock,
and the joint breaking at tensileStrength. Gravity-free worlds: a docked body keeps its distance, a free one
drifts with its initial velocity, so every expectation follows from the lock state alone."""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 16


def _world(active: str = "", passive: str = "", a_type: str = "active", b_type: str = "passive",
           a_x: float = 0.0, velocity: float = 0.0, robot: str = "") -> Supervisor:  # fmt: skip
    # the robot's connector faces +x at its origin; the static block's connector faces -x at x=0 (rotated π about z)
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BLOCK Solid {{ translation 0.1 0 0 children [
  Connector {{ translation -0.1 0 0 rotation 0 0 1 3.14159265 name "b" type "{b_type}" {passive} }} ] }}
DEF BOT Robot {{ translation {a_x} 0 0 supervisor TRUE {robot}
  children [ Connector {{ name "a" type "{a_type}" {active} }} ]
  boundingObject Sphere {{ radius 0.01 }} physics Physics {{ mass 1 }} linearVelocity {-velocity} 0 0 }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _presence(sup: Supervisor) -> int:
    c = sup.getDevice("a")
    c.enablePresence(TS)
    sup.step(TS)
    return int(c.getPresence())


def test_presence_needs_a_compatible_peer_in_position() -> None:
    assert _presence(_world()) == 1
    assert _presence(_world(b_type="active")) == 0  # two active connectors never dock
    assert _presence(_world(a_type="symmetric", b_type="symmetric")) == 1
    assert _presence(_world(passive='model "other"')) == 0  # models differ
    assert _presence(_world(a_x=-0.009)) == 1  # 9 mm < distanceTolerance 0.01
    assert _presence(_world(a_x=-0.011)) == 0
    # docking axes 0.15 rad apart: inside axisTolerance 0.2, outside 0.1
    assert _presence(_world(active="rotation 0 0 1 0.15")) == 1
    assert _presence(_world(active="rotation 0 0 1 0.15 axisTolerance 0.1")) == 0
    # a quarter turn about the docking axis matches one of 4 rotations, not one of 3
    assert _presence(_world(active="rotation 1 0 0 1.5707963")) == 1
    assert _presence(_world(active="rotation 1 0 0 1.5707963 numberOfRotations 3")) == 0


def test_passive_connector_has_no_presence_sensor() -> None:
    sup = _world(a_type="passive", b_type="active")
    c = sup.getDevice("a")
    c.enablePresence(TS)
    assert c.getPresenceSamplingPeriod() == c.presence_sampling_period == TS
    sup.step(TS)
    assert c.getPresence() == -1  # Webots: "not applicable" for a passive connector
    assert _presence(_world()) == 1  # control: the active side of the same pair reads 1


def _run(sup: Supervisor, steps: int) -> float:
    for _ in range(steps):
        sup.step(TS)
    return float(sup.getSelf().getPosition()[0])


def test_lock_holds_the_robot_and_unlock_frees_it() -> None:
    free = _world(velocity=0.5)
    assert _run(free, 10) == pytest.approx(-0.5 * 10 * TS / 1000, abs=1e-6)  # control: drifts away
    sup = _world(velocity=0.5)
    c = sup.getDevice("a")
    c.lock()
    assert c.isLocked() and c.locked
    assert _run(sup, 10) == pytest.approx(0.0, abs=1e-3)  # the fixed joint from the first step holds it
    c.unlock()
    assert not c.isLocked()
    sup.getSelf().setVelocity([-0.5, 0, 0, 0, 0, 0])
    assert _run(sup, 10) < -0.05


def test_lock_out_of_position_needs_auto_lock() -> None:
    # the robot starts 5 cm away and approaches at 0.5 m/s: in position after ~0.1 s
    sup = _world(a_x=-0.05, velocity=-0.5)
    sup.getDevice("a").lock()
    assert _run(sup, 20) > 0.05  # lock() alone found no peer in position: it passes through
    auto = _world(active="autoLock TRUE", a_x=-0.05, velocity=-0.5)
    auto.getDevice("a").lock()
    assert abs(_run(auto, 20)) < 0.011  # docked within the distance tolerance and held there


def test_is_locked_in_the_world_file_docks_at_load() -> None:
    assert _run(_world(active="isLocked TRUE", velocity=0.5), 10) == pytest.approx(0.0, abs=1e-3)


def test_tensile_strength_breaks_the_joint() -> None:
    def pulled(strength: float) -> tuple[float, bool, int]:
        sup = _world(active=f"tensileStrength {strength}")
        c = sup.getDevice("a")
        c.enablePresence(TS)
        c.lock()
        sup.step(TS)
        for _ in range(10):
            sup.getSelf().addForce([-2.0, 0, 0], False)  # 2 N pulling the robot off the block
            sup.step(TS)
        return float(sup.getSelf().getPosition()[0]), c.isLocked(), c.getPresence()

    x, locked, presence = pulled(5.0)  # 2 N < 5 N: holds
    assert x == pytest.approx(0.0, abs=1e-3) and locked and presence == 1
    x, locked, presence = pulled(1.0)  # 2 N > 1 N: breaks, both unlock, the robot accelerates away
    assert x < -0.005 and not locked and presence == 0


def test_both_locked_sides_add_their_strengths() -> None:
    # two symmetric connectors of 1.5 N each: one locked holds 1.5 N (a 2 N pull breaks it), both locked 3 N
    def pulled(lock_both: bool) -> bool:
        sup = _world(active="tensileStrength 1.5", passive=f"tensileStrength 1.5 isLocked {'TRUE' if lock_both else 'FALSE'}",
                     a_type="symmetric", b_type="symmetric")  # fmt: skip
        c = sup.getDevice("a")
        c.lock()
        sup.step(TS)
        for _ in range(10):
            sup.getSelf().addForce([-2.0, 0, 0], False)
            sup.step(TS)
        return c.isLocked()

    assert pulled(lock_both=True)
    assert not pulled(lock_both=False)


@pytest.mark.parametrize("snap", [True, False])
def test_snap_aligns_the_robot_on_docking(snap: bool) -> None:
    # 8 mm off sideways and turned 0.1 rad about z: in position (tolerances 0.01 m, 0.2 rad) but not aligned
    sup = _world(active=f"snap {'TRUE' if snap else 'FALSE'}", robot="translation 0 0.008 0 rotation 0 0 1 0.1")
    sup.getDevice("a").lock()
    sup.step(TS)
    me = sup.getSelf()
    y = me.getPosition()[1]
    heading = me.getOrientation()[3]  # R[1][0] = sin(yaw)
    if snap:  # moved onto the block's connector: origin at 0, x axis along +x
        assert y == pytest.approx(0.0, abs=1e-6) and heading == pytest.approx(0.0, abs=1e-6)
    else:  # control: docked where it stood
        assert y == pytest.approx(0.008, abs=1e-6) and heading == pytest.approx(0.0998, abs=1e-3)


def test_simulation_reset_undocks() -> None:
    sup = _world(velocity=0.5)
    c = sup.getDevice("a")
    c.lock()
    _run(sup, 5)
    assert c.isLocked()
    sup.simulationReset()
    sup.step(TS)  # the reset step: back to the load state, unlocked as in the world file
    assert not c.isLocked()
    assert _run(sup, 10) < -0.05  # nothing holds the robot any more: it drifts with its initial velocity
