"""A converted GPS reads what Webots' GPS reads when the world sets ``WorldInfo.gpsReference`` (both twins).

``gpsReference`` is the world origin expressed in the GPS coordinate system; in ``local`` mode Webots' GPS reads
the device origin's world position plus that reference (the WorldInfo reference page, as the Webots twin's
:mod:`dualtwin.webots.world_frame` applies it). The converted GPS is a MuJoCo ``framepos``, the site's world
position: without the reference it read 10, -20 and 30 m off, silently. It is now measured from a world-fixed
site at -gpsReference (axes of the world), which adds the reference exactly. A WGS84 world cannot be converted
so (MuJoCo has no latitude/longitude): the conversion says so.

Expected values by hand: the robot stands at (1, 2, 0.5) turned 0.5 rad about z, its GPS 0.1 m ahead of it
inside a Pose: world position (1 + 0.1·cos 0.5, 2 + 0.1·sin 0.5, 0.5), plus (10, -20, 30).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text


def _world(info: str) -> str:
    return world_text(
        'DEF R Robot { translation 1 2 0.5 rotation 0 0 1 0.5 controller "<extern>" children [\n'
        '  Pose { translation 0.1 0 0 rotation 1 0 0 0.7 children [ GPS { name "g" } ] }\n'
        "  DEF H HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } device [ PositionSensor {\n"
        '    name "s" } ] endPoint DEF E Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }',
        f"basicTimeStep 8 gravity 0 {info}")


def test_both_twins_read_the_position_plus_the_gps_reference(tmp_path: Path) -> None:
    expected = [1 + 0.1 * math.cos(0.5) + 10, 2 + 0.1 * math.sin(0.5) - 20, 0.5 + 30]
    with converted_twins(_world("gpsReference 10 -20 30"), tmp_path, 0.008) as (_, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        np.testing.assert_allclose(webots._sensor("g").getValues(), expected, atol=1e-9)
        model, data = mujoco_twin.model, mujoco_twin.data
        adr = int(model.sensor("g").adr[0])
        np.testing.assert_allclose(data.sensordata[adr:adr + 3], expected, atol=1e-6)  # the MJCF file: 6 digits


def test_without_a_reference_the_gps_reads_the_world_position(tmp_path: Path) -> None:
    # control: the default reference (0 0 0) adds nothing, and no reference site is written
    expected = [1 + 0.1 * math.cos(0.5), 2 + 0.1 * math.sin(0.5), 0.5]
    with converted_twins(_world(""), tmp_path, 0.008) as (conv, _, mujoco_twin):
        mujoco_twin.step()
        adr = int(mujoco_twin.model.sensor("g").adr[0])
        np.testing.assert_allclose(mujoco_twin.data.sensordata[adr:adr + 3], expected, atol=1e-6)
        assert "refname" not in conv.xml


def test_a_wgs84_world_says_its_gps_reads_metres() -> None:
    conv = convert_world_text(_world('gpsCoordinateSystem "WGS84" gpsReference 46.5 6.6 400'), "w.wbt")
    assert any("WGS84" in w and "GPS" in w for w in conv.warnings), conv.warnings
    assert not any("WGS84" in w for w in convert_world_text(_world(""), "w.wbt").warnings)  # control
