"""How many times a supervisor has written the fields of a node (and each field): the stamp a device compares
with the one its configuration was read at, to read its fields again after an edit.

Webots connects each device field to an ``update*`` slot (WbDistanceSensor's lookup table and rays, WbEmitter's
channel and range, ...) that recomputes what the device derives from the field and marks the device to be
configured again in its controller at the next step. A device here derives the same from its node's fields
once, and again when the stamp of its node moved: after any write through the Field API, and after a
``simulationReset`` that put the edited fields back.

A write counts from the beginning of the step that executes it (:func:`execute_edits`), not when the supervisor
makes it: webots-on-ode.md §6, a write is executed at the beginning of the next step and a controller sees the world
through its steps, so another robot's device getter (``getLookupTable``, an Emitter's ``getChannel``) read between
the write and that step gives what the steps executed, whichever controller's request came first in real time.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from dualtwin.webots.nodes import Node

__all__ = ["edit_stamp", "execute_edits", "note_edit", "stamps_of", "written_since"]

_KEY = "field_edit_stamps"
_NONE: frozenset[str] = frozenset()
#: the writes made since the last step began, counted as the stamps are (moved into them by execute_edits)
_UNEXECUTED_KEY = "field_edit_stamps_unexecuted"


def stamps_of(sim: Any) -> dict[Any, int]:
    """The simulation's write counts: by ``id(node)`` (any field of the node) and by ``(id(node), name)``. A device
    keeps this one dict and reads its node's count with one look-up (devices ask at every sample)."""
    stamps: dict[Any, int] | None = sim.extensions.get(_KEY)
    if stamps is None:
        table: dict[Any, int] = {}
        stamps = sim.extensions[_KEY] = table

        def reset() -> None:  # simulationReset restored every edited field: each one is read again
            execute_edits(sim)
            for key in table:
                table[key] += 1

        sim.reset_hooks.append(reset)
    return stamps


def _unexecuted_of(sim: Any) -> dict[Any, int]:
    unexecuted: dict[Any, int] | None = sim.extensions.get(_UNEXECUTED_KEY)
    if unexecuted is None:
        unexecuted = sim.extensions[_UNEXECUTED_KEY] = {}
    return unexecuted


def note_edit(sim: Any, node: Node, name: str) -> None:
    """Count a write of ``node``'s field ``name`` (``Simulation.field_changed`` calls it for every write); the count
    shows from the beginning of the next step (:func:`execute_edits`)."""
    unexecuted = _unexecuted_of(sim)
    for key in (id(node), (id(node), name)):
        unexecuted[key] = unexecuted.get(key, 0) + 1


def execute_edits(sim: Any) -> None:
    """The beginning of a step: the writes counted since the last one move the stamps, so the devices of their nodes
    read their fields again from this step on (the simulation's step calls it, and a reset)."""
    unexecuted: dict[Any, int] | None = sim.extensions.get(_UNEXECUTED_KEY)
    if not unexecuted:
        return
    stamps = stamps_of(sim)
    for key, count in unexecuted.items():
        stamps[key] = stamps.get(key, 0) + count
    unexecuted.clear()


def written_since(stamps: dict[Any, int], node: Node | None, names: Iterable[str], seen: dict[Any, int],
                  never: int = 0) -> frozenset[str]:
    """The fields of ``node`` among ``names`` written (or restored by a reset) since ``seen``, the stamps they were
    last read at (keyed as ``stamps``, :func:`stamps_of`; ``never`` for a key not read yet: 0, nothing is new at the
    first read, -1, everything is), brought up to date. None at one look-up while the node's own stamp has not moved
    (what a device, a Track or a Propeller asks at every sample or step)."""
    if node is None:
        return _NONE
    key = id(node)
    stamp = stamps.get(key, 0)
    if seen.get(key, never) == stamp:
        return _NONE
    seen[key] = stamp
    changed = []
    for name in names:
        field_stamp = stamps.get((key, name), 0)
        if seen.get((key, name), never) != field_stamp:
            seen[(key, name)] = field_stamp
            changed.append(name)
    return frozenset(changed)


def edit_stamp(sim: Any, node: Node, name: str | None = None) -> int:
    """The number of writes of ``node``'s field ``name`` (of any of its fields when None) so far, 0 if none."""
    stamps: dict[Any, int] | None = sim.extensions.get(_KEY)
    if stamps is None:
        return 0
    return stamps.get(id(node) if name is None else (id(node), name), 0)
