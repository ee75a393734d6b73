"""DistanceSensor, Lidar and RangeFinder read what Webots would in scenes whose answer is known analytically.

The wall is a box whose face lies at x = 0.5 m in front of the sensor; every expected value below is computed
here from that geometry and Webots' documented formulas, not from the implementation.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.rays import RayCaster, cast_ode

# a wall drawn and collided alike: ray sensors hit bounding objects, lidars and infra-red sensors visual Shapes
WALL = "Solid { translation 0.55 0 0.1 children [ Shape { geometry DEF WALL_BOX Box { size 0.1 4 4 } } ] boundingObject USE WALL_BOX }"


def _world(devices: str, wall: str = WALL, robot_extra: str = "") -> Supervisor:
    text = (
        "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 randomSeed 3 }\n"
        f"{wall}\n"
        f"Robot {{ translation 0 0 0.1 supervisor TRUE {robot_extra} children [ {devices} ] }}\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _interp(table: list[tuple[float, float]], x: float) -> float:
    for (x0, y0), (x1, y1) in zip(table, table[1:], strict=False):
        if x0 <= x <= x1:
            return y0 + (x - x0) / (x1 - x0) * (y1 - y0)
    return table[-1][1] if x > table[-1][0] else table[0][1]


def _read(sup: Supervisor, name: str, steps: int = 1) -> float:
    dev = sup.getDevice(name)
    dev.enable(8)
    assert math.isnan(dev.getValue())  # NaN before the first sample
    for _ in range(steps):
        sup.step(8)
    return dev.getValue()


@pytest.mark.parametrize(
    "table",
    [
        [(0.0, 0.0), (1.0, 1000.0)],
        [(0.0, 4095.0), (0.05, 2000.0), (1.0, 0.0)],  # decreasing, e-puck-like
        [(0.0, 0.0), (0.2, 10.0), (0.7, 80.0), (2.0, 90.0)],
    ],
)
def test_generic_single_ray_reads_the_lookup_table_at_the_wall(table: list[tuple[float, float]]) -> None:
    lut = ", ".join(f"{x} {y} 0" for x, y in table)
    sup = _world(f'DistanceSensor {{ name "ds" lookupTable [ {lut} ] }}')
    assert _read(sup, "ds") == pytest.approx(_interp(table, 0.5), rel=1e-9, abs=1e-9)


def test_nothing_in_range_reads_the_last_output_and_empty_table_zero() -> None:
    sup = _world(
        'DistanceSensor { name "short" lookupTable [ 0 7 0, 0.3 1234 0 ] } '
        'DistanceSensor { name "empty" lookupTable [ ] }'
    )
    assert _read(sup, "short") == 1234.0
    assert _read(sup, "empty") == 0.0


@pytest.mark.parametrize("aperture", [0.4, 1.0])
def test_generic_three_rays_on_the_aperture_cone(aperture: float) -> None:
    # Webots' 3-ray layout puts all three rays at half the aperture off axis, with equal weights
    sup = _world(
        f'DistanceSensor {{ name "ds" numberOfRays 3 aperture {aperture} lookupTable [ 0 0 0, 2 2 0 ] }}'
    )
    assert _read(sup, "ds") == pytest.approx(0.5 / math.cos(aperture / 2), rel=1e-9)


def test_generic_four_rays_gaussian_weights() -> None:
    aperture, width = 0.8, 0.7
    sup = _world(
        f'DistanceSensor {{ name "ds" numberOfRays 4 aperture {aperture} gaussianWidth {width} '
        "lookupTable [ 0 0 0, 2 2 0 ] }"
    )
    # one central ray (weight 1) and three at aperture/2 (weight exp(-(θ/(aperture·width))²))
    theta = aperture / 2
    w = math.exp(-((theta / (aperture * width)) ** 2))
    expected = (0.5 + 3 * w * 0.5 / math.cos(theta)) / (1 + 3 * w)
    assert _read(sup, "ds") == pytest.approx(expected, rel=1e-9)


def test_infra_red_reads_like_generic_on_a_white_wall_and_laser_reads_one_ray() -> None:
    sup = _world(
        'DistanceSensor { name "ir" type "infra-red" numberOfRays 3 aperture 0.6 lookupTable [ 0 0 0, 2 2 0 ] } '
        'DistanceSensor { name "laser" type "laser" numberOfRays 5 lookupTable [ 0 0 0, 2 2 0 ] }'
    )
    assert _read(sup, "ir") == pytest.approx(0.5 / math.cos(0.3), rel=1e-9)
    assert _read(sup, "laser") == pytest.approx(0.5, rel=1e-9)
    assert sup.getDevice("ir").getType() == 1 and sup.getDevice("laser").getType() == 3


@pytest.mark.parametrize("yaw, echoes", [(0.3, True), (0.45, False)])
def test_sonar_echo_only_from_a_surface_facing_the_ray(yaw: float, echoes: bool) -> None:
    # the sensor turned by yaw meets the wall at incidence yaw: an echo returns below π/8 (0.3927 rad)
    sup = _world(
        f'DistanceSensor {{ name "sonar" type "sonar" rotation 0 0 1 {yaw} lookupTable [ 0 0 0, 2 2000 0 ] }}'
    )
    expected = 1000.0 * 0.5 / math.cos(yaw) if echoes else 2000.0
    assert _read(sup, "sonar") == pytest.approx(expected, rel=1e-9)
    # an unknown type string is a sonar in Webots
    other = _world('DistanceSensor { name "x" type "ultrasound" }')
    assert other.getDevice("x").getType() == 2


def test_resolution_and_multiplicative_noise() -> None:
    sup = _world(
        'DistanceSensor { name "res" resolution 7 lookupTable [ 0 0 0, 1 1000 0 ] } '
        'DistanceSensor { name "noisy" lookupTable [ 0 0 0.1, 1 1000 0.1 ] }'
    )
    assert _read(sup, "res") == 497.0  # int(500/7 + 0.5)·7
    noisy = sup.getDevice("noisy")
    noisy.enable(8)
    values = []
    for _ in range(400):
        sup.step(8)
        values.append(noisy.getValue())
    assert np.mean(values) == pytest.approx(500.0, rel=0.02)
    assert np.std(values) == pytest.approx(50.0, rel=0.15)  # σ = 0.1 · 500


def test_own_robot_is_invisible_unless_self_collision() -> None:
    body = "boundingObject Box { size 0.3 0.3 0.3 }"
    dev = 'DistanceSensor { name "ds" lookupTable [ 0 0 0, 1 1000 0 ] }'
    assert _read(_world(dev, robot_extra=body), "ds") == pytest.approx(500.0)
    # with selfCollision the ray, starting inside the robot's box, reports the box's far face (ODE's rule)
    assert _read(_world(dev, robot_extra=body + " selfCollision TRUE"), "ds") == pytest.approx(150.0)


def test_sampling_period_decides_when_rays_are_cast() -> None:
    sup = _world('DistanceSensor { name "ds" lookupTable [ 0 0 0, 1 1000 0 ] }')
    ds = sup.getDevice("ds")
    ds.enable(32)
    sup.step(8)
    assert math.isnan(ds.getValue())  # first sample after one sampling period
    sup.step(24)
    assert ds.getValue() == pytest.approx(500.0)


# ------------------------------------------------------------------------------------------ lidar, range finder


def test_cylindrical_lidar_euclidean_and_point_cloud() -> None:
    # 3 layers need verticalFieldOfView·horizontalResolution/fieldOfView ≥ 3 (webots-devices.md §3.1): 0.4·9/1
    fov, vfov, width, layers = 1.0, 0.4, 9, 3
    sup = _world(
        f'Lidar {{ name "lidar" horizontalResolution {width} fieldOfView {fov} verticalFieldOfView {vfov} '
        f'numberOfLayers {layers} maxRange 0.54 projection "cylindrical" }}'
    )
    lidar = sup.getDevice("lidar")
    lidar.enable(8)
    lidar.enablePointCloud()
    sup.step(8)
    image = np.array(lidar.getRangeImageArray())
    assert image.shape == (layers, width)
    for i in range(layers):
        phi = vfov / 2 - i * vfov / (layers - 1)
        for j in range(width):
            theta = fov / 2 - (j + 0.5) * fov / width
            r = 0.5 / (math.cos(theta) * math.cos(phi))
            expected = r if r < 0.54 else math.inf  # beyond maxRange: +inf
            assert image[i, j] == pytest.approx(expected, rel=1e-9)
    assert np.isinf(image).any() and np.isfinite(image).any()
    points = [p for p in lidar.getPointCloud() if math.isfinite(p.x)]
    assert points and all(p.x == pytest.approx(0.5, rel=1e-9) for p in points)
    assert lidar.getNumberOfPoints() == width * layers
    assert lidar.getLayerRangeImage(2) == image[2].tolist()


def test_planar_lidar_and_range_finder_read_depth() -> None:
    sup = _world(
        'Lidar { name "lidar" horizontalResolution 16 fieldOfView 1.2 numberOfLayers 1 maxRange 2 '
        'projection "planar" } '
        'RangeFinder { name "rf" width 8 height 6 fieldOfView 1.0 maxRange 2 }'
    )
    lidar, rf = sup.getDevice("lidar"), sup.getDevice("rf")
    assert lidar.getRangeImage() == [0.0] * 16  # before the first sample
    lidar.enable(8)
    rf.enable(8)
    sup.step(8)
    assert lidar.getRangeImage() == pytest.approx([0.5] * 16, rel=1e-9)
    assert rf.getRangeImage() == pytest.approx([0.5] * 48, rel=1e-9)
    assert np.array(rf.getRangeImageArray()).shape == (6, 8)


def test_range_finder_min_range_and_wall_edge() -> None:
    # a narrow wall covering only the left half of the image: the right half sees nothing (+inf)
    wall = "Solid { translation 0.55 1 0.1 children [ Shape { geometry Box { size 0.1 2 4 } } ] }"
    sup = _world('RangeFinder { name "rf" width 4 height 2 fieldOfView 1.0 maxRange 3 }', wall=wall)
    rf = sup.getDevice("rf")
    rf.enable(8)
    sup.step(8)
    image = np.array(rf.getRangeImageArray())
    assert image[:, :2] == pytest.approx(np.full((2, 2), 0.5))
    assert np.isinf(image[:, 2:]).all()
    near = _world('RangeFinder { name "rf" width 2 height 2 minRange 0.6 maxRange 3 }')
    dev = near.getDevice("rf")
    dev.enable(8)
    near.step(8)
    assert np.isinf(dev.getRangeImage()).all()  # closer than minRange: +inf


def test_vectorised_rays_match_ode_ray_collider() -> None:
    text = """#VRML_SIM R2023b utf8
