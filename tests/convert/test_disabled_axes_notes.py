"""A converted vector sensor with an axis turned off says that MuJoCo still reads that component.

Webots' Accelerometer, Gyro, Compass and InertialUnit read NaN for a component whose ``xAxis``/``yAxis``/``zAxis``
is FALSE (their reference pages; the Webots twin does so, tests/webots/test_sensor_frames.py); a MuJoCo sensor has
no such switch, so the converted sensor read a number there, silently. The conversion now names the axes.
"""

from __future__ import annotations

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text


def _warnings(device: str) -> list[str]:
    scene = (f'Robot {{ controller "<extern>" children [ {device}\n'
             "  HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } device [ PositionSensor {\n"
             '    name "s" } ] endPoint Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }')
    return convert_world_text(world_text(scene, "basicTimeStep 8"), "w.wbt").warnings


@pytest.mark.parametrize("kind", ["Accelerometer", "Gyro", "Compass", "InertialUnit"])
def test_an_axis_turned_off_is_reported(kind: str) -> None:
    notes = [w for w in _warnings(f'{kind} {{ name "v" xAxis FALSE zAxis FALSE }}') if "NaN" in w]
    assert len(notes) == 1 and "xAxis and zAxis FALSE" in notes[0], notes
    assert not [w for w in _warnings(f'{kind} {{ name "v" }}') if "NaN" in w]  # control: all axes on
