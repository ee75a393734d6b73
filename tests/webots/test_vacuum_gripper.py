"""VacuumGripper: a 1 kg box rests on a static suction plate and is pulled up by 20 N; it stays only while the
gripper holds it (on, enough contact points, strength above the net 10.19 N pull)."""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 16
START_Z = 0.06  # box centre: plate top at 0.01, half size 0.05


def _world(gripper: str = "") -> Supervisor:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BOX Solid {{ translation 0 0 {START_Z} boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ mass 1 }} }}
Robot {{ supervisor TRUE children [
  VacuumGripper {{ name "cup" boundingObject Box {{ size 0.3 0.3 0.02 }} {gripper} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _settle(sup: Supervisor, steps: int = 10) -> None:
    for _ in range(steps):
        sup.step(TS)


def _pull(sup: Supervisor, steps: int = 10) -> float:
    box = sup.getFromDef("BOX")
    for _ in range(steps):
        box.addForce([0, 0, 20.0], False)
        sup.step(TS)
    return float(box.getPosition()[2]) - START_Z


def test_off_the_box_is_pulled_away() -> None:
    sup = _world()
    _settle(sup)
    assert _pull(sup) > 0.01  # control: nothing holds it


def test_on_it_holds_and_reports_presence_then_releases() -> None:
    sup = _world()
    cup = sup.getDevice("cup")
    cup.enablePresence(TS)
    cup.turnOn()
    assert cup.isOn() and cup.on
    _settle(sup)
    assert cup.getPresence() is True
    assert abs(_pull(sup)) < 1e-3
    cup.turnOff()
    assert _pull(sup) > 0.01
    assert cup.getPresence() is False


def test_is_on_in_the_world_file() -> None:
    sup = _world("isOn TRUE")
    _settle(sup)
    assert abs(_pull(sup)) < 1e-3


@pytest.mark.parametrize(("points", "holds"), [(1, True), (50, False)])
def test_contact_points_needed_to_grasp(points: int, holds: bool) -> None:
    sup = _world(f"isOn TRUE contactPoints {points}")  # a box face on the plate gives a handful of points
    _settle(sup)
    assert (abs(_pull(sup)) < 1e-3) is holds


@pytest.mark.parametrize(("strength", "holds"), [(15.0, True), (5.0, False)])
def test_tensile_strength(strength: float, holds: bool) -> None:
    sup = _world(f"isOn TRUE tensileStrength {strength}")
    cup = sup.getDevice("cup")
    cup.enablePresence(TS)
    _settle(sup)
    lift = _pull(sup)
    assert (abs(lift) < 1e-3) is holds
    assert cup.getPresence() is holds
