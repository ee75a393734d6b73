"""Compass: the north of the world's coordinateSystem, in the device frame."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation


def _values(system: str, compass: str) -> list[float]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ coordinateSystem "{system}" basicTimeStep 16 }}
Robot {{ children [ Compass {{ name "c" {compass} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    robot = Robot(simulation=sim, robot_node=sim.robots[0].node)
    c = robot.getDevice("c")
    c.enable(16)
    robot.step(16)
    return list(c.getValues())


def test_north_per_coordinate_system() -> None:
    assert _values("ENU", "") == pytest.approx([0, 1, 0], abs=1e-9)  # north is +y
    assert _values("NUE", "") == pytest.approx([1, 0, 0], abs=1e-9)  # north is +x
    assert _values("EUN", "") == pytest.approx([0, 0, 1], abs=1e-9)  # north is +z


def test_north_in_the_device_frame() -> None:
    # a compass turned 90° to the left about ENU's up axis: its x axis now points north, (1, 0, 0)
    assert _values("ENU", "rotation 0 0 1 1.5707963") == pytest.approx([1, 0, 0], abs=1e-6)
    # tilted 30° nose up about y: the north (+y) is unchanged in the device frame
    assert _values("ENU", "rotation 0 1 0 0.5235988") == pytest.approx([0, 1, 0], abs=1e-6)


def test_disabled_axis_and_lookup_table() -> None:
    v = _values("NUE", "yAxis FALSE lookupTable [ -1 -100 0, 1 100 0 ]")
    assert v[0] == pytest.approx(100.0) and math.isnan(v[1]) and v[2] == pytest.approx(0.0, abs=1e-9)
