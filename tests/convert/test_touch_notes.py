"""A converted TouchSensor says how its MuJoCo ``touch`` reading differs from what its Webots ``type`` reads.

MuJoCo's touch sums the normal forces (N) of the contacts in its site, whatever their direction. Webots
(webots-devices §2.3): a bumper reads 1 while touched; ``force`` reads only the push along the sensor's −x that
its fixed joint passes on to its parent (0 for a push along another axis); ``force-3d`` reads that joint force
as a vector in the sensor frame; an unknown type is a bumper. The dual-twin fuzz read 0 N from a Webots force
sensor whose −x was horizontal on a robot resting on it, where the MuJoCo twin read the robot's weight, and the
conversion said nothing about it.
"""

from __future__ import annotations

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text


def _notes(kind: str) -> list[str]:
    robot = ('DEF R Robot { controller "<extern>" children [ GPS { name "gps" } '
             f'TouchSensor {{ name "t" type "{kind}" boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} }} ] '
             "boundingObject Box { size 0.2 0.2 0.2 } physics Physics { } }")
    warnings = convert_world_text(world_text(robot), "touch.wbt").warnings
    return [w for w in warnings if "touch sensor 't'" in w]


@pytest.mark.parametrize(("kind", "webots"), [
    ("bumper", "reads 1 while touched"),
    ("force", "only the push along its -x"),
    ("force-3d", "as a vector in its own frame"),
    ("Bumper", "reads 1 while touched"),  # case-sensitive in Webots: unknown, so a bumper
])
def test_each_type_gets_its_note(kind: str, webots: str) -> None:
    notes = _notes(kind)
    assert len(notes) == 1 and "total normal force" in notes[0] and webots in notes[0], notes
