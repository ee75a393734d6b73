"""Composite: a LightSensor and a light mounted in a turned Solid (the light's frame meets the sensor's).

Webots' DirectionalLight reference page: its ``direction`` is "in the global coordinate system" (unlike VRML,
where it is in the parent's frame); a PointLight's ``location`` is in its parent's frame and the lamp moves with
the Solid carrying it. Before this test the twin turned a DirectionalLight's direction by the Solid it sits in.

The LightSensor (its x axis up) reads ``1000·E`` through the default table ``[0 0 0, 1 1000 0]``, with
``E = intensity·cos θ·attenuation``, θ between the sensor's axis and the direction to the light (light_sensor.py).
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation

UP = "rotation 0 1 0 -1.5707963267948966"  # the sensor's x axis points up, +z
TURNED = "translation 0 0 1 rotation 0 1 0 1.5707963267948966"  # a quarter turn about y: its -z is the world's -x


def _reading(lights: str) -> float:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 }}
{lights}
Robot {{ children [ LightSensor {{ name "ls" {UP} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    robot = Robot(simulation=sim, robot_node=sim.robots[0].node)
    sensor = robot.getDevice("ls")
    sensor.enable(16)
    robot.step(16)
    return float(sensor.getValue())


def test_a_directional_light_in_a_turned_solid_shines_along_its_world_direction() -> None:
    # direction 0 0 -1 is the world's down wherever the node sits: straight onto the up-facing sensor, cos 0 = 1,
    # E = 0.8. (Turned with its Solid it would shine along -x, at 90° to the sensor's axis: 0.)
    assert _reading(f"Solid {{ {TURNED} children [ DirectionalLight {{ direction 0 0 -1 intensity 0.8 }} ] }}") == (
        pytest.approx(800.0, abs=1e-6))
    # the same light under a turned Pose inside the Solid: still the world's down
    assert _reading(f"Solid {{ children [ Pose {{ {TURNED} children [ DirectionalLight {{ direction 0 0 -1 "
                    "intensity 0.8 } ] } ] }") == pytest.approx(800.0, abs=1e-6)
    # control: a world-level light reads the same
    assert _reading("DirectionalLight { direction 0 0 -1 intensity 0.8 }") == pytest.approx(800.0, abs=1e-6)


def test_a_point_light_in_a_turned_solid_still_rides_with_it() -> None:
    # control of the other rule: location 0 0 1 in the Solid at (0, 0, 1) turned about y is the world point (1, 0, 1):
    # d = √2, cos θ = 1/√2, attenuation 1/d² -> E = (1/√2)/2, 1000·E = 353.55
    lamp = f"Solid {{ {TURNED} children [ PointLight {{ location 0 0 1 attenuation 0 0 1 }} ] }}"
    assert _reading(lamp) == pytest.approx(1000 / (2 * math.sqrt(2)), abs=1e-4)
