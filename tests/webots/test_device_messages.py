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
