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
from dualtwin.webots.controller import Motor, PositionSensor, Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.quiet_worlds import quiet_supervisor

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
    return quiet_supervisor(text)


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


# ------------------------------------------------------------------------------------------ one Motor class


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_track_and_propeller_motors_are_motors(name: str) -> None:
    # R (webots-python-api.md, Shared semantics): "Robot() builds one object per device (both motor node types
    # become Motor)"; R Motor: the properties mirror the getters
    motor = _sup().getDevice(name)
    assert isinstance(motor, Motor)
    assert motor.max_velocity == motor.getMaxVelocity() == 10.0
    motor.target_velocity = 4.0  # a settable property: setVelocity
    assert motor.getVelocity() == 4.0 and motor.target_velocity == 4.0


def test_a_motor_built_by_name_is_the_track_motor() -> None:
    # R Motor: __init__(name); one device, one state whichever handle commands it
    sup = _sup()
    built = Motor("belt")
    built.setVelocity(3.0)
    assert sup.getDevice("belt").getVelocity() == 3.0 and built.getMaxForce() == 10.0
    # R Sensor __init__: built from a name string it enables itself (at the basic time step)
    sensor = PositionSensor("belt sensor")
    assert sensor.getType() == 1 and sup.getDevice("belt sensor").getSamplingPeriod() == TS


def test_track_devices_link_to_each_other() -> None:
    # D §7.1: a Track's device field holds its LinearMotor, a PositionSensor and a Brake; R Motor getBrake/
    # getPositionSensor, PositionSensor getMotor/getBrake, Brake getMotor/getPositionSensor: the sibling devices
    sup = _belt("Brake { name \"belt brake\" }")
    motor = sup.getDevice("belt")
    assert motor.getPositionSensor().getName() == "belt sensor" and motor.getBrake().getName() == "belt brake"
    sensor, brake = sup.getDevice("belt sensor"), sup.getDevice("belt brake")
    assert sensor.getMotor().getName() == "belt" and sensor.getBrake().getName() == "belt brake"
    assert brake.getMotor().getName() == "belt" and brake.getPositionSensor().getName() == "belt sensor"
    assert sensor.getType() == brake.getType() == motor.getType() == 1  # LINEAR
    prop = _sup().getDevice("prop")
    assert prop.getBrake() is None and prop.getPositionSensor() is None


# ------------------------------------------------------------------------------------------ §7 Track facts


def _belt(extra: str = "", physics: bool = True, robot: str = "") -> Supervisor:
    """A robot without Physics holding a 5 kg Track (its own body), or a Track without Physics."""
    phys = "physics Physics { mass 5 }" if physics else ""
    text = (f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n"
            f"Robot {{ supervisor TRUE {robot} children [ Track {{ translation 0 0 0.2 boundingObject Box {{ size 2 0.4 "
            f'0.1 }} {phys} device [ LinearMotor {{ name "belt" }} PositionSensor {{ name "belt sensor" }} '
            f"{extra} ] }} ] }}\n")
    return quiet_supervisor(text)


def test_track_without_a_body_does_not_move_its_belt() -> None:
    # D §7.2: "no motor (or no body) ⇒ v = 0"; the same command on a 5 kg Track moves it 0.25·0.2 = 0.05 m
    for physics, travel in ((False, 0.0), (True, 0.05)):
        sup = _belt(physics=physics)
        sensor, motor = sup.getDevice("belt sensor"), sup.getDevice("belt")
        sensor.enable(TS)
        motor.setPosition(math.inf)
        motor.setVelocity(0.25)
        _steps(sup, 50)
        assert sensor.getValue() == pytest.approx(travel, abs=1e-12)


def _force_travel(damping: float | None, steps: int) -> float:
    sup = _belt('Brake { name "belt brake" }')
    sensor, motor = sup.getDevice("belt sensor"), sup.getDevice("belt")
    sensor.enable(TS)
    if damping is not None:
        sup.getDevice("belt brake").setDampingConstant(damping)
    motor.setForce(10.0)
    _steps(sup, steps)
    return float(sensor.getValue())


def test_track_brake_damps_the_belt_in_force_control() -> None:
    # D §7.2: force control "v = (F − brakeDamping·v_prev)·dt / m_body" (not integrated) and trackPos += v·dt.
    # F = 10 N (= maxForce), m = 5 kg, dt = 0.004 s; by hand: without damping v = 0.008 m/s every step
    assert _force_travel(None, 50) == pytest.approx(50 * 0.008 * 0.004, rel=1e-9)
    v = travel = 0.0
    for _ in range(50):
        v = (10.0 - 100.0 * v) * 0.004 / 5.0
        travel += v * 0.004
    assert travel < 50 * 0.008 * 0.004
    assert _force_travel(100.0, 50) == pytest.approx(travel, rel=1e-9)


