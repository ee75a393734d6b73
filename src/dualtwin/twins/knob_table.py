"""Knob tables: one entry per knob kind per twin, from which ``knobs()``, ``set_knobs()`` and the docs derive.

A twin's knobs used to be two parallel string chains (one listing them, one dispatching ``set_knobs`` on the
name with implicit ``else`` branches), so a new knob meant editing both in each twin. Now a twin declares a
:class:`KnobTable`: groups of model objects (joints, geoms, bodies, motors, sensors, or the model itself),
each with the :class:`KnobKind` entries that apply to them. An entry holds everything about one kind of knob:

* ``pattern`` -- its name, e.g. ``joint.<j>.damping`` (one ``<x>`` placeholder for the object's name);
* ``unit``, ``description`` -- copied into every :class:`~dualtwin.twins.base.Knob` of the kind;
* ``bounds``, ``sets`` -- the bounds rule and what the value writes in the model, as text for the docs
  (``scripts/gen_knob_docs.py`` writes the knob table of ``docs/concepts/knobs.md`` from them);
* ``find`` -- which objects of its group have the knob, and the handle it reads and writes;
* ``nominal``, ``limits`` -- the nominal value and the bounds of one knob, from its handle;
* ``apply`` -- write one value through the handle.

:meth:`KnobTable.build` walks the groups in order and returns every knob with its entry and handle; a twin's
``knobs()`` is that list's :class:`Knob` values and its ``set_knobs()`` looks the names up in it, so an
unknown name is simply one the walk did not produce. The order of the walk is the order of ``knobs()``
(objects first, kinds within an object), which selections, optimisers and reports keep.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from dualtwin.twins.base import Knob

T = TypeVar("T")

_PLACEHOLDER = re.compile(r"<[a-z]+>")


def named(twin: Any, obj: Any) -> tuple[str, Any]:
    """The default ``find``: the group yields ``(name, handle)`` pairs and every one has the knob."""
    return obj  # type: ignore[no-any-return]


@dataclass(frozen=True)
class KnobKind(Generic[T]):
    """One kind of knob of one twin (see the module docstring)."""

    pattern: str
    unit: str
    bounds: str
    sets: str
    nominal: Callable[[T, Any], float]
    limits: Callable[[T, Any, float], tuple[float, float]]
    apply: Callable[[T, Any, float], None]
    description: str = ""
    find: Callable[[T, Any], tuple[str, Any] | None] = named
    #: The unit when it depends on the object (a slide joint's armature is a mass); else ``unit``.
    unit_of: Callable[[T, Any], str] | None = None

    def __post_init__(self) -> None:
        # The pattern split once around its placeholder: name() runs for every knob on every build.
        match = _PLACEHOLDER.search(self.pattern)
        parts = (self.pattern[:match.start()], self.pattern[match.end():]) if match else (self.pattern, None)
        object.__setattr__(self, "_parts", parts)

    def name(self, obj_name: str) -> str:
        """The knob's name for an object (the pattern itself when it has no placeholder)."""
        head, tail = self._parts  # type: ignore[attr-defined]
        return head if tail is None else head + obj_name + tail  # type: ignore[no-any-return]


@dataclass(frozen=True)
class KnobGroup(Generic[T]):
    """Objects of one kind, in knob order, and the knob kinds they may have."""

    objects: Callable[[T], Iterable[Any]]
    kinds: tuple[KnobKind[T], ...]


@dataclass(frozen=True)
class BoundKnob(Generic[T]):
    """One knob of a twin: its entry, the handle it reads and writes, and its :class:`Knob`."""

    kind: KnobKind[T]
    handle: Any
    knob: Knob


@dataclass(frozen=True)
class KnobTable(Generic[T]):
    """A twin's knobs, as groups of objects and the kinds of knob each may have."""

    groups: tuple[KnobGroup[T], ...]

    @property
    def kinds(self) -> list[KnobKind[T]]:
        """Every entry once, in table order (the docs' rows)."""
        return [kind for group in self.groups for kind in group.kinds]

    def build(self, twin: T) -> dict[str, BoundKnob[T]]:
        """Every knob ``twin`` has now, by name, in ``knobs()`` order."""
        out: dict[str, BoundKnob[T]] = {}
        for group in self.groups:
            for obj in group.objects(twin):
                for kind in group.kinds:
                    found = kind.find(twin, obj)
                    if found is None:
                        continue
                    obj_name, handle = found
                    nominal = kind.nominal(twin, handle)
                    lower, upper = kind.limits(twin, handle, nominal)
                    unit = kind.unit_of(twin, handle) if kind.unit_of is not None else kind.unit
                    name = kind.name(obj_name)
                    out[name] = BoundKnob(kind, handle, Knob(name, float(nominal), float(lower), float(upper), unit,
                                                             kind.description))
        return out
