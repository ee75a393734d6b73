"""The converter's contact notes name only material pairs that can touch.

A converted robot's geoms meet only the static environment (robot parts never collide with each other without
``selfCollision``, webots-on-ode §2.3 rule 4), so a robot alone in its world has no contact at all: no
ContactProperties field of it can be lost. The converter still warned that the default pair's ``bounce 0.5``
(the ContactProperties default, §2.1) "is not reproduced" in every such world, e.g. each free-flying robot of
the dual-twin fuzz.
"""

from __future__ import annotations

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text

ROBOT = ('DEF R Robot { translation 0 0 1 controller "<extern>" children [ GPS { name "gps" } ] '
         "boundingObject Sphere { radius 0.1 } physics Physics { } }")


def _contact_notes(scene: str) -> list[str]:
    return [w for w in convert_world_text(world_text(scene), "notes.wbt").warnings if w.startswith("contact ")]


def test_a_robot_alone_gets_no_contact_note() -> None:
    assert _contact_notes(ROBOT) == []


def test_control_a_robot_above_a_floor_gets_the_bounce_note() -> None:
    notes = _contact_notes('Solid { name "floor" boundingObject Plane { } }\n' + ROBOT)
    assert len(notes) == 1 and "'default'/'default': bounce 0.5 is not reproduced" in notes[0]
