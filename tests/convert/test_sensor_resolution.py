"""A PositionSensor's (GPS's) ``resolution`` reaches the converted model (``webots_sensor.<name>`` numeric) and the
MuJoCo twin quantises its readings as Webots does: ``discretize(v, r) = int(v/r + 0.5)·r`` with C's truncation toward
zero (webots-devices §0.4, on-ode §5.4), so a negative reading rounds up: -0.26 at 0.1 reads -0.2, not -0.3.

Expected values are hand computations of that rule; the dual-twin test reads the Webots twin on the same world.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

PERIOD = 0.008


def _world(position: float, resolution: str, *, at: float = 0.0, gps: str = "") -> str:
    return world_text(
        f'DEF R Robot {{ translation {at} 0 0 controller "<extern>" children [ {gps} DEF H HingeJoint {{\n'
        f"  jointParameters HingeJointParameters {{ axis 0 0 1 position {position} }}\n"
        f'  device [ PositionSensor {{ name "s" {resolution} }} RotationalMotor {{ name "m" }} ]\n'
        f"  endPoint DEF E Solid {{ rotation 0 0 1 {position} physics Physics {{ }} "
        "boundingObject Box { size 0.1 0.1 0.1 } } } ] }", "basicTimeStep 2 gravity 0")


@pytest.mark.parametrize(("position", "reading"), [(0.26, 0.3), (-0.26, -0.2), (-0.36, -0.3), (0.04, 0.0)])
def test_the_mujoco_twin_reads_positions_quantised_as_webots(position: float, reading: float) -> None:
    conv = convert_world_text(_world(position, "resolution 0.1"), "r.wbt")
    assert [float(v) for v in conv.compile().numeric("webots_sensor.s").data] == [0.1]
    twin = MuJoCoTwin(conv.spec, PERIOD)
    assert twin.sensor("s") == pytest.approx(reading, abs=1e-12)
    assert not twin.plain_sensor_reads  # a batch must not read the raw value either


def test_without_a_resolution_the_reading_is_the_position() -> None:
    conv = convert_world_text(_world(-0.26, ""), "r.wbt")
    assert "webots_sensor" not in conv.xml
    twin = MuJoCoTwin(conv.spec, PERIOD)
    assert twin.sensor("s") == pytest.approx(-0.26, abs=1e-12)


def test_the_webots_twin_reads_the_same(tmp_path: Path) -> None:
    # The motor holds the joint at its initial position in both twins (a servo on a still joint: the
    # position stays within 1e-9 rad, far from a 0.1 step), so both readings are the quantised -0.26.
    with converted_twins(_world(-0.26, "resolution 0.1"), tmp_path, PERIOD) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.step()
            assert twin.joint_position("H") == pytest.approx(-0.26, abs=1e-9), twin.name
            assert twin.sensor("s") == pytest.approx(-0.2, abs=1e-12), twin.name


@pytest.mark.parametrize(("x", "reading"), [(0.123, 0.1), (-0.123, -0.05)])
def test_a_gps_resolution_quantises_both_twins_alike(tmp_path: Path, x: float, reading: float) -> None:
    # int(0.123/0.05 + 0.5) = 2 -> 0.1; int(-0.123/0.05 + 0.5) = int(-1.96) = -1 -> -0.05 (round would give -0.1).
    # The robot is welded where it stands, so its GPS x is exactly x in both twins.
    text = _world(0.0, "", at=x, gps='GPS { name "gps" resolution 0.05 }')
    with converted_twins(text, tmp_path, PERIOD) as (conv, webots, mujoco_twin):
        assert [float(v) for v in conv.compile().numeric("webots_sensor.gps").data] == [0.05]
        for twin in (webots, mujoco_twin):
            twin.step()  # the Webots twin enabled the GPS when it was made, so this first read is a sample
            assert twin.sensor("gps") == pytest.approx(reading, abs=1e-12), twin.name


def test_an_inertial_unit_resolution_is_not_written() -> None:
    # Control: MuJoCo's framequat is a quaternion where Webots quantises roll/pitch/yaw; nothing is written.
    conv = convert_world_text(_world(0.0, "", gps='InertialUnit { name "imu" resolution 0.1 }'), "imu.wbt")
    assert "webots_sensor" not in conv.xml
