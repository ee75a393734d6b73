"""The documented behaviours (the "notes" column, the QUIRKs and "Shared semantics") of Webots R2023b's Robot,
joint devices (Motor, PositionSensor, Brake), Connector, TouchSensor, VacuumGripper and the battery sensor, one
small test each. References: R = /work/shared/reference/webots-python-api.md, D = .../webots-devices.md,
O = .../webots-on-ode.md (line numbers as of this writing). Emitter/Receiver, Keyboard, Mouse and Motion are in
test_device_notes_actuators2.py."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world, load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation

TS = 8

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 gravity 0 }
Robot {
  name "bot" model "tester" customData "hello" synchronization FALSE
  battery [ 100 100 0 ]
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 }
      device [ RotationalMotor { name "m" maxTorque 5 maxVelocity 10 } PositionSensor { name "s" } Brake { name "b" } ]
      endPoint Solid { translation 0.2 0 0 name "arm" boundingObject Sphere { radius 0.05 } physics Physics { mass 1 } }
    }
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 anchor 0 1 0 }
      device [ RotationalMotor { name "lim" minPosition -1 maxPosition 1 } ]
      endPoint Solid { translation 0.2 1 0 name "arm2" boundingObject Sphere { radius 0.05 } physics Physics { mass 1 } }
    }
    SliderJoint {
      jointParameters JointParameters { axis 1 0 0 }
      device [ LinearMotor { name "lin" } PositionSensor { name "ls" } ]
      endPoint Solid { translation 0 -1 0 name "slide" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } }
    }
    TouchSensor { translation 0 0 -3 name "touch" }
    Connector { translation 0 0 -4 name "con" }
    VacuumGripper { translation 0 0 -5 name "cup" }
  ]
}
"""


def _robot(world: str = WORLD) -> Robot:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(world))
    return Robot(simulation=sim, robot_node=sim.robots[0].node)


def _steps(robot: Robot, n: int) -> None:
    for _ in range(n):
        assert robot.step(TS) == 0


# ------------------------------------------------------------------ Sensor shared semantics


def test_enable_t_then_step_t_already_gives_a_value() -> None:
    # R:35 "enable(T) then step(T) already gives a value. Until then the value is NaN"
    robot = _robot()
    s = robot.getDevice("s")
    s.enable(TS)
    assert math.isnan(s.getValue())
    robot.step(TS)
    assert s.getValue() == pytest.approx(0.0, abs=1e-9)


def test_first_value_arrives_at_the_first_step_that_covers_the_period() -> None:
    # R:34 "The first value arrives at the first step() that covers p"
    robot = _robot()
    s = robot.getDevice("s")
    s.enable(2 * TS)
    robot.step(TS)
    assert math.isnan(s.getValue())
    robot.step(TS)
    assert math.isfinite(s.getValue())


def test_enable_zero_disables() -> None:
    # R:35-36 "p = 0 disables"; D:29 "enable(0) ≡ disable()"
    robot = _robot()
    s = robot.getDevice("s")
    s.enable(TS)
    s.enable(0)
    assert s.getSamplingPeriod() == 0


def test_enable_with_a_negative_period_is_an_error_and_ignored(capfd: pytest.CaptureFixture[str]) -> None:
    # D:29 "`enable(p<0)` → error, ignored"
    robot = _robot()
    s = robot.getDevice("s")
    s.enable(TS)
    capfd.readouterr()
    s.enable(-5)
    assert s.getSamplingPeriod() == TS and "Error:" in capfd.readouterr().err


def test_sampling_period_property_none_disables() -> None:
    # R:300 Sensor "sampling_period (setter enables (None = 0 = disable))"
    robot = _robot()
    s = robot.getDevice("s")
    s.sampling_period = 16
    assert s.getSamplingPeriod() == 16
    s.sampling_period = None
    assert s.getSamplingPeriod() == 0


