"""Device rules of webots-devices.md checked one small world each: the Lidar's load-time layer check (§3.1) and
the stated facts of the simple devices.

References: D = /work/shared/reference/webots-devices.md, R = .../webots-python-api.md. Expected values come
from those texts or from hand computation, never from running this code.
"""

from __future__ import annotations

from dualtwin.webots.controller import Supervisor
from tests.support.sensor_worlds import sensor_world

NO_WALL = ""


def _lidar(fields: str) -> tuple[Supervisor, list[str]]:
    sup = sensor_world(f'Lidar {{ name "lidar" {fields} }}', NO_WALL)
    return sup, sup.simulation.build_warnings


# ------------------------------------------------------------------------------------------ §3.1 Lidar layers


def test_lidar_with_more_layers_than_its_vertical_resolution_gets_the_field_rewritten() -> None:
    # D §3.1: "Load-time check: numberOfLayers ≤ vfov·horizontalResolution/fov ..., else fields rewritten":
    # 0.2·8/1 = 1.6, so 4 layers become 1 (the largest whole number that fits), with a warning
    sup, built = _lidar("horizontalResolution 8 fieldOfView 1 verticalFieldOfView 0.2 numberOfLayers 4")
    lidar = sup.getDevice("lidar")
    assert lidar.getNumberOfLayers() == 1
    lidar.enable(8)
    sup.step(8)
    assert len(lidar.getRangeImage()) == 8
    assert any("numberOfLayers" in w for w in built)
    node = sup.getFromDevice(lidar._tag)  # R: getFromDevice takes the device tag
    assert node.getField("numberOfLayers").getSFInt32() == 1


def test_lidar_layers_within_the_vertical_resolution_are_kept() -> None:
    # D §3.1: 0.5·8/1 = 4 ≥ 4: nothing rewritten, no warning
    sup, built = _lidar("horizontalResolution 8 fieldOfView 1 verticalFieldOfView 0.5 numberOfLayers 4")
    assert sup.getDevice("lidar").getNumberOfLayers() == 4
    assert not any("numberOfLayers" in w for w in built)


def test_rotating_lidar_layer_check_uses_two_pi() -> None:
    # D §3.1: "(2π for rotating)": 0.5·8/(2π) ≈ 0.64 < 4, so the same fields give a single layer when rotating
    sup, built = _lidar('type "rotating" horizontalResolution 8 fieldOfView 1 verticalFieldOfView 0.5 '
                        "numberOfLayers 4")
    assert sup.getDevice("lidar").getNumberOfLayers() == 1
    assert any("numberOfLayers" in w for w in built)
