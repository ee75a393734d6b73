"""LED: set/get with Webots' value rules (colour index, or 0xRRGGBB when gradual); no physics."""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation


def _led(fields: str) -> object:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 }}
Robot {{ children [ LED {{ name "led" {fields} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node).getDevice("led")


def test_indexed_colours(capsys: pytest.CaptureFixture[str]) -> None:
    led = _led("color [ 1 0 0, 0 1 0 ]")
    assert led.get() == 0  # off at start
    led.set(2)
    assert led.get() == 2 and led.value == 2
    led.set(3)  # only two colours: refused, value kept
    assert led.get() == 2
    assert "out of range" in capsys.readouterr().err
    led.value = 0
    assert led.get() == 0


def test_gradual_takes_an_rgb_value() -> None:
    led = _led("gradual TRUE")
    led.set(0x00FF80)
    assert led.get() == 0x00FF80