def test_reading_a_never_sampled_disabled_sensor_prints_an_error_and_returns_nan(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 "Reading a disabled sensor prints an error on stderr and returns the last cached value (NaN if it
    # never sampled). It never raises."; D:27 "prints `Error: ... called for a disabled device! ...`"
    robot = _robot()
    capfd.readouterr()
    assert math.isnan(robot.getDevice("s").getValue())
    err = capfd.readouterr().err
    assert "Error:" in err and "called for a disabled device" in err


def test_reading_a_disabled_sensor_returns_its_last_value_with_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 "returns the last cached value"; R:306 disable: "readings keep their last value (stderr error on read)"
    robot = _robot()
    motor, s = robot.getDevice("m"), robot.getDevice("s")
    s.enable(TS)
    motor.setPosition(0.5)
    _steps(robot, 100)
    last = s.getValue()
    s.disable()
    motor.setPosition(-0.5)
    _steps(robot, 100)
    capfd.readouterr()
    assert s.getValue() == last
    assert "called for a disabled device" in capfd.readouterr().err


def test_a_disabled_touch_sensor_read_prints_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 shared semantics; D:26-27 (touch is one of the NaN-initialised devices)
    robot = _robot()
    capfd.readouterr()
    assert math.isnan(robot.getDevice("touch").getValue())
    assert "called for a disabled device" in capfd.readouterr().err


def test_a_disabled_force_feedback_read_prints_an_error_and_returns_nan(capfd: pytest.CaptureFixture[str]) -> None:
    # R:346/350 getForceFeedback/getTorqueFeedback "NaN until sampled"; D:26 (motor force feedback cached NaN) and
    # D:27 (disabled read: error, cached value)
    robot = _robot()
    motor = robot.getDevice("m")
    capfd.readouterr()
    assert math.isnan(motor.getTorqueFeedback()) and math.isnan(motor.getForceFeedback())
    assert capfd.readouterr().err.count("called for a disabled device") == 2


def test_force_feedback_is_nan_until_sampled_then_a_number() -> None:
    # R:350 "torque applied (N*m); NaN until sampled"
    robot = _robot()
    motor = robot.getDevice("m")
    motor.enableTorqueFeedback(TS)
    assert motor.getTorqueFeedbackSamplingPeriod() == TS and math.isnan(motor.getTorqueFeedback())
    robot.step(TS)
    assert math.isfinite(motor.getTorqueFeedback())


def test_a_disabled_connector_presence_read_prints_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 shared semantics (Connector's presence is sampled: enablePresence/getPresenceSamplingPeriod, R:415-418)
    robot = _robot()
    capfd.readouterr()
    robot.getDevice("con").getPresence()
    assert "called for a disabled device" in capfd.readouterr().err


def test_connector_presence_is_zero_without_a_peer_once_sampled() -> None:
    # R:417 getPresence "1 if a compatible connector is in docking range, else 0"
    robot = _robot()
    con = robot.getDevice("con")
    con.enablePresence(TS)
    robot.step(TS)
    assert con.getPresence() == 0 and con.getPresenceSamplingPeriod() == TS and con.isLocked() is False


def test_a_disabled_vacuum_gripper_presence_read_prints_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 shared semantics (VacuumGripper's presence is sampled, R:814-817)
    robot = _robot()
    capfd.readouterr()
    robot.getDevice("cup").getPresence()
    assert "called for a disabled device" in capfd.readouterr().err


# ------------------------------------------------------------------ Motor


def test_get_velocity_is_the_target_velocity_not_a_measurement() -> None:
    # R:335 getVelocity "the TARGET velocity set, not a measurement"
    robot = _robot()
    motor = robot.getDevice("m")
    motor.setVelocity(3.0)  # position control at the current position: the joint does not move
    _steps(robot, 10)
    assert motor.getVelocity() == 3.0


def test_min_and_max_position_zero_mean_no_limit() -> None:
    # R:333 getMinPosition "0 with maxPosition 0 = no limit"; O:429 clamp only "If minPosition ≠ maxPosition"
    robot = _robot()
    motor = robot.getDevice("m")
    assert motor.getMinPosition() == 0.0 and motor.getMaxPosition() == 0.0
    motor.setPosition(5.0)
    assert motor.getTargetPosition() == 5.0


def test_set_position_is_clamped_into_the_limits(capfd: pytest.CaptureFixture[str]) -> None:
    # O:429-430 "If minPosition ≠ maxPosition and p finite, clamp into [minPosition, maxPosition] (warning)"
    robot = _robot()
    motor = robot.getDevice("lim")
    capfd.readouterr()
    motor.setPosition(3.0)
    assert motor.getTargetPosition() == 1.0
    assert capfd.readouterr().err != ""
    motor.setPosition(float("inf"))  # R:324 "float('inf') = velocity control": not clamped
    assert motor.getTargetPosition() == math.inf


def test_set_available_force_above_max_force_gives_max_force() -> None:
    # R:327 setAvailableForce "<= maxForce"; O:433 "available = min(f, maxTorque/maxForce)"
    robot = _robot()
    motor = robot.getDevice("m")
    motor.setAvailableTorque(50.0)
    assert motor.getAvailableTorque() == motor.getMaxTorque() == 5.0
    motor.setAvailableTorque(2.0)
    assert motor.getAvailableForce() == 2.0


def test_negative_available_force_is_rejected(capfd: pytest.CaptureFixture[str]) -> None:
    # D:354-355 "negative available force rejected"
    robot = _robot()
    motor = robot.getDevice("m")
    capfd.readouterr()
    motor.setAvailableForce(-1.0)
    assert motor.getAvailableForce() == 5.0 and capfd.readouterr().err != ""


def test_negative_velocity_is_rejected_in_position_control(capfd: pytest.CaptureFixture[str]) -> None:
    # D:354-355 "negative velocity rejected while the commanded motor is in position control"
    robot = _robot()
    motor = robot.getDevice("m")
    motor.setPosition(1.0)
    capfd.readouterr()
    motor.setVelocity(-2.0)
    assert motor.getVelocity() == 10.0  # the initial target velocity is maxVelocity (O:422)
    assert capfd.readouterr().err != ""


def test_negative_velocity_is_accepted_in_velocity_control() -> None:
    # D:354 the rejection is for position control only; R:325 setVelocity: "target velocity" in velocity control
    robot = _robot()
    s, motor = robot.getDevice("s"), robot.getDevice("m")
    s.enable(TS)
    motor.setPosition(float("inf"))
    motor.setVelocity(-2.0)
    _steps(robot, 20)
    assert motor.getVelocity() == -2.0 and s.getValue() < -0.1


def test_negative_acceleration_other_than_minus_one_is_rejected(capfd: pytest.CaptureFixture[str]) -> None:
    # D:355 "negative acceleration (≠ −1) ... rejected"; R:326 setAcceleration "-1 = unlimited"
    robot = _robot()
    motor = robot.getDevice("m")
    motor.setAcceleration(4.0)
    capfd.readouterr()
    motor.setAcceleration(-5.0)
    assert motor.getAcceleration() == 4.0 and capfd.readouterr().err != ""
    motor.setAcceleration(-1.0)
    assert motor.getAcceleration() == -1.0


def test_set_torque_is_torque_control_until_the_next_set_position() -> None:
    # R:330 setForce "torque/force control until next setPosition"; O:430 setPosition "Leaves torque mode"
    robot = _robot()
    s, motor = robot.getDevice("s"), robot.getDevice("m")
    s.enable(TS)
    motor.setTorque(1.0)
    _steps(robot, 50)
    assert s.getValue() > 1.0  # pushed away from 0
    motor.setPosition(0.0)
    _steps(robot, 300)
    assert s.getValue() == pytest.approx(0.0, abs=1e-2)


def _angle_after_torque(available: float, torque: float) -> float:
    robot = _robot()
    s, motor = robot.getDevice("s"), robot.getDevice("m")
    s.enable(TS)
    motor.setAvailableTorque(available)
    motor.setTorque(torque)
    _steps(robot, 25)
    return float(s.getValue())


def test_set_torque_is_clamped_to_the_available_torque() -> None:
    # O:435-436 setTorque: "raw input = τ·multiplier clamped to ±available torque"
    assert _angle_after_torque(0.5, 100.0) == pytest.approx(_angle_after_torque(5.0, 0.5), rel=1e-9)


def test_get_brake_and_get_position_sensor_are_the_sibling_devices() -> None:
    # R:352-353 getBrake/getPositionSensor: "sibling device on the same joint"; None where there is none
    robot = _robot()
    motor = robot.getDevice("m")
    assert motor.getBrake().getName() == "b" and motor.getPositionSensor().getName() == "s"
    assert motor.brake.getName() == "b" and motor.position_sensor.getName() == "s"
    assert robot.getDevice("lim").getBrake() is None and robot.getDevice("lim").getPositionSensor() is None
    sensor = motor.getPositionSensor()
    sensor.enable(TS)  # one device, one state: the robot's own handle is enabled too
    assert robot.getDevice("s").getSamplingPeriod() == TS


def test_position_sensor_and_brake_link_back_to_their_siblings() -> None:
    # R:367-368 PositionSensor getBrake/getMotor; R:385-386 Brake getMotor/getPositionSensor
    robot = _robot()
    s, b = robot.getDevice("s"), robot.getDevice("b")
    assert s.getMotor().getName() == "m" and s.getBrake().getName() == "b"
    assert b.getMotor().getName() == "m" and b.getPositionSensor().getName() == "s"
    assert robot.getDevice("ls").getBrake() is None


def test_motor_position_sensor_and_brake_types() -> None:
    # R:313 Motor "ROTATIONAL=0, LINEAR=1"; getType ROTATIONAL / LINEAR
    robot = _robot()
    assert robot.getDevice("m").getType() == 0 and robot.getDevice("lin").getType() == 1
    assert robot.getDevice("s").getType() == 0 and robot.getDevice("ls").getType() == 1
    assert robot.getDevice("b").getType() == 0


def test_brake_damping_slows_a_spinning_joint() -> None:
    # R:383 setDampingConstant "N*m*s/rad or N*s/m added to the joint"
    def spin(damping: float) -> float:
        robot = _robot()
        s, motor = robot.getDevice("s"), robot.getDevice("m")
        s.enable(TS)
        robot.getDevice("b").setDampingConstant(damping)
        motor.setTorque(1.0)
        _steps(robot, 25)
        return float(s.getValue())

    assert spin(1.0) < 0.8 * spin(0.0)


# ------------------------------------------------------------------ Robot


def test_robot_identity_fields() -> None:
    # R:79-81 getName/getModel/getCustomData: the Robot's fields; R:85-86 getSupervisor/getSynchronization
    robot = _robot()
    assert robot.getName() == "bot" and robot.getModel() == "tester" and robot.getCustomData() == "hello"
    assert robot.getSupervisor() is False and robot.getSynchronization() is False


def test_set_custom_data_writes_the_field() -> None:
    # R:82 setCustomData "writes Robot.customData"
    robot = _robot()
    robot.setCustomData("new")
    assert robot.getCustomData() == "new"
    assert robot.simulation.robots[0].node.fields["customData"] == "new"


def test_step_none_runs_one_basic_time_step() -> None:
    # R:90 step "(time_step=None) ... None = basicTimeStep"; returns 0
    robot = _robot()
    assert robot.step() == 0
    assert robot.getTime() == pytest.approx(TS / 1000)
    assert robot.stepBegin() == 0 and robot.stepEnd() == 0
    assert robot.getTime() == pytest.approx(2 * TS / 1000)


def test_get_device_of_an_unknown_name_prints_and_returns_none(capfd: pytest.CaptureFixture[str]) -> None:
    # R:71 getDevice "unknown name: stderr message, None"
    robot = _robot()
    capfd.readouterr()
    assert robot.getDevice("nope") is None
    assert "nope" in capfd.readouterr().err


def test_get_device_by_index_walks_every_device() -> None:
    # R:72 getDeviceByIndex "0 <= index < getNumberOfDevices()"; R:32 getDevice returns the same object
    robot = _robot()
    n = robot.getNumberOfDevices()
    by_index = [robot.getDeviceByIndex(i) for i in range(n)]
    assert n == 9 and {d.getName() for d in by_index} == set(robot.devices)
    assert all(robot.getDevice(d.getName()) is d for d in by_index)


def test_project_and_world_paths(tmp_path: Path) -> None:
    # R:83 getProjectPath "project folder (parent of worlds/)"; R:84 getWorldPath "absolute path of the .wbt"
    worlds = tmp_path / "project" / "worlds"
    worlds.mkdir(parents=True)
    (worlds / "w.wbt").write_text(WORLD)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world(worlds / "w.wbt"))
    robot = Robot(simulation=sim, robot_node=sim.robots[0].node)
    assert Path(robot.getWorldPath()) == (worlds / "w.wbt").resolve() and Path(robot.getWorldPath()).is_absolute()
    assert Path(robot.getProjectPath()) == (tmp_path / "project").resolve()


def test_battery_property_none_enables_at_the_basic_time_step() -> None:
    # R:66 battery_sensor_sampling_period "setting enables the sensor (None = basic step)"; R:97 "NaN until sampled"
    robot = _robot()
    robot.battery_sensor_sampling_period = None
    assert robot.batterySensorGetSamplingPeriod() == TS
    assert math.isnan(robot.batterySensorGetValue())
    robot.step(TS)
    assert robot.batterySensorGetValue() == pytest.approx(100.0, abs=1.0)  # 10 W of cpuConsumption for 8 ms
    robot.batterySensorDisable()
    assert robot.batterySensorGetSamplingPeriod() == 0


def test_a_disabled_battery_sensor_read_prints_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 shared semantics (the battery level sensor, R:93-97)
    robot = _robot()
    capfd.readouterr()
    assert math.isnan(robot.batterySensorGetValue())
    assert "called for a disabled device" in capfd.readouterr().err


def test_urdf_exports_joints_as_webots_does() -> None:
    # O:509-514 getUrdf: HingeJoint → revolute (motor limits) or continuous, SliderJoint → prismatic, <limit>,
    # no mass or inertia; R:87 getUrdf(prefix='')
    urdf = _robot().getUrdf("p_")
    assert urdf.count('type="continuous"') == 1 and urdf.count('type="revolute"') == 1
    assert urdf.count('type="prismatic"') == 1
    assert 'lower="-1' in urdf and 'upper="1' in urdf and "<limit" in urdf
    assert "<mass" not in urdf and "<inertia" not in urdf
    assert 'name="p_' in urdf
