"""webots-devices.md §3-§4 (Lidar, RangeFinder, Camera Recognition): one test per fact that no other test pins,
at the level of the computation. Expected values come from the reference (its line cited as ``devices.md:N``) or
from the geometry of the world written here, never from running our code.

Worlds: the device at the origin of a static robot 0.1 m above ground, looking along +x at a wall whose face is at
x = 0.5 m. Noise is made deterministic by a generator whose Gaussian draw is always 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.sensor_worlds import sensor_world, unit_noise

WALL = "Solid { translation 0.55 0 0.1 children [ Shape { geometry DEF WB Box { size 0.1 4 4 } } ] }"


def _world(devices: str, wall: str = WALL, head: str = "") -> Supervisor:
    return sensor_world(devices, wall, head=head)


def _image(sup: Supervisor, name: str) -> np.ndarray:
    dev = sup.getDevice(name)
    dev.enable(8)
    sup.step(8)
    return np.array(dev.getRangeImageArray())


# ------------------------------------------------------------------------------------------ §3 ranges


def test_range_finder_vertical_fov_is_2_atan_of_tan_half_fov_times_height_over_width() -> None:
    # devices.md:159: vfov = 2·atan(tan(fov/2)·h/w); 8×4 pixels, fov 1: tan(vfov/2) = tan 0.5 / 2 = 0.2732, rows
    # at z/x = 0.2732·(1 − (2i+1)/4) = 0.205, 0.068, −0.068, −0.205. A wall above z = 0.1 m at x = 0.5 (z/x > 0.2)
    # is met by the top row alone (a vfov of fov·h/w = 0.5 would put it at 0.191 and miss)
    upper = "Solid { translation 0.55 0 2.2 children [ Shape { geometry Box { size 0.1 4 4 } } ] }"
    image = _image(_world('RangeFinder { name "rf" width 8 height 4 fieldOfView 1 maxRange 3 }', wall=upper), "rf")
    assert image[0] == pytest.approx([0.5] * 8, rel=1e-9)  # planar depth (devices.md:163)
    assert np.isinf(image[1:]).all()


def test_a_range_equal_to_max_range_is_inf_and_one_equal_to_min_range_is_kept() -> None:
    # devices.md:162-163: values < minRange or ≥ maxRange become +inf; the axis ray meets the face at exactly 0.5
    at_max = _world('RangeFinder { name "rf" width 1 height 1 maxRange 0.5 }')
    assert np.isinf(_image(at_max, "rf")).all()
    at_min = _world('RangeFinder { name "rf" width 1 height 1 minRange 0.5 maxRange 2 }')
    assert _image(at_min, "rf") == pytest.approx(np.array([[0.5]]), rel=1e-12)


def test_range_noise_is_additive_with_sigma_noise_times_max_range() -> None:
    # devices.md:166: additive σ·N(0,1), σ = noise·maxRange: 0.5 + 0.01·2·1 = 0.52
    sup = _world('RangeFinder { name "rf" width 2 height 2 maxRange 2 noise 0.01 }')
    unit_noise(sup)
    assert _image(sup, "rf") == pytest.approx(np.full((2, 2), 0.52), rel=1e-12)


def test_one_layer_lidar_looks_at_its_tilt_angle() -> None:
    # devices.md:173-174: φ = tilt for one layer; the centre column (one column, θ = 0)
    # (θ = fov/2 − ½·fov/1 = 0) meets the wall at the Euclidean 0.5/cos 0.3 (cylindrical)
    sup = _world('Lidar { name "l" horizontalResolution 1 fieldOfView 0.1 numberOfLayers 1 tiltAngle 0.3 maxRange 3 }')
    assert _image(sup, "l") == pytest.approx(np.array([[0.5 / math.cos(0.3)]]), rel=1e-9)


def test_lidar_layers_are_spread_over_the_vertical_fov_around_the_tilt() -> None:
    # devices.md:173: φ_i = vfov/2 − i·vfov/(L−1) + tilt: vfov 0.4, 3 layers, tilt −0.1 -> 0.1, −0.1, −0.3
    sup = _world('Lidar { name "l" horizontalResolution 1 fieldOfView 0.1 verticalFieldOfView 0.4 '
                 'numberOfLayers 3 tiltAngle -0.1 maxRange 3 }')
    expected = [[0.5 / math.cos(phi)] for phi in (0.1, -0.1, -0.3)]
    assert _image(sup, "l") == pytest.approx(np.array(expected), rel=1e-9)


def test_lidar_point_cloud_elevation_includes_the_tilt() -> None:
    # devices.md:172-174: z = r·sin φ with φ = tilt for one layer: the wall point at x = 0.5 has z = 0.5·tan 0.3
    sup = _world('Lidar { name "l" horizontalResolution 1 fieldOfView 0.1 numberOfLayers 1 tiltAngle 0.3 maxRange 3 }')
    lidar = sup.getDevice("l")
    lidar.enable(8)
    lidar.enablePointCloud()
    sup.step(8)
    (p,) = lidar.getPointCloud()
    assert (p.x, p.y, p.z) == pytest.approx((0.5, 0.0, 0.5 * math.tan(0.3)), abs=1e-9)


def test_semi_transparent_shapes_count_as_opaque_for_depth() -> None:
    # devices.md:163: semi-transparent objects count as opaque (the glass at x = 0.2..0.3 hides the wall)
    glass = (
        "Solid { translation 0.25 0 0.1 children [ Shape { appearance PBRAppearance { transparency 0.5 } "
        "geometry Box { size 0.1 4 4 } } ] }"
    )
    sup = _world('RangeFinder { name "rf" width 1 height 1 maxRange 3 } '
                 'Lidar { name "l" horizontalResolution 1 fieldOfView 0.1 numberOfLayers 1 maxRange 3 }',
                 wall=f"{WALL}\n{glass}")
    assert _image(sup, "rf") == pytest.approx(np.array([[0.2]]), rel=1e-9)
    assert _image(sup, "l") == pytest.approx(np.array([[0.2]]), rel=1e-9)


def test_a_range_finder_sees_shapes_of_its_own_robot() -> None:
    # devices.md:162: the depth image renders the visual scene, the device's own robot included
    part = "Pose { translation 0.35 0 0 children [ Shape { geometry Box { size 0.1 1 1 } } ] }"
    sup = _world(f'RangeFinder {{ name "rf" width 2 height 2 fieldOfView 0.5 maxRange 3 }} {part}', wall="")
    assert _image(sup, "rf") == pytest.approx(np.full((2, 2), 0.3), rel=1e-9)


# ------------------------------------------------------------------------------------------ §4 Recognition

_CAMERA = 'Camera { name "cam" width 32 height 32 fieldOfView 1.0 recognition Recognition { } }'


def _box(name: str, x: float, colours: str = "recognitionColors [ 1 0 0 ]", y: float = 0.0) -> str:
    return (f'DEF {name} Solid {{ translation {x} {y} 0.1 name "{name}" {colours} children [ Shape {{ '
            f"geometry DEF {name}B Box {{ size 0.4 0.4 0.4 }} }} ] boundingObject USE {name}B }}")


def _recognised(objects: str) -> list[str]:
    sup = _world(_CAMERA, wall=objects, head="DirectionalLight { direction 0 0 -1 }")
    cam = sup.getDevice("cam")
    cam.recognitionEnable(8)
    sup.step(8)
    names = []
    for obj in cam.getRecognitionObjects():
        node = sup.getFromId(obj.getId())
        assert node is not None
        names.append(node.getDef())
    return names


def test_recognition_default_max_range_is_100_m() -> None:
    # devices.md:209: maxRange 100 by default (a 0.4 m box covers about 1.3 px at 9.9 m with this camera)
    assert _recognised(_box("NEAR", 90.0) + "\n" + _box("FAR", 110.0, y=0.0)) == ["NEAR"]


def test_recognition_default_max_objects_is_unlimited() -> None:
    # devices.md:209: maxObjects −1: every recognisable object in view is reported
    objects = "\n".join(_box(f"B{i}", 2.0 + i, y=0.6 * (i - 2)) for i in range(5))
    assert sorted(_recognised(objects)) == [f"B{i}" for i in range(5)]


def test_recognition_default_occlusion_hides_what_is_behind() -> None:
    # devices.md:209: occlusion 1 by default: the box behind the nearer one is not reported
    assert _recognised(_box("FRONT", 2.0) + "\n" + _box("BACK", 4.0)) == ["FRONT"]


def test_only_solids_with_recognition_colors_are_reported_even_unoccluded() -> None:
    # devices.md:210: only Solids with non-empty recognitionColors; a plain Solid in view is not reported
    assert _recognised(_box("PLAIN", 2.0, colours="") + "\n" + _box("SEEN", 2.0, y=1.0)) == ["SEEN"]
