"""A Robot inside top-level grouping nodes (Group, Pose, Transform) is a robot of the world, as in Webots and the Webots
twin (which finds every Robot of the scene tree); the converter found only top-level Robots ("world has no robot").
Its world pose is the product of its ancestors' frames (on-ODE §3.1), a Transform's uniform scale scaling it as the
converter scales the environment below a Transform.

Hand computation (NESTED): the Pose at (1, 2, 0) turned +90 deg about z takes the Transform's (0.5, 0, 0) to
(1, 2 + 0.5, 0); the robot's (0, 0, 0.3) keeps its z: the robot starts at (1, 2.5, 0.3), turned pi/2 + 0.5 about z.
Its 0.2 m cube, dropped 0.2 m onto the floor, rests with its centre at z = 0.1, x and y unchanged.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.convert.world_robots import find_robots
from dualtwin.webots.protos import load_world_text
from tests.support.converted_twins import converted_twins, world_text

FLOOR = "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }\n"
CUBE = ('controller "<extern>" children [ GPS { name "gps" } ] boundingObject Box { size 0.2 0.2 0.2 } '
        "physics Physics { density -1 mass 1 }")
NESTED = world_text(
    FLOOR + "Group { children [ Pose { translation 1 2 0 rotation 0 0 1 1.5707963267948966 children [\n"
    "  Transform { translation 0.5 0 0 children [\n"
    f"    DEF R Robot {{ translation 0 0 0.3 rotation 0 0 1 0.5 {CUBE} }} ] }} ] }} ] }}", "basicTimeStep 4")
START = np.array([1.0, 2.5, 0.3])
YAW = math.pi / 2 + 0.5


def test_a_robot_in_grouping_nodes_is_found_and_placed_in_the_world() -> None:
    conv = convert_world_text(NESTED, "nested.wbt")
    assert conv.robot == "R" and conv.free_base
    body = conv.compile().body("R")
    assert np.allclose(body.pos, START, atol=1e-9)
    # quaternion of a turn by YAW about z
    assert np.allclose(body.quat, [math.cos(YAW / 2), 0, 0, math.sin(YAW / 2)], atol=1e-9)


def test_a_robot_inside_a_solid_is_part_of_that_solid_not_a_robot_of_the_world() -> None:
    world = load_world_text(world_text("DEF S Solid { children [ DEF INNER Robot { } ] }\n"
                                       "Pose { children [ Group { children [ DEF R Robot { } ] } ] }"), "w.wbt")
    assert [r.def_name for r in find_robots(world)] == ["R"]


def test_a_transform_scale_above_the_robot_scales_it() -> None:
    # Transform at (1, 0, 0), scale 2: the robot's (0, 0, 0.5) lands at (1, 0, 1.0); its 0.2 m box becomes 0.4 m
    # (MuJoCo's box size is the half extent: 0.2).
    conv = convert_world_text(world_text(FLOOR + "Transform { translation 1 0 0 scale 2 2 2 children [\n"
                                         f"  DEF R Robot {{ translation 0 0 0.5 {CUBE} }} ] }}"), "scaled.wbt")
    model = conv.compile()
    assert np.allclose(model.body("R").pos, [1.0, 0.0, 1.0], atol=1e-12)
    assert np.allclose(model.geom("R").size, [0.2, 0.2, 0.2], atol=1e-12)


def test_a_non_uniform_scale_above_the_robot_acts_as_its_largest_factor_with_one_warning() -> None:
    # as in the Webots twin (webots.solid_scale.body_factor): the cube's 0.2 m becomes 0.4 m, and one warning says why
    text = world_text(f"Transform {{ scale 1 2 1 children [ DEF R Robot {{ {CUBE} }} ] }}")
    conv = convert_world_text(text, "w.wbt")
    assert np.allclose(conv.compile().geom("R").size, [0.2, 0.2, 0.2], atol=1e-12)
    assert sum("Transform scale 1 2 1 is not uniform above a Solid or joint: scaled by its largest factor 2" in w
               for w in conv.warnings) == 1


def test_both_twins_start_the_nested_robot_at_its_world_pose_and_drop_it_on_the_floor(tmp_path: Path) -> None:
    with converted_twins(NESTED, tmp_path, 0.02) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            assert twin.body_position("R") == pytest.approx(START, abs=1e-6), twin.name
            assert twin.sensor("gps") == pytest.approx(START[0], abs=1e-6), twin.name  # GPS x
        for _ in range(40):  # 0.8 s: the 0.2 m drop takes 0.2 s
            webots.step()
            mujoco_twin.step()
        for twin in (webots, mujoco_twin):
            assert twin.body_position("R") == pytest.approx([*START[:2], 0.1], abs=3e-3), twin.name
            heading = twin.body_orientation("R") @ np.array([1.0, 0.0, 0.0])
            assert math.atan2(heading[1], heading[0]) == pytest.approx(YAW, abs=1e-3), twin.name
