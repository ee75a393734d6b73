"""LightSensor: irradiance from the world's lights with Webots' formula (attenuation, spot cone, cos θ,
colour filter, occlusion), through the lookup table. Expected values are worked out by hand in each test."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation

UP = "rotation 0 1 0 -1.5707963"  # the sensor's x axis (its optical axis) points up, +z


def _robot(lights: str, sensor: str = "", extra: str = "") -> Robot:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 }}
{lights}
{extra}
Robot {{ children [ LightSensor {{ name "ls" {sensor} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node)


def _read(robot: Robot) -> float:
    ls = robot.getDevice("ls")
    ls.enable(16)
    robot.step(16)
    return float(ls.getValue())


def test_point_light_overhead_with_quadratic_attenuation() -> None:
    # E = intensity · cos 0 / (a3 · d²) = 0.5 / (1 · 1²) = 0.5; default table ×1000
    light = "PointLight { location 0 0 1 attenuation 0 0 1 intensity 0.5 }"
    assert _read(_robot(light, UP)) == pytest.approx(500.0, abs=1e-6)


def test_tilted_sensor_reads_the_cosine() -> None:
    # optical axis 60° from the light direction: cos 60° = 0.5 -> 250
    light = "PointLight { location 0 0 1 attenuation 0 0 1 intensity 0.5 }"
    assert _read(_robot(light, "rotation 0 1 0 -0.5235988")) == pytest.approx(250.0, abs=1e-4)


def test_light_behind_the_sensor_gives_nothing() -> None:
    light = "PointLight { location 0 0 1 attenuation 0 0 1 intensity 0.5 }"
    assert _read(_robot(light, "rotation 0 1 0 1.5707963")) == pytest.approx(0.0, abs=1e-9)


def test_directional_light_and_colour_filter() -> None:
    light = "DirectionalLight { direction 0 0 -1 intensity 0.8 }"
    assert _read(_robot(light, UP)) == pytest.approx(800.0, abs=1e-6)
    # a red filter lets one channel of white light in three through
    assert _read(_robot(light, UP + " colorFilter 1 0 0")) == pytest.approx(800.0 / 3, abs=1e-6)


def test_spot_light_falls_off_linearly_between_beam_width_and_cut_off() -> None:
    # sensor 0.3 rad off the spot's axis at 1 m height: spot = (0.5 - 0.3) / (0.5 - 0.1) = 0.5, cos θ = cos 0.3
    x = math.tan(0.3)
    light = "SpotLight { location 0 0 1 direction 0 0 -1 beamWidth 0.1 cutOffAngle 0.5 }"
    robot = _robot(light, UP + f" translation {x} 0 0")
    assert _read(robot) == pytest.approx(1000 * 0.5 * math.cos(0.3), abs=1e-3)
    # outside the cut-off angle nothing arrives
    far = _robot(light, UP + f" translation {math.tan(0.6)} 0 0")
    assert _read(far) == pytest.approx(0.0, abs=1e-9)


def test_occlusion_by_a_bounding_object() -> None:
    light = "PointLight { location 0 0 1 attenuation 0 0 1 intensity 0.5 }"
    wall = "Solid { translation 0 0 0.5 boundingObject Box { size 1 1 0.01 } }"
    assert _read(_robot(light, UP, wall)) == pytest.approx(500.0, abs=1e-6)  # occlusion FALSE: ignored
    assert _read(_robot(light, UP + " occlusion TRUE", wall)) == pytest.approx(0.0, abs=1e-9)


def test_lookup_table_and_light_on_a_moving_solid() -> None:
    # the light rides on a Solid 2 m up: E = 1 / 2² = 0.25 -> table [0 0 0, 1 10 0] gives 2.5
    solid = "Solid { translation 0 0 2 children [ PointLight { attenuation 0 0 1 } ] }"
    ls = _robot(solid, UP + " lookupTable [ 0 0 0, 1 10 0 ]")
    assert _read(ls) == pytest.approx(2.5, abs=1e-6)
    assert ls.getDevice("ls").getLookupTable() == [0.0, 0.0, 0.0, 1.0, 10.0, 0.0]
