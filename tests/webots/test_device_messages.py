"""The prefix of the stderr line a device prints on a refused call: ``Error:`` where webots-devices.md says the call
is an error (libController prints those lines as errors), ``Warning:`` where it says warning.

References: D = /work/shared/reference/webots-devices.md (sections cited per test). Only the prefix and the fact of
the line are checked: the reference does not give the wording.
"""

from __future__ import annotations

import math

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.sensor_worlds import sensor_world

DEVICES = (
    'Lidar { name "lidar" horizontalResolution 8 fieldOfView 1 verticalFieldOfView 0.5 numberOfLayers 2 } '
    'TouchSensor { name "touch3d" type "force-3d" } '
    'Emitter { name "emitter" } Receiver { name "receiver" } Display { name "display" }'
)


@pytest.fixture
def sup() -> Supervisor:
    return sensor_world(DEVICES, "")


def _lines(capfd: pytest.CaptureFixture[str]) -> list[str]:
    return capfd.readouterr().err.splitlines()


def test_lidar_set_frequency_outside_its_range_is_an_error(sup: Supervisor, capfd: pytest.CaptureFixture[str]) -> None:
    # D §3.3: "getFrequency/setFrequency(f) (outside [min,max] → error)"; defaults min 1, max 25 Hz (§3.1)
    lidar = sup.getDevice("lidar")
    capfd.readouterr()
    lidar.setFrequency(30.0)
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")
    assert lidar.getFrequency() == 10.0


def test_lidar_number_of_points_without_point_cloud_is_an_error(sup: Supervisor,
                                                                capfd: pytest.CaptureFixture[str]) -> None:
    # D §3.3: "getNumberOfPoints() (0 + error unless point cloud and device enabled)"
    lidar = sup.getDevice("lidar")
    lidar.enable(8)
    capfd.readouterr()
    assert lidar.getNumberOfPoints() == 0
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")


def test_touch_get_value_on_a_force_3d_sensor_is_an_error(sup: Supervisor, capfd: pytest.CaptureFixture[str]) -> None:
    # D §2.4: getValue() "bumper/force only; other types → stderr error and NaN"
    touch = sup.getDevice("touch3d")
    touch.enable(8)
    sup.step(8)
    capfd.readouterr()
    assert math.isnan(touch.getValue())
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")


def test_emitter_channel_below_minus_one_is_an_error(sup: Supervisor, capfd: pytest.CaptureFixture[str]) -> None:
    # D §5.3: "getChannel/setChannel(c) (c < −1 or not allowed → error)"
    emitter = sup.getDevice("emitter")
    capfd.readouterr()
    emitter.setChannel(-2)
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")
    assert emitter.getChannel() == 0


def test_receiver_data_size_of_an_empty_queue_is_an_error(sup: Supervisor,
                                                          capfd: pytest.CaptureFixture[str]) -> None:
    # D §5.3: "getDataSize() (−1 + error if empty)"
    receiver = sup.getDevice("receiver")
    receiver.enable(8)
    capfd.readouterr()
    assert receiver.getDataSize() == -1
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")


def test_display_colour_out_of_range_is_an_error(sup: Supervisor, capfd: pytest.CaptureFixture[str]) -> None:
    # D §6: "setColor(0xRRGGBB) (default white; out of range → error)"
    display = sup.getDevice("display")
    capfd.readouterr()
    display.setColor(0x1000000)
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")


def test_get_device_of_an_unknown_name_is_an_error(sup: Supervisor, capfd: pytest.CaptureFixture[str]) -> None:
    # D §12: "getDevice(name) returns it or prints an error and returns None"
    capfd.readouterr()
    assert sup.getDevice("no such device") is None
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Error: ")


def test_unknown_touch_sensor_type_stays_a_warning(capfd: pytest.CaptureFixture[str]) -> None:
    # D §2.1: "unknown → bumper + warning"
    sup = sensor_world('TouchSensor { name "t" type "Force" }', "")
    capfd.readouterr()
    assert sup.getDevice("t").getType() == 0
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Warning: ")


# ------------------------------------------------------------------------------------------ §9 force clipping


def _arm(motor: str, y: float) -> str:
    return (f"HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 {y} 0 }} device [ "
            f"RotationalMotor {{ {motor} maxTorque 5 }} ] endPoint Solid {{ translation 0.2 {y} 0 name \"arm{y}\" "
            "boundingObject Sphere { radius 0.05 } physics Physics { mass 1 } } }")


def test_a_force_beyond_the_available_force_is_clipped_with_a_warning(capfd: pytest.CaptureFixture[str]) -> None:
    # D §9: setForce/setTorque: Webots computes f·m "clipped to ±available force/torque; warning suppressed for
    # coupled motors"
    sup = sensor_world(_arm('name "m"', 0) + _arm('name "g::a"', 1) + _arm('name "g::b"', 2), "")
    capfd.readouterr()
    sup.getDevice("m").setTorque(2.0)
    assert _lines(capfd) == []
    sup.getDevice("m").setTorque(100.0)
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Warning: ")
    sup.getDevice("g::a").setTorque(100.0)  # coupled: clipped silently
    assert _lines(capfd) == []


def test_a_track_force_beyond_its_available_force_is_clipped_with_a_warning(
        capfd: pytest.CaptureFixture[str]) -> None:
    # D §9 as above, for the LinearMotor of a Track (maxForce 10, D §7.1)
    sup = sensor_world('Track { boundingObject Box { size 2 0.4 0.1 } physics Physics { mass 5 } '
                       'device [ LinearMotor { name "belt" } ] }', "")
    capfd.readouterr()
    sup.getDevice("belt").setForce(50.0)
    lines = _lines(capfd)
    assert len(lines) == 1 and lines[0].startswith("Warning: ")