def test_track_motor_force_feedback_is_not_available(capfd: pytest.CaptureFixture[str]) -> None:
    # D §7.2: "Force feedback is not available for Track motors": the Motor API's feedback calls exist (R Motor)
    # but give no value (NaN: what libController holds before any sample, D §0.2)
    sup = _belt()
    motor = sup.getDevice("belt")
    capfd.readouterr()
    motor.enableForceFeedback(TS)
    assert capfd.readouterr().err != ""  # a warning that there is none
    assert motor.getForceFeedbackSamplingPeriod() == TS
    motor.setForce(5.0)
    _steps(sup, 5)
    assert math.isnan(motor.getForceFeedback())


def test_track_motor_consumes_no_energy() -> None:
    # D §7.2: "energy consumption 0": a robot's battery [100 100 0] with cpuConsumption 10 W loses only
    # 10·0.2 = 2 J in 0.2 s while its Track motor pushes with its full 10 N
    sup = _belt(robot="battery [ 100 100 0 ] cpuConsumption 10")
    sup.batterySensorEnable(TS)
    sup.getDevice("belt").setForce(10.0)
    _steps(sup, 50)
    assert sup.batterySensorGetValue() == pytest.approx(98.0, rel=1e-9)


def test_track_position_sensor_read_while_disabled_is_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # D §0.2: reading a disabled device prints "Error: ... called for a disabled device!" and returns the cache
    sensor = _belt().getDevice("belt sensor")
    capfd.readouterr()
    assert math.isnan(sensor.getValue())
    assert capfd.readouterr().err.startswith("Error: ")


# ------------------------------------------------------------------------------------------ §8 Propeller facts


def _propeller_warnings(robot_physics: str) -> list[str]:
    text = (f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n"
            f"Robot {{ supervisor TRUE {robot_physics} children [ {PROPELLER.format(motor='')} ] }}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
        Supervisor(simulation=sim, robot_node=sim.robots[0].node)  # the propellers are installed with it
    return [w for w in sim.build_warnings if "Propeller" in w]


def test_propeller_without_physics_upstream_warns() -> None:
    # D §8: "No Physics upstream ⇒ warning, no effect"; with a body above it, no such warning
    assert len(_propeller_warnings("")) == 1
    assert _propeller_warnings("boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 }") == []


@pytest.mark.parametrize("name", ["belt", "prop"])
def test_multiplier_zero_is_reset_to_one_with_a_warning(name: str) -> None:
    # D §9: "multiplier (default 1; 0 → reset to 1 with warning)"
    text = (f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n"
            "Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
            f"children [ {TRACK.format(motor='multiplier 0')} {PROPELLER.format(motor='multiplier 0')} ] }}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
        sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    assert sup.getDevice(name).getMultiplier() == 1.0
    assert sum(f"'{name}'" in w and "multiplier" in w for w in sim.build_warnings) == 1


@pytest.mark.parametrize("name, sensor_reading", [("belt", "belt sensor"), ("prop", None)])
def test_simulation_reset_restores_the_acceleration_field(name: str, sensor_reading: str | None) -> None:
    # O §5.2: setAcceleration replaces the motor's acceleration field; D §11.3 lists the motors' acceleration among
    # what simulationReset resets, as for a joint's motor. Loaded unlimited (-1): after the reset a velocity command
    # is reached in one step again. With the 0.5 m/s² (rad/s²) set before the reset kept, the first step would
    # reach only 0.5·0.004 = 0.002.
    sup = _sup()
    motor = sup.getDevice(name)
    motor.setAcceleration(0.5)
    sup.simulationReset()
    sup.step(TS)
    assert motor.getAcceleration() == -1.0
    motor.setPosition(math.inf)
    motor.setVelocity(2.0)
    if sensor_reading is not None:  # the belt travels v·dt in its first step: 2·0.004
        sensor = sup.getDevice(sensor_reading)
        sensor.enable(TS)
        sup.step(TS)
        before = sensor.getValue()
        sup.step(TS)
        assert sensor.getValue() - before == pytest.approx(2.0 * TS / 1000.0, abs=1e-12)