WorldInfo { }
Solid { translation 0.3 0.1 0.2 rotation 0.3 0.5 0.8 0.7 boundingObject Box { size 0.4 0.2 0.3 } }
Solid { translation -0.5 0.2 0.1 rotation 1 0 0 0.4 boundingObject Cylinder { radius 0.15 height 0.4 } }
Solid { translation 0.1 -0.6 0.1 rotation 0 1 0 0.9 boundingObject Capsule { radius 0.1 height 0.3 } }
Solid { translation 0.1 0.6 -0.1 boundingObject Sphere { radius 0.2 } }
Solid { translation 0 0 -0.5 rotation 1 0 0 0.2 boundingObject Plane { } }
Solid { translation -0.4 -0.3 -0.2 rotation 0 0 1 0.6 boundingObject Box { size 0.2 0.3 0.1 } }
Solid { translation 0.6 0.6 0.4 boundingObject Sphere { radius 0.1 } }
"""
    sim = Simulation(load_world_text(text))
    rng = np.random.default_rng(1)
    n = 1500
    origins = rng.uniform(-0.9, 0.9, (n, 3))  # many start inside a geom
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    caster = RayCaster(sim)
    for geom in sim.geoms.values():
        fast = caster.cast(origins, dirs, 2.0, [geom])
        ref = cast_ode(origins, dirs, np.full(n, 2.0), [geom])
        assert np.isfinite(ref.distance).sum() > 4, geom.kind
        np.testing.assert_allclose(fast.distance, ref.distance, atol=1e-9, err_msg=geom.kind)
        hit = np.isfinite(ref.distance)
        np.testing.assert_allclose(fast.normal[hit], ref.normal[hit], atol=1e-7, err_msg=geom.kind)
    # all geoms at once, per-ray lengths: the nearest hit and which geom it is
    geoms = list(sim.geoms.values())
    lengths = rng.uniform(0.2, 2.0, n)
    fast = caster.cast(origins, dirs, lengths, geoms)
    ref = cast_ode(origins, dirs, lengths, geoms)
    np.testing.assert_allclose(fast.distance, ref.distance, atol=1e-9)
    hit = np.isfinite(ref.distance)
    assert fast.geom == ref.geom and hit.sum() > 300
    np.testing.assert_allclose(fast.normal[hit], ref.normal[hit], atol=1e-7)
    sim.close()


def test_sensors_on_a_moving_spinning_robot_follow_its_body() -> None:
    # zero gravity; the robot translates toward the wall and spins about z; the sensor sits 0.1 m ahead
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 gravity 0 }
Solid { translation 0.55 0 0 children [ Shape { geometry DEF W Box { size 0.1 40 4 } } ] boundingObject USE W }
DEF R Robot { supervisor TRUE boundingObject Sphere { radius 0.05 } physics Physics { mass 1 }
  children [
    DistanceSensor { name "ds" translation 0.1 0 0 lookupTable [ 0 0 0, 2 2 0 ] }
    Lidar { name "lidar" translation 0.1 0 0 horizontalResolution 3 fieldOfView 0.6 numberOfLayers 1 maxRange 2 }
  ]
}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    robot = sup.getFromDef("R")
    robot.setVelocity([0.2, 0.0, 0.0, 0.0, 0.0, 0.4])
    ds, lidar = sup.getDevice("ds"), sup.getDevice("lidar")
    ds.enable(8)
    lidar.enable(8)
    checked = 0
    for k in range(100):
        sup.step(8)
        if k % 20 != 19:
            continue
        x, y, _ = robot.getPosition()
        R = robot.getOrientation()
        yaw = math.atan2(R[3], R[0])
        sx = x + 0.1 * math.cos(yaw)  # the sensor's x in the world
        assert ds.getValue() == pytest.approx((0.5 - sx) / math.cos(yaw), rel=1e-6)
        # lidar columns at +0.2, 0, -0.2 rad from the sensor axis (fov/2 - (j+1/2)·fov/W)
        for j, offset in enumerate((0.2, 0.0, -0.2)):
            assert lidar.getRangeImage()[j] == pytest.approx((0.5 - sx) / math.cos(yaw + offset), rel=1e-6)
        checked += 1
    assert checked == 5
    sim.close()


def test_meshes_and_height_fields_are_hit_through_ode_rays() -> None:
    # a triangle-mesh wall (its face at x = 0.5) in front, a box wall farther: the nearer mesh wins
    mesh = (
        "Solid { translation 0.5 0 0.1 boundingObject IndexedFaceSet { coord Coordinate { point "
        "[ 0 -1 -1, 0 1 -1, 0 1 1, 0 -1 1, 0.2 -1 -1, 0.2 1 -1, 0.2 1 1, 0.2 -1 1 ] } "
        "coordIndex [ 0 3 2 1 -1 4 5 6 7 -1 0 1 5 4 -1 2 3 7 6 -1 0 4 7 3 -1 1 2 6 5 -1 ] } }\n"
        "Solid { translation 0.95 0 0.1 boundingObject Box { size 0.1 4 4 } }"
    )
    sup = _world('DistanceSensor { name "ds" lookupTable [ 0 0 0, 2 2 0 ] }', wall=mesh)
    assert _read(sup, "ds") == pytest.approx(0.5, rel=1e-9)
    # a height field (x-y grid, heights along z) 0.1 m below a downward-looking sensor
    grid = (
        "Solid { translation -1 -1 0 boundingObject ElevationGrid { xDimension 3 yDimension 3 "
        "xSpacing 1 ySpacing 1 height [ 0 0 0 0 0 0 0 0 0 ] } }"
    )
    down = _world(
        'DistanceSensor { name "ds" rotation 0 1 0 1.5708 lookupTable [ 0 0 0, 2 2 0 ] }', wall=grid
    )
    geoms = [g.kind for g in down.simulation.geoms.values()]
    assert "ElevationGrid" in geoms
    assert _read(down, "ds") == pytest.approx(0.1, rel=1e-6)
