"""The Webots twin reads every scalar sensor from its first step, as the MuJoCo twin does: GPS, Gyro,
Accelerometer, Compass and Altimeter are enabled when the twin is made (a Webots sensor reads NaN until its first
sample after ``enable``; before, only the ``*Sensor`` nodes were enabled at start, the others at their first read,
which was NaN). A device with no value to read (an InertialUnit) is refused in one line, not with a traceback."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from tests.support.converted_twins import converted_twins, world_text

X = 0.25  # the robot stands welded at x = X, still: its GPS x is exactly X, its gyro 0, its accelerometer x 0
DEVICES = ('GPS { name "gps" } Gyro { name "gyro" } Accelerometer { name "acc" } Compass { name "compass" } '
           'Altimeter { name "alt" } InertialUnit { name "imu" }')


def test_the_first_read_after_one_step_is_a_sample_in_both_twins(tmp_path: Path) -> None:
    text = world_text(
        f'Robot {{ translation {X} 0 0 controller "<extern>" children [ {DEVICES} DEF H HingeJoint {{\n'
        '  jointParameters HingeJointParameters { axis 0 0 1 }\n'
        '  device [ PositionSensor { name "s" } RotationalMotor { name "m" } ]\n'
        "  endPoint DEF E Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }",
        "basicTimeStep 8 gravity 0")
    with converted_twins(text, tmp_path, 0.008) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        for name in ("gps", "gyro", "acc", "compass", "alt"):
            assert math.isfinite(webots.sensor(name)), name
        assert webots.sensor("gps") == pytest.approx(X, abs=1e-12) == mujoco_twin.sensor("gps")
        assert webots.sensor("gyro") == 0.0 and webots.sensor("acc") == pytest.approx(0.0, abs=1e-9)
        with pytest.raises(DualtwinError, match="no sensor named 'imu'") as refused:
            webots.sensor("imu")
        assert "\n" not in str(refused.value) and "known: acc, alt, compass, gps, gyro, s" in str(refused.value)


def test_a_hinge2_second_axis_sensor_and_motor_are_the_twins_from_the_first_step(tmp_path: Path) -> None:
    # A Hinge2Joint's device2 (its second axis) holds a PositionSensor and a motor like device does: the Webots
    # twin enables that sensor when it is made too (before, its walk skipped device2, so the first read was NaN
    # and its motor was missing from the known names). The robot has Physics and no gravity, so the Hinge2
    # joins two bodies (an ODE hinge2, not the kinematic static-parent case) and nothing moves: both twins read
    # the second axis' initial position 0.2 exactly (MuJoCo's ref, ODE's offset at a zero angle).
    text = world_text(
        'Robot { controller "<extern>" physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } children [\n'
        '  DEF H Hinge2Joint { jointParameters HingeJointParameters { axis 1 0 0 }\n'
        '  jointParameters2 JointParameters { axis 0 1 0 position 0.2 }\n'
        '  device [ PositionSensor { name "s1" } ] device2 [ PositionSensor { name "s2" } RotationalMotor { name "m2" } ]\n'
        "  endPoint DEF E Solid { translation 0 0 -0.3 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }"
        " } ] }", "basicTimeStep 8 gravity 0")
    with converted_twins(text, tmp_path, 0.008) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        for twin in (webots, mujoco_twin):
            assert twin.sensor("s2") == pytest.approx(0.2, abs=1e-9), twin.name
            assert twin.sensor("s1") == pytest.approx(0.0, abs=1e-9), twin.name
        with pytest.raises(DualtwinError, match="known: m2"):
            webots.command("nope", "velocity", 1.0)


def test_a_sub_millisecond_basic_step_still_samples(tmp_path: Path) -> None:
    # Found by the dual-twin fuzz: with basicTimeStep 0.5 the twin enabled every sensor with int(0.5) = 0 ms,
    # which is Webots' disable() (webots-devices §0.2: enable(0) ≡ disable()), so every read was NaN. Webots'
    # enable() takes whole milliseconds and samples when now − lastUpdate ≥ period (§0.1): 1 ms, the shortest,
    # samples every other 0.5 ms step, so each 2 ms control period ends on a sample. Hand values: nothing moves
    # (gravity 0), so the GPS reads the robot's x and the PositionSensor the hinge's initial position 0.3.
    text = world_text(
        f'Robot {{ translation {X} 0 0 controller "<extern>" children [ GPS {{ name "gps" }} DEF H HingeJoint {{\n'
        "  jointParameters HingeJointParameters { axis 0 0 1 position 0.3 }\n"
        '  device [ PositionSensor { name "s" } ]\n'
        "  endPoint DEF E Solid { rotation 0 0 1 0.3 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } }"
        " ] }", "basicTimeStep 0.5 gravity 0")
    with converted_twins(text, tmp_path, 0.002) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.step()
            assert twin.sensor("gps") == pytest.approx(X, abs=1e-12), twin.name
            assert twin.sensor("s") == pytest.approx(0.3, abs=1e-9), twin.name
