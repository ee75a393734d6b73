"""How many times a supervisor has written the fields of a node (and each field): the stamp a device compares
with the one its configuration was read at, to read its fields again after an edit.

Webots connects each device field to an ``update*`` slot (WbDistanceSensor's lookup table and rays, WbEmitter's
channel and range, ...) that recomputes what the device derives from the field and marks the device to be
configured again in its controller at the next step. A device here derives the same from its node's fields
once, and again when the stamp of its node moved: after any write through the Field API, and after a
``simulationReset`` that put the edited fields back.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.nodes import Node

__all__ = ["edit_stamp", "note_edit", "stamps_of"]

_KEY = "field_edit_stamps"


def stamps_of(sim: Any) -> dict[Any, int]:
    """The simulation's write counts: by ``id(node)`` (any field of the node) and by ``(id(node), name)``. A device
    keeps this one dict and reads its node's count with one look-up (devices ask at every sample)."""
    stamps: dict[Any, int] | None = sim.extensions.get(_KEY)
    if stamps is None:
        table: dict[Any, int] = {}
        stamps = sim.extensions[_KEY] = table

        def reset() -> None:  # simulationReset restored every edited field: each one is read again
            for key in table:
                table[key] += 1

        sim.reset_hooks.append(reset)
    return stamps


def note_edit(sim: Any, node: Node, name: str) -> None:
    """Count a write of ``node``'s field ``name`` (``Simulation.field_changed`` calls it for every write)."""
    stamps = stamps_of(sim)
    for key in (id(node), (id(node), name)):
        stamps[key] = stamps.get(key, 0) + 1


def edit_stamp(sim: Any, node: Node, name: str | None = None) -> int:
    """The number of writes of ``node``'s field ``name`` (of any of its fields when None) so far, 0 if none."""
    stamps: dict[Any, int] | None = sim.extensions.get(_KEY)
    if stamps is None:
        return 0
    return stamps.get(id(node) if name is None else (id(node), name), 0)
