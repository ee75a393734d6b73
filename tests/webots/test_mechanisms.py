"""Mechanisms: coupled motors ('name::suffix'), and later propellers, tracks and closed loops."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation


def _sup(body: str, step: int = 4) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {step} gravity 0 }}\n{body}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _arm(name: str, multiplier: float, y: float) -> str:
    return f"""HingeJoint {{
  jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 {y} 0 }}
  device [ RotationalMotor {{ name "{name}" multiplier {multiplier} maxVelocity 5 maxTorque 50 }}
           PositionSensor {{ name "{name} sensor" }} ]
  endPoint Solid {{ translation 0.1 {y} 0 boundingObject Box {{ size 0.2 0.02 0.02 }} physics Physics {{ }} }}
}}"""


COUPLED = (
    "Robot { supervisor TRUE children [ "
    + _arm("gripper::left", 1.0, 0.2)
    + _arm("gripper::right", -2.0, -0.2)
    + _arm("other", 1.0, 0.6)
    + " ] }"
)


def _sensors(sup: Supervisor, names: list[str]) -> list:
    devs = [sup.getDevice(f"{n} sensor") for n in names]
    for d in devs:
        d.enable(4)
    return devs


def test_coupled_motors_follow_position_with_their_multipliers() -> None:
    sup = _sup(COUPLED)
    left, right, other = _sensors(sup, ["gripper::left", "gripper::right", "other"])
    sup.getDevice("gripper::left").setPosition(0.3)
    for _ in range(500):
        sup.step(4)
    assert left.getValue() == pytest.approx(0.3, abs=1e-3)
    assert right.getValue() == pytest.approx(-0.6, abs=1e-3)
    assert other.getValue() == pytest.approx(0.0, abs=1e-6)  # not a sibling
    # the sibling's controller-side target changed too (raw value times its own multiplier)
    assert sup.getDevice("gripper::right").getTargetPosition() == pytest.approx(-0.6)


def test_coupled_motors_relay_velocity_and_torque() -> None:
    sup = _sup(COUPLED)
    left, right = _sensors(sup, ["gripper::left", "gripper::right"])
    motor = sup.getDevice("gripper::right")  # commanding either motor moves both
    motor.setPosition(math.inf)
    motor.setVelocity(0.5)
    for _ in range(50):
        sup.step(4)
    a0, b0 = left.getValue(), right.getValue()
    for _ in range(100):
        sup.step(4)
    assert (left.getValue() - a0) / 0.4 == pytest.approx(0.5, rel=1e-3)
    assert (right.getValue() - b0) / 0.4 == pytest.approx(-1.0, rel=1e-3)
    sup.getDevice("gripper::left").setTorque(0.0)
    assert all(sup.getDevice(n)._record.torque_mode for n in ("gripper::left", "gripper::right"))
    assert not sup.getDevice("other")._record.torque_mode
