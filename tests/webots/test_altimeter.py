"""Altimeter: the device's coordinate along the world's up axis (z in ENU, y in NUE), with resolution."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation


def _altimeter(system: str, robot: str, device: str = "") -> tuple[Robot, object]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ coordinateSystem "{system}" basicTimeStep 16 }}
Robot {{ {robot} children [ Altimeter {{ name "alt" translation 0 0 0.5 {device} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    r = Robot(simulation=sim, robot_node=sim.robots[0].node)
    return r, r.getDevice("alt")


def _value(system: str, robot: str, device: str = "") -> float:
    r, alt = _altimeter(system, robot, device)
    assert math.isnan(alt.getValue())  # nothing sampled before the first step
    alt.enable(16)
    r.step(16)
    return float(alt.getValue())


def test_altitude_along_the_up_axis() -> None:
    assert _value("ENU", "translation 3 4 1") == pytest.approx(1.5)  # robot z 1 + device 0.5 up
    # NUE: up is y; the device's 0.5 offset along z is horizontal there
    assert _value("NUE", "translation 3 2 4") == pytest.approx(2.0)


def test_resolution() -> None:
    assert _value("ENU", "translation 0 0 1.3", "resolution 0.5") == pytest.approx(2.0)  # 1.8 m -> nearest 0.5
