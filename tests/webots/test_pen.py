"""Pen: the API keeps the pen's state in its fields (ink itself is visual only and not drawn headless)."""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation


def test_write_and_ink_colour(capsys: pytest.CaptureFixture[str]) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text('#VRML_SIM R2023b utf8\nRobot { children [ Pen { name "pen" } ] }\n'))
    pen = Robot(simulation=sim, robot_node=sim.robots[0].node).getDevice("pen")
    node = sim.robots[0].devices["pen"].node
    assert node.fields["write"] is True
    pen.write(False)
    assert node.fields["write"] is False
    pen.setInkColor(0xFF8000, 0.25)
    assert node.fields["inkColor"] == pytest.approx((1.0, 128 / 255, 0.0))
    assert node.fields["inkDensity"] == 0.25
    pen.setInkColor(0xFF8000, 2.0)  # density above 1: refused
    assert node.fields["inkDensity"] == 0.25
    assert "out of range" in capsys.readouterr().err
