"""An Accelerometer's, Gyro's or Compass's ``lookupTable`` applies per axis in the MuJoCo twin as in Webots
(webots-devices §0.3: clamped rows, interpolated output, then the resolution §0.4), and a Compass's ``resolution``
is written as the other sensors' is. ``twin.sensor`` reads a vector sensor's first component in both twins.

The robot is welded and yawed by 0.5 rad in an ENU world without gravity: its Compass reads the north (+y) in its
frame, (sin 0.5, cos 0.5, 0), so x = 0.479426; its Gyro and Accelerometer read 0. Expected values are hand
computations; the dual-twin test reads the Webots twin on the same world.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

PERIOD = 0.008
YAW = 0.5
NORTH_X = math.sin(YAW)  # 0.479426
COMPASS = "-1 -100 0, 0 0 0, 1 50 0"  # a kink at 0: 50 per unit above, 100 below
OFFSET = "-10 -4 0, 10 6 0"  # 0 -> 1 (slope 0.5)


def _world(devices: str) -> str:
    return world_text(
        f'DEF R Robot {{ rotation 0 0 1 {YAW} controller "<extern>" children [ GPS {{ name "gps" }} {devices}\n'
        "  DEF H HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }\n"
        '  device [ PositionSensor { name "s" } RotationalMotor { name "m" } ]\n'
        "  endPoint DEF E Solid { translation 0 0 -1 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }"
        " } ] }", "basicTimeStep 2 gravity 0")


def _mujoco(text: str) -> MuJoCoTwin:
    return MuJoCoTwin(convert_world_text(text, "t.wbt").spec, PERIOD)


@pytest.mark.parametrize(("device", "reading"), [
    (f'Compass {{ name "c" lookupTable [ {COMPASS} ] }}', 50.0 * NORTH_X),  # 23.9713
    (f'Compass {{ name "c" lookupTable [ {COMPASS} ] resolution 10 }}', 20.0),  # int(2.397 + 0.5)·10
    ('Compass { name "c" lookupTable [ 0 5 0, 1 6 0 ] }', 5.0 + NORTH_X),
    ('Compass { name "c" lookupTable [ 0.6 -1 0, 1 1 0 ] }', -1.0),  # below the first input: the first row
    (f'Gyro {{ name "c" lookupTable [ {OFFSET} ] }}', 1.0),
    (f'Accelerometer {{ name "c" lookupTable [ {OFFSET} ] }}', 1.0),
])
def test_a_vector_sensor_reads_its_table(device: str, reading: float) -> None:
    conv = convert_world_text(_world(device), "t.wbt")
    assert "webots_sensor_lut.c" in conv.xml
    assert not [w for w in conv.warnings if "lookupTable" in w], conv.warnings
    assert MuJoCoTwin(conv.spec, PERIOD).sensor("c") == pytest.approx(reading, abs=1e-9)


def test_a_compass_resolution_is_written_and_applied() -> None:
    # No table: int(0.479/0.1 + 0.5)·0.1 = 0.5 (Webots' rule, as for a GPS).
    conv = convert_world_text(_world('Compass { name "c" resolution 0.1 }'), "t.wbt")
    assert [float(v) for v in conv.compile().numeric("webots_sensor.c").data] == [0.1]
    assert MuJoCoTwin(conv.spec, PERIOD).sensor("c") == pytest.approx(0.5, abs=1e-12)


@pytest.mark.parametrize("device", ['Compass { name "c" }', 'Gyro { name "c" }', 'Accelerometer { name "c" }'])
def test_control_without_a_table_nothing_changes(device: str) -> None:
    # Control: no table is Webots' identity; nothing is written and the reading is MuJoCo's, as before.
    conv = convert_world_text(_world(device), "t.wbt")
    assert "webots_sensor" not in conv.xml
    twin = MuJoCoTwin(conv.spec, PERIOD)
    assert twin.plain_sensor_reads
    assert twin.sensor("c") == pytest.approx(NORTH_X if device.startswith("Compass") else 0.0, abs=1e-12)


def test_the_webots_twin_reads_the_same(tmp_path: Path) -> None:
    # Both twins rotate the same north by the same welded yaw and read no motion. The model file stores the
    # robot's quaternion with 6 significant digits (0.968912 0 0 0.247404), a yaw off by up to 2e-6 rad, so the
    # Compass's x is off by up to 2e-6 and its table output (slope 50) by up to 1e-4: that is its tolerance. The
    # rounded Compass (0.479 to 0.5) and the Gyro and Accelerometer (exactly 0 -> 1) must agree to 1e-9.
    devices = (f'Compass {{ name "compass" lookupTable [ {COMPASS} ] }} '
               f'Compass {{ name "rounded" resolution 0.1 }} '
               f'Gyro {{ name "gyro" lookupTable [ {OFFSET} ] }} '
               f'Accelerometer {{ name "accel" lookupTable [ {OFFSET} ] }}')
    expected = {"compass": 50.0 * NORTH_X, "rounded": 0.5, "gyro": 1.0, "accel": 1.0}
    with converted_twins(_world(devices), tmp_path, PERIOD) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.step()
            for name, reading in expected.items():
                tolerance = 1e-4 if name == "compass" else 1e-9
                assert twin.sensor(name) == pytest.approx(reading, abs=tolerance), (twin.name, name)
