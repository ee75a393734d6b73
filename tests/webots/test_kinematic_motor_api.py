"""The Motor API rules of a Track's LinearMotor and a Propeller's RotationalMotor: the same controller-side checks,
clipping and echoes as a joint motor's.

References: D = /work/shared/reference/webots-devices.md (§7 Track, §8 Propeller, §9 "Controller-side checks" and
the raw, unmultiplied cache), O = .../webots-on-ode.md (§5.1 initial state, §5.2 setPosition/setVelocity/
setAvailableTorque). Expected values come from those texts or from hand computation.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 4

TRACK = ('Track {{ translation 0 0 0.2 boundingObject Box {{ size 2 0.4 0.1 }} physics Physics {{ mass 5 }} '
         'device [ LinearMotor {{ name "belt" {motor} }} PositionSensor {{ name "belt sensor" }} ] }}')
PROPELLER = ('Propeller {{ shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0 '
             'device RotationalMotor {{ name "prop" {motor} }} }}')


def _sup(track: str | None = "", propeller: str = "") -> Supervisor:
    """A 1 kg robot with a Propeller and (unless ``track`` is None) a Track, their motors' extra fields given."""
    belt = "" if track is None else TRACK.format(motor=track)
    text = (f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n"
            "DEF DRONE Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
            f"children [ {belt} {PROPELLER.format(motor=propeller)} ] }}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        sup.step(TS)


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_negative_velocity_is_refused_in_position_control(name: str, capfd: pytest.CaptureFixture[str]) -> None:
    # D §9: "negative velocity rejected while the commanded motor is in position control" (libController's error);
    # O §5.1: the initial state is position control with target velocity maxVelocity (10)
    motor = _sup().getDevice(name)
    capfd.readouterr()
    motor.setVelocity(-2.0)
    err = capfd.readouterr().err
    assert err.startswith("Error: wb_motor_set_velocity() called with a negative velocity")
    assert motor.getVelocity() == 10.0


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_negative_velocity_is_accepted_in_velocity_control(name: str, capfd: pytest.CaptureFixture[str]) -> None:
    # D §9: the refusal is for position control only (setPosition(inf) is velocity control)
    motor = _sup().getDevice(name)
    motor.setPosition(math.inf)
    capfd.readouterr()
    motor.setVelocity(-2.0)
    assert motor.getVelocity() == -2.0 and capfd.readouterr().err == ""


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_negative_acceleration_other_than_minus_one_is_refused(name: str,
                                                               capfd: pytest.CaptureFixture[str]) -> None:
    # D §9: "negative acceleration (≠ −1) ... rejected"; -1 means unlimited
    motor = _sup().getDevice(name)
    motor.setAcceleration(4.0)
    capfd.readouterr()
    motor.setAcceleration(-5.0)
    assert capfd.readouterr().err.startswith("Error: wb_motor_set_acceleration() called with a negative acceleration")
    assert motor.getAcceleration() == 4.0
    motor.setAcceleration(-1.0)
    assert motor.getAcceleration() == -1.0


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_targets_echo_the_raw_value_not_the_multiplied_one(name: str) -> None:
    # D §9: the commanded motor's cache holds the raw, unmultiplied value (Webots applies p·m, v·m)
    motor = _sup(track="multiplier 2", propeller="multiplier 2").getDevice(name)
    motor.setPosition(1.5)
    assert motor.getTargetPosition() == 1.5
    motor.setPosition(math.inf)
    motor.setVelocity(3.0)
    assert motor.getVelocity() == 3.0 and motor.getMultiplier() == 2.0


def test_track_multiplier_still_scales_the_belt_speed() -> None:
    # D §9: Webots' target velocity is v·m: 0.125 m/s × 2 = 0.25 m/s; D §7.2 trackPos += v·dt: 0.05 m in 0.2 s
    sup = _sup(track="multiplier 2")
    sensor, motor = sup.getDevice("belt sensor"), sup.getDevice("belt")
    sensor.enable(TS)
    motor.setPosition(math.inf)
    motor.setVelocity(0.125)
    _steps(sup, 50)
    assert sensor.getValue() == pytest.approx(0.05, rel=1e-6)


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_set_position_is_clipped_into_the_limits(name: str, capfd: pytest.CaptureFixture[str]) -> None:
    # O §5.2: "If minPosition ≠ maxPosition and p finite, clamp into [minPosition, maxPosition] (warning)"; the
    # echo is then the clipped target in the motor's own units (multiplier 1 here)
    motor = _sup(track="minPosition -1 maxPosition 1", propeller="minPosition -1 maxPosition 1").getDevice(name)
    capfd.readouterr()
    motor.setPosition(5.0)
    assert motor.getTargetPosition() == 1.0 and capfd.readouterr().err != ""
    assert motor.getMinPosition() == -1.0 and motor.getMaxPosition() == 1.0


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_nan_and_negative_available_force_are_refused_with_a_message(name: str,
                                                                      capfd: pytest.CaptureFixture[str]) -> None:
    # D §9: "NaN position/velocity/force rejected ...; negative available force rejected"
    motor = _sup().getDevice(name)
    capfd.readouterr()
    motor.setAvailableForce(-1.0)
    assert capfd.readouterr().err != "" and motor.getAvailableForce() == 10.0
    motor.setPosition(math.nan)
    assert capfd.readouterr().err != "" and motor.getTargetPosition() == 0.0


def test_propeller_available_torque_is_capped_at_max_torque() -> None:
    # R (webots-python-api.md, Motor) setAvailableTorque "<= maxTorque"; O §5.2 available = min(f, maxTorque)
    motor = _sup().getDevice("prop")
    motor.setAvailableTorque(50.0)
    assert motor.getAvailableTorque() == 10.0 and motor.getMaxTorque() == 10.0
    motor.setAvailableTorque(2.0)
    assert motor.getAvailableTorque() == 2.0 and motor.getMaxTorque() == 10.0


def test_propeller_starts_with_target_velocity_max_velocity() -> None:
    # O §5.1: initial target velocity = maxVelocity, so setPosition alone spins the propeller (D §8: position
    # mode moves the angle toward the target, ω ≥ 0). maxVelocity 100, maxTorque 1000 (spin-up 1000 rad/s²:
    # 100 rad/s after 0.1 s); then T = 1e-4·100² = 1 N along z on 1 kg for 0.5 s: Δv_z = 0.5 m/s (the target
    # 1e6 rad is far from the ~50 rad travelled)
    sup = _sup(track=None, propeller="maxVelocity 100 maxTorque 1000")
    prop = sup.getDevice("prop")
    assert prop.getVelocity() == 100.0
    prop.setPosition(1e6)
    _steps(sup, 30)
    drone = sup.getFromDef("DRONE")
    v0 = drone.getVelocity()
    _steps(sup, 125)
    assert drone.getVelocity()[2] - v0[2] == pytest.approx(0.5, rel=1e-3)
