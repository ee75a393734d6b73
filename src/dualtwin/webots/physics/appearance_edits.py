"""A supervisor's edit of a Shape's colour at run time: what the Camera draws and the infra-red rays weigh.

Webots' PBRAppearance and Material connect their colour fields to update slots that change the rendered Shape from
the next frame on; an infra-red DistanceSensor reads the colour of what each ray hits at each sample
(webots-devices.md §1: the reflection factor from the hit Shape's red and roughness). The twin's Camera scene and the
infra-red rays' Shapes are built from these fields (``visual_scene``, ``visual_rays``) and rebuilt when the
simulation's ``geometry_version`` moves: an edit of a field they read moves it. A DEF'd appearance is one node with
its USEs (the twin's DEF/USE rule, as for geometry edits), so the value is copied to them first.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.nodes import Node, copy_value

__all__ = ["APPEARANCE_FIELDS", "apply_appearance_field"]

#: the fields of each appearance node that the Camera's colours and the infra-red reflection factor read
APPEARANCE_FIELDS: dict[str, frozenset[str]] = {
    "PBRAppearance": frozenset({"baseColor", "transparency", "roughness"}),
    "Material": frozenset({"diffuseColor", "transparency"}),
}


def apply_appearance_field(sim: Any, node: Node, name: str) -> bool:
    """Apply an edit of ``node``'s field ``name`` if it is a colour field the scene reads (False otherwise): the
    DEF/USE copies take the value and the visual scenes are built again before their next image or ray."""
    if name not in APPEARANCE_FIELDS.get(node.type_name, frozenset()):
        return False
    value = node.fields.get(name)
    for other in sim.linked_nodes(node)[1:]:
        other.fields[name] = copy_value(value)
    sim.geometry_version += 1
    return True
