"""A converted DistanceSensor reads in the MuJoCo twin what Webots' DistanceSensor reads (webots-devices §1):
Webots' rays over the aperture with their Gaussian weights (§1.2); generic, sonar and laser rays hitting only
boundingObjects outside the sensor's robot unless ``selfCollision`` (§1.3), a sonar's π/8 echo angle (§1.4);
infra-red rays hitting the Shapes, its robot's too, weighted by their reflection factor (§1.4). The MuJoCo
rangefinder of the same sensor is one ray that also hits visual geoms and the robot's other bodies and reads any
echo, so each world below that tests one of these rules read otherwise before the rays were written
(``webots_distance.<sensor>``, :mod:`dualtwin.twins.mujoco_rays`); the tests named "control" read the same.

Expected values are hand computations of those rules; each world is also read by the Webots twin (our ODE runtime,
the project's reference for Webots' behaviour). Tables are the identity in metres (``0 0 0, 1 1 0``: D = 1 m), so
a reading is the distance Webots feeds to its table.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

PERIOD = 0.008
METRES = "lookupTable [ 0 0 0, 1 1 0 ]"  # reading = distance, D = 1 m


def _world(sensor: str, scenery: str = "", *, part: str = "0 0 -1", self_collision: bool = False) -> str:
    """A welded robot at the origin carrying the DistanceSensor ``ds`` (``sensor``: its fields) looking along +x,
    and ``scenery``. Its hinged part (a 0.1 m box, the robot's other body) sits at ``part``; a GPS, the part's
    held motor and its PositionSensor give the robot a binding."""
    robot = (f'DEF R Robot {{ controller "<extern>" selfCollision {"TRUE" if self_collision else "FALSE"} '
             f'children [ GPS {{ name "gps" }} DistanceSensor {{ name "ds" {sensor} }} '
             "DEF H HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }\n"
             '  device [ PositionSensor { name "s" } RotationalMotor { name "m" } ]\n'
             f"  endPoint DEF E Solid {{ translation {part} physics Physics {{ }} "
             "boundingObject Box { size 0.1 0.1 0.1 } } } ] }")
    return world_text(f"{robot}\n{scenery}", "basicTimeStep 2 gravity 0")


def _wall(x: float, yaw: float = 0.0, name: str = "wall") -> str:
    """A 0.02 m thick, 2 m wide wall (a boundingObject) centred at (x, 0, 0), turned by ``yaw`` about z."""
    return (f'Solid {{ name "{name}" translation {x} 0 0 rotation 0 0 1 {yaw} '
            "boundingObject Box { size 0.02 2 2 } }")


def _read(tmp_path: Path, text: str) -> tuple[float, float]:
    """(Webots twin, MuJoCo twin) reading of ``ds`` after one period."""
    with converted_twins(text, tmp_path, PERIOD) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        return webots.sensor("ds"), mujoco_twin.sensor("ds")


def _both(tmp_path: Path, text: str, expected: float) -> None:
    # ODE's and MuJoCo's ray-box distances agree to rounding: 1e-9 m is far below any difference tested here.
    webots, mujoco_value = _read(tmp_path, text)
    assert webots == pytest.approx(expected, abs=1e-9), "webots"
    assert mujoco_value == pytest.approx(expected, abs=1e-9), "mujoco"


def test_a_multi_ray_generic_sensor_reads_the_weighted_mean_of_its_rays(tmp_path: Path) -> None:
    # numberOfRays 4 (§1.2): (α, k) = (0, 0) (the axis), then (0, 1), (2π/3, 1), (-2π/3, 1), the last three
    # θ = k·aperture/2 = 0.5 rad off the axis. Weights exp(-(θ/(aperture·gaussianWidth))²): 1 on the axis,
    # exp(-(0.5/1)²) = exp(-0.25) off it, normalised. A wall facing the sensor, its near face at x = a = 0.2:
    # the axis ray reads a, the others a/cos(0.5). Distance = a·(w0 + 3·w1/cos 0.5) = 0.219519... (one ray: 0.2).
    a, theta = 0.2, 0.5
    w1 = math.exp(-0.25)
    w0, w1 = 1.0 / (1.0 + 3.0 * w1), w1 / (1.0 + 3.0 * w1)
    expected = a * (w0 + 3.0 * w1 / math.cos(theta))
    _both(tmp_path, _world(f"numberOfRays 4 aperture 1 {METRES}", _wall(a + 0.01)), expected)


def test_the_rays_keep_webots_layout_in_the_site_frame(tmp_path: Path) -> None:
    # The same four rays, 0.5 rad off the axis: (0, 1) points up, (cos 0.5, 0, sin 0.5) (§1.2: α' = π/2), the
    # (±2π/3, 1) rays point down-left and down-right. A wall only above z = 0.01 (its near face at x = 0.5) is
    # hit by the up ray alone, at 0.5/cos 0.5 (z = 0.27 there); the others miss and count D = 1 m.
    w1 = math.exp(-0.25)
    w0, w1 = 1.0 / (1.0 + 3.0 * w1), w1 / (1.0 + 3.0 * w1)
    expected = w0 * 1.0 + w1 * 0.5 / math.cos(0.5) + 2.0 * w1 * 1.0
    upper = 'Solid { name "upper" translation 0.51 0 0.5 boundingObject Box { size 0.02 2 0.98 } }'
    _both(tmp_path, _world(f"numberOfRays 4 aperture 1 {METRES}", upper), expected)


def test_rays_pass_through_the_robots_other_bodies(tmp_path: Path) -> None:
    # The robot's hinged part (x from 0.15 to 0.25) is on the ray; Webots ignores same-robot pairs (§1.3), so the
    # ray reads the wall at 0.5 (MuJoCo's rangefinder excludes only the sensor's own body: it read 0.15).
    _both(tmp_path, _world(METRES, _wall(0.51), part="0.2 0 0"), 0.5)


def test_a_multi_ray_sensor_passes_the_robot_on_every_ray(tmp_path: Path) -> None:
    # Three rays (2π/3 apart, 0.3 rad off the axis, equal weights): each crosses the part (0.15 < x < 0.25) before
    # the wall at x = 0.5, reading 0.5/cos 0.3; their mean is the same.
    _both(tmp_path, _world(f"numberOfRays 3 aperture 0.6 {METRES}", _wall(0.51), part="0.2 0 0"),
          0.5 / math.cos(0.3))


def test_a_delayed_sensor_reads_the_rays_of_its_period(tmp_path: Path) -> None:
    # A sensor-delay knob reads the distance one period old from the twin's history: still Webots' rays (the wall
    # at 0.5 behind the robot's part), not the rangefinder's 0.15.
    text = _world(METRES, _wall(0.51), part="0.2 0 0")
    with converted_twins(text, tmp_path, PERIOD) as (_, _webots, mujoco_twin):
        mujoco_twin.set_knobs({"sensor.ds.delay": 1.0})
        mujoco_twin.step()
        mujoco_twin.step()
        assert mujoco_twin.sensor("ds") == pytest.approx(0.5, abs=1e-9)


def test_control_with_self_collision_the_robot_is_seen(tmp_path: Path) -> None:
    # Control: selfCollision TRUE keeps same-robot pairs (§1.3): the part's near face at 0.15.
    _both(tmp_path, _world(METRES, _wall(0.51), part="0.2 0 0", self_collision=True), 0.15)


def test_a_shape_without_bounding_object_is_not_seen(tmp_path: Path) -> None:
    # A visual-only box (no boundingObject) at 0.2: Webots' ODE rays collide with bounding objects only (§1.3), so
    # the wall at 0.5 is read (the rangefinder hit the visual geom at 0.15).
    shape = 'Solid { name "ghost" translation 0.2 0 0 children [ Shape { geometry Box { size 0.1 0.1 0.1 } } ] }'
    _both(tmp_path, _world(METRES, f"{shape}\n{_wall(0.51)}"), 0.5)


@pytest.mark.parametrize(("yaw", "expected"), [
    (0.5, 1.0),  # 0.5 rad > π/8 (0.3927) off the wall's normal: no echo, the distance is D
    (0.3, 0.5 - 0.01 / math.cos(0.3)),  # control, within π/8: the echo from the near face
])
def test_a_sonar_hears_only_surfaces_facing_it_within_pi_over_8(tmp_path: Path, yaw: float, expected: float) -> None:
    # The wall (centre x = 0.5) turned by ``yaw``: the ray meets its near face at incidence ``yaw``, at
    # x = 0.5 - 0.01/cos(yaw) (the face is 0.01 from the centre plane along the normal).
    _both(tmp_path, _world(f'type "sonar" {METRES}', _wall(0.5, yaw)), expected)


def test_the_rays_are_in_the_converted_model() -> None:
    # type group own D rays aperture gaussianWidth redColorSensitivity: a generic sensor (0) hitting collision geoms
    # (group 3), blind to its robot, 1 m long, Webots' default one ray over aperture 1.5708, gaussianWidth 1 and
    # redColorSensitivity 1.
    m = convert_world_text(_world(METRES), "t.wbt").compile()
    assert np.asarray(m.numeric("webots_distance.ds").data).tolist() == [0, 3, 1, 1, 1, 1.5708, 1, 1]
    # A laser of 3 rays (Webots: one, §1.1) on a selfCollision robot: type 3, not blind, one ray.
    laser = convert_world_text(_world(f'type "laser" numberOfRays 3 {METRES}', self_collision=True), "t.wbt")
    assert np.asarray(laser.compile().numeric("webots_distance.ds").data)[[0, 2, 4]].tolist() == [3, 0, 1]
    # Infra-red hits the visual geoms (group 2) and hides its robot's Shapes enclosing it even with selfCollision.
    ir = convert_world_text(_world(f'type "infra-red" {METRES}', self_collision=True), "t.wbt").compile()
    assert np.asarray(ir.numeric("webots_distance.ds").data)[:3].tolist() == [1, 2, 1]


def test_control_the_rangefinder_stays_for_plain_mujoco() -> None:
    # The converted model keeps its one-ray rangefinder (other MuJoCo programs read it): it still hits the part.
    twin = MuJoCoTwin(convert_world_text(_world(METRES, _wall(0.51), part="0.2 0 0"), "t.wbt").spec, PERIOD)
    twin.refresh()
    assert float(twin.data.sensordata[twin.model.sensor("ds").adr[0]]) == pytest.approx(0.15, abs=1e-9)


RED_WALL = ('Solid { name "red wall" translation 0.51 0 0 children [ Shape { '
            "appearance PBRAppearance { baseColor 0.5 0 0 } geometry Box { size 0.02 2 2 } } ] }")
HOUSING = "Shape { geometry Box { size 0.1 0.1 0.1 } }"  # the robot's body drawn around the sensor


def test_an_infra_red_sensor_reads_the_shapes_and_their_red(tmp_path: Path) -> None:
    # Infra-red rays hit Shapes (§1.4), not bounding objects: the robot's housing drawn around the sensor is not
    # seen (the Webots twin's rule for a Shape enclosing the sensor), a boundingObject-only box at 0.2 is not seen,
    # the wall's Shape is: each of the 3 rays (0.3 rad off the axis, equal weights) at d = 0.5/cos 0.3, its red 0.5
    # and roughness 0 (PBRAppearance's default) reflecting f = 0.2 + 0.8·0.5 = 0.6. Distance
    # d̄ + (d̄/f̄ − d̄)·redColorSensitivity with d̄ = 0.5/cos 0.3, f̄ = 0.6, sensitivity 1: d̄/0.6 = 0.8724...
    # (the rangefinder read the bounding box at 0.15).
    bounds_only = 'Solid { name "bounds" translation 0.2 0 0 boundingObject Box { size 0.1 0.1 0.1 } }'
    text = _world(f'type "infra-red" numberOfRays 3 aperture 0.6 {METRES}', f"{bounds_only}\n{RED_WALL}")
    text = text.replace('children [ GPS', f"children [ {HOUSING} GPS")
    _both(tmp_path, text, 0.5 / math.cos(0.3) / 0.6)


def test_an_infra_red_sensor_sees_its_robots_other_shapes(tmp_path: Path) -> None:
    # Webots' infra-red rays see the sensor's own robot (§1.4): the hinged part's Shape, near face at 0.15, drawn in
    # a Material of diffuseColor red 0.25: f = 0.2 + 0.8·0.25 = 0.4; one ray, redColorSensitivity 0.5:
    # 0.15 + (0.15/0.4 - 0.15)·0.5 = 0.2625.
    part = ("Shape { appearance Appearance { material Material { diffuseColor 0.25 1 1 } } "
            "geometry Box { size 0.1 0.1 0.1 } }")
    text = _world(f'type "infra-red" redColorSensitivity 0.5 {METRES}', RED_WALL.replace("0.51", "0.81"),
                  part="0.2 0 0")
    text = text.replace("physics Physics { } boundingObject", f"children [ {part} ] physics Physics {{ }} boundingObject")
    _both(tmp_path, text, 0.2625)


def test_infra_red_reflection_is_written_only_with_an_infra_red_sensor() -> None:
    # The red wall's visual geom gets its factor 0.6 (above) in a world with an infra-red sensor, nothing otherwise.
    def reflections(sensor: str) -> list[list[float]]:
        m = convert_world_text(_world(sensor, RED_WALL), "t.wbt").compile()
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_NUMERIC, i) for i in range(m.nnumeric)]
        return [np.asarray(m.numeric(n).data).tolist() for n in names if n.startswith("webots_reflection.")]

    assert reflections(f'type "infra-red" {METRES}') == [[pytest.approx(0.6)]]
    assert reflections(METRES) == []


@pytest.mark.parametrize("factor", [0.0, -0.5])
def test_a_reflection_factor_that_is_not_positive_is_not_read(factor: float) -> None:
    # Webots' factor is 0.2 + 0.8·red·(1 − 0.5·roughness), 0.2 to 1 (§1.4), and the distance divides by it: a hand-
    # edited model's 0 or negative factor is not Webots' and is not read (factor 1), as a malformed rays numeric is
    # not. One infra-red ray along +x to the red wall's near face at 0.51 − 0.01 = 0.5 m, f = 1: 0.5.
    spec = convert_world_text(_world(f'type "infra-red" {METRES}', RED_WALL), "t.wbt").spec
    edited = [n for n in spec.numerics if n.name.startswith("webots_reflection.")]
    assert len(edited) == 1
    edited[0].data = [factor]
    twin = MuJoCoTwin(spec, PERIOD)
    twin.step()
    assert twin.sensor("ds") == pytest.approx(0.5, abs=1e-9)
