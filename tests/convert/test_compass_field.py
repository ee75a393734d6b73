"""A Compass reads the world's north in its frame in both twins (:mod:`dualtwin.convert.sensor_models`).

Webots' Compass gives the unit vector of the axis ``WorldInfo.coordinateSystem`` names north (+y in ENU) in the
device frame; MuJoCo's magnetometer gives the model's magnetic field in its site frame, by default (0, -0.5, 0), so
the converted Compass read -0.5 times Webots' vector (a sign flip and half the length), silently. A world with a
Compass now gets ``<option magnetic>`` = north. Expected values by hand: a robot turned 0.5 rad about z sees the
north (0, 1, 0) as (sin 0.5, cos 0.5, 0).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text


def _world(devices: str, info: str = "") -> str:
    return world_text(
        f'DEF R Robot {{ rotation 0 0 1 0.5 controller "<extern>" children [ {devices} DEF H HingeJoint {{\n'
        '  jointParameters HingeJointParameters { axis 0 0 1 } device [ PositionSensor { name "s" } ]\n'
        "  endPoint DEF E Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }",
        f"basicTimeStep 8 gravity 0 {info}")


def test_both_twins_read_the_north_in_the_compass_frame(tmp_path: Path) -> None:
    expected = [math.sin(0.5), math.cos(0.5), 0.0]
    with converted_twins(_world('Compass { name "c" }'), tmp_path, 0.008) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        np.testing.assert_allclose(webots._sensor("c").getValues(), expected, atol=1e-6)  # the twin's poses: ~3e-7
        model, data = mujoco_twin.model, mujoco_twin.data
        adr = int(model.sensor("c").adr[0])
        np.testing.assert_allclose(data.sensordata[adr:adr + 3], expected, atol=1e-6)  # the MJCF file: 6 digits
        assert mujoco_twin.sensor("c") == pytest.approx(webots.sensor("c"), abs=1e-6)


@pytest.mark.parametrize(("system", "north"), [("ENU", [0, 1, 0]), ("NUE", [1, 0, 0]), ("EUN", [0, 0, 1])])
def test_the_field_is_the_coordinate_systems_north(system: str, north: list[float]) -> None:
    model = convert_world_text(_world('Compass { name "c" }', f'coordinateSystem "{system}"'), "c.wbt").compile()
    assert [float(v) for v in model.opt.magnetic] == north


def test_a_world_without_a_compass_keeps_mujocos_default() -> None:
    assert "magnetic" not in convert_world_text(_world('GPS { name "g" }'), "g.wbt").xml
