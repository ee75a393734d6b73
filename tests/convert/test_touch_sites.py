"""A TouchSensor's MuJoCo touch site covers its boundingObject (:mod:`dualtwin.convert.touch_sites`).

MuJoCo's ``touch`` counts only contacts whose point lies inside its site; the converter wrote a 2 cm sphere at the
sensor's origin, so a sensor box resting on the floor (contacts on its bottom face, 5 cm below the origin) read 0
where Webots senses the contact (webots-devices §2.3). Expected values are hand computations: the site is the box
enclosing the boundingObject grown by TOUCH_MARGIN, and a robot resting on its sensor presses it with its weight.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.convert.touch_sites import TOUCH_MARGIN
from tests.support.converted_twins import converted_twins, world_text

SENSOR = ('TouchSensor {{ name "t" translation 0 0 -0.3 boundingObject {bounds} '
          'physics Physics {{ density -1 mass 2 }} }}')
BOX = "Box { size 0.2 0.2 0.1 }"


def _world(z: float, bounds: str = BOX) -> str:
    return world_text(
        'Solid { name "floor" boundingObject Plane { size 10 10 } }\n'
        f'DEF R Robot {{ translation 0 0 {z} controller "<extern>" children [ {SENSOR.format(bounds=bounds)} '
        'DEF H HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } device [ PositionSensor { name "s" } ] '
        'endPoint DEF E Solid { translation 0 0.1 0 '
        'physics Physics { density -1 mass 0.5 } boundingObject Sphere { radius 0.05 } } } ] '
        "boundingObject Box { size 0.3 0.3 0.1 } physics Physics { density -1 mass 5 } }", "basicTimeStep 4")


def _site(bounds: str) -> tuple[list[float], list[float], int]:
    model = convert_world_text(_world(1.0, bounds), "t.wbt").compile()
    site = model.site("t")
    return [float(v) for v in site.pos], [float(v) for v in site.size], int(site.type[0])


def test_the_site_is_the_bounding_box_grown_by_the_margin() -> None:
    # A box 0.2 x 0.2 x 0.1 at the sensor's origin (0, 0, -0.3 in the robot's body): half sizes + 5 mm.
    pos, size, kind = _site(BOX)
    assert pos == pytest.approx([0.0, 0.0, -0.3], abs=1e-9) and kind == int(mujoco.mjtGeom.mjGEOM_BOX)
    assert size == pytest.approx([0.1 + TOUCH_MARGIN, 0.1 + TOUCH_MARGIN, 0.05 + TOUCH_MARGIN], abs=1e-9)
    # A capsule (radius 0.02, cylinder 0.1 long, along z) moved 0.1 along x: x in [0.08, 0.12], z in [-0.07, 0.07].
    pos, size, _ = _site("Pose { translation 0.1 0 0 children [ Capsule { radius 0.02 height 0.1 } ] }")
    assert pos == pytest.approx([0.1, 0.0, -0.3], abs=1e-9)
    assert size == pytest.approx([0.02 + TOUCH_MARGIN, 0.02 + TOUCH_MARGIN, 0.07 + TOUCH_MARGIN], abs=1e-9)


def test_a_sensor_resting_on_the_floor_is_touched_in_both_twins(tmp_path: Path) -> None:
    # The robot stands on its sensor's box (bottom at z = 0.35 - 0.3 - 0.05 = 0): once settled, MuJoCo's touch
    # reads the normal force carrying the whole robot, (5 + 2 + 0.5) kg x 9.81 = 73.575 N, and Webots' bumper 1.
    with converted_twins(_world(0.35), tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(60):
            webots.step()
            mujoco_twin.step()
        assert mujoco_twin.sensor("t") == pytest.approx(7.5 * 9.81, rel=0.01)
        assert webots.sensor("t") == 1.0


def test_a_sensor_in_the_air_is_not(tmp_path: Path) -> None:
    with converted_twins(_world(1.0), tmp_path, 0.008) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        assert mujoco_twin.sensor("t") == 0.0 and webots.sensor("t") == 0.0
