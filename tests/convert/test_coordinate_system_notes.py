"""A WorldInfo coordinateSystem the converter cannot read is named in the conversion's warnings.

It is converted as ENU (gravity along -z, north +y), as the Webots twin reads it (and says so in its build
warnings, tests/webots/test_composite_frames_world_axes.py); it was converted so silently.
"""

from __future__ import annotations

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text


def _world(info: str) -> str:
    return world_text(
        'Robot { controller "<extern>" children [ Compass { name "c" }\n'
        "  HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } device [ PositionSensor {\n"
        '    name "s" } ] endPoint Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }',
        f"basicTimeStep 8 {info}")


def test_a_coordinate_system_the_converter_cannot_read_is_named() -> None:
    # read as ENU (gravity -z, north +y), as the Webots twin reads it; the conversion says so in one line
    notes = [w for w in convert_world_text(_world('coordinateSystem "NED"'), "w.wbt").warnings if "NED" in w]
    assert notes == ['WorldInfo coordinateSystem "NED" is not "ENU", "NUE" or "EUN": converted as ENU']
    assert not [w for w in convert_world_text(_world('coordinateSystem "enu"'), "w.wbt").warnings
                if "coordinateSystem" in w]  # control: ENU in any case
