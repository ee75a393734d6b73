"""Device rules of webots-devices.md checked one small world each: the Lidar's load-time layer check (§3.1) and
where a TrackWheel puts its children (§7.1).

References: D = /work/shared/reference/webots-devices.md, R = .../webots-python-api.md. Expected values come
from those texts or from hand computation, never from running this code.
"""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Camera, Supervisor
from tests.support.quiet_worlds import quiet_supervisor
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


# ------------------------------------------------------------------------------------------ §7.1 TrackWheel


def _tank(eye: str) -> Supervisor:
    """A supervisor 'eye' at (-1, 0, 0.2) looking along +x, and a tank whose Track (at the origin) has a
    TrackWheel at position (0.3, 0.2) holding a red sphere of radius 0.05 and a Solid 'HUB'."""
    wheel = ('TrackWheel { position 0.3 0.2 radius 0.05 children [ Shape { appearance PBRAppearance { baseColor 1 0 0 '
             'roughness 1 metalness 0 } geometry Sphere { radius 0.05 } } DEF HUB Solid { name "hub" } ] }')
    text = ("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 gravity 0 }\nDirectionalLight { direction 1 0 0 }\n"
            f'Robot {{ name "eye" supervisor TRUE translation -1 0 0.2 children [ {eye} ] }}\n'
            f'Robot {{ name "tank" children [ Track {{ children [ {wheel} ] device [ LinearMotor {{ }} ] }} ] }}\n')
    return quiet_supervisor(text)


def test_track_wheel_children_sit_at_its_position() -> None:
    # D §7.1: "Code places its children at (position.x, 0, position.y) in the Track frame"
    sup = _tank("")
    sup.step(8)
    assert sup.getFromDef("HUB").getPosition() == pytest.approx([0.3, 0.0, 0.2], abs=1e-12)


def test_track_wheel_shapes_are_seen_at_its_position_by_a_range_finder() -> None:
    # D §7.1 as above; D §3.2: a RangeFinder renders the visual Shapes: the sphere's near side is at
    # x = 0.3 − 0.05 = 0.25, 1.25 m in front of the eye (one centred pixel, planar depth)
    sup = _tank('RangeFinder { name "rf" width 1 height 1 fieldOfView 0.01 maxRange 5 }')
    rf = sup.getDevice("rf")
    rf.enable(8)
    sup.step(8)
    assert rf.getRangeImage() == pytest.approx([1.25], rel=1e-9)


def test_track_wheel_shapes_are_drawn_at_its_position_by_a_camera() -> None:
    # D §7.1 as above: the red sphere fills the centre of a narrow camera looking at it
    sup = _tank('Camera { name "cam" width 8 height 8 fieldOfView 0.02 }')
    cam = sup.getDevice("cam")
    cam.enable(8)
    sup.step(8)
    image = cam.getImage()
    red, green = Camera.imageGetRed(image, 8, 4, 4), Camera.imageGetGreen(image, 8, 4, 4)
    assert red > 100 and green < red / 2  # red-dominant (a grazing specular highlight lifts green a little)
