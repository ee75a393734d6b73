"""How many times a supervisor has written the fields of a node: the stamp a device compares with the one its
configuration was read at, to read its fields again after an edit.

Webots connects each device field to an ``update*`` slot (WbDistanceSensor's lookup table and rays, WbEmitter's
channel and range, ...) that recomputes what the device derives from the field and marks the device to be
configured again in its controller at the next step. A device here derives the same from its node's fields
once, and again when the stamp of its node moved: after any write through the Field API, and after a
``simulationReset`` that put the edited fields back.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.nodes import Node

__all__ = ["edit_stamp", "note_edit"]

_KEY = "field_edit_stamps"


def note_edit(sim: Any, node: Node) -> None:
    """Count a write of one of ``node``'s fields (``Simulation.field_changed`` calls it for every write)."""
    stamps: dict[int, int] | None = sim.extensions.get(_KEY)
    if stamps is None:
        table: dict[int, int] = {}
        stamps = sim.extensions[_KEY] = table

        def reset() -> None:  # simulationReset restored every edited field: each such node reads them again
            for key in table:
                table[key] += 1

        sim.reset_hooks.append(reset)
    stamps[id(node)] = stamps.get(id(node), 0) + 1


def edit_stamp(sim: Any, node: Node) -> int:
    """The number of writes of ``node``'s fields so far (0 for a node never edited)."""
    stamps: dict[int, int] | None = sim.extensions.get(_KEY)
    return 0 if stamps is None else stamps.get(id(node), 0)
