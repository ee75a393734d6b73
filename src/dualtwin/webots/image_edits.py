"""What a supervisor's edit of a Lidar's, RangeFinder's or Camera's image size, or of a Lidar's frequencies or
type, does at run time.

Webots connects each of these fields to an ``update*`` slot of the device (WbLidar, WbAbstractCamera) that sets
the device up again and configures its controller at the next step. The reference (webots-devices.md §3.1, §4)
gives the fields and the load-time layer check; it is silent on run-time edits of these fields, so this module's
choices are:

* a Camera's or RangeFinder's ``width``/``height`` and a Lidar's ``horizontalResolution``/``numberOfLayers``:
  the next image has the new size and the getters (``getWidth``, ``getHorizontalResolution``, ...) follow; the
  image reads zeros of that size until the next sample. A side outside 1..``MAX_IMAGE_SIDE`` keeps the current
  one, with a warning (at load such a side takes its default). The load's other checks apply again: a Lidar's
  layer check of §3.1 (``numberOfLayers`` at most ``verticalFieldOfView · horizontalResolution /
  fieldOfView``, 2π for a rotating lidar, else the largest whole number that fits, with a warning) and, for a
  Lidar or RangeFinder, the ray cap dualtwin puts on one image (``MAX_DEPTH_RAYS``: the rows are cut).
* a Lidar's ``minFrequency``/``maxFrequency``: the bounds of ``setFrequency`` and their getters, checked as at
  load; a current frequency left outside the new bounds is clamped into them. ``defaultFrequency``: the
  frequency the lidar starts with, so a write sets its frequency from the next step (replacing what the
  controller set), clamped into the bounds as at load.
* a Lidar's ``type``: a fixed lidar does not become a rotating one nor the reverse (its rotating head and its
  image's 2π span are set up at load); the edit is named in one warning line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from dualtwin.webots.api_args import warn
from dualtwin.webots.lidar_head import frequencies
from dualtwin.webots.physics.build import MAX_DEPTH_RAYS
from dualtwin.webots.protos import MAX_IMAGE_SIDE

__all__ = ["HEAD_FIELDS", "SIZE_FIELDS", "edited_image_size", "edited_model"]

SIZE_FIELDS = ("width", "height")  # a Camera's or RangeFinder's
LIDAR_SIZE_FIELDS = frozenset({"horizontalResolution", "numberOfLayers"})
FREQUENCY_FIELDS = frozenset({"minFrequency", "maxFrequency", "defaultFrequency"})
#: the fields of this module, watched by the lidar besides those of its rays
HEAD_FIELDS = ("horizontalResolution", "numberOfLayers", "minFrequency", "maxFrequency", "defaultFrequency", "type")


class _Model(Protocol):
    """What this module reads and sets of a ``ranging.LidarModel`` (a Protocol: ranging imports this module)."""

    width: int
    layers: int
    rotating: bool
    min_frequency: float
    max_frequency: float
    frequency: float


M = TypeVar("M", bound=_Model)


def edited_model(
    model: M, fields: dict[str, Any], changed: frozenset[str], name: str, build: Callable[[dict[str, Any]], M]
) -> M:
    """The Lidar model ``build`` makes of the edited ``fields`` (the rays of the next scan: field of view, ranges,
    noise, resolution), with the size and frequencies this module's docstring gives and the load's type."""
    width, layers = model.width, model.layers
    if changed & LIDAR_SIZE_FIELDS:
        width, layers = _lidar_size(fields, (width, layers), model.rotating, name)
    if "type" in changed and (str(fields.get("type", "fixed")) == "rotating") != model.rotating:
        warn(f"Lidar '{name}': a run-time edit of type is not applied; it stays "
             f"{'rotating' if model.rotating else 'fixed'}")
    kept = {"horizontalResolution": width, "numberOfLayers": layers, "minFrequency": model.min_frequency,
            "maxFrequency": model.max_frequency, "defaultFrequency": model.frequency,
            "type": "rotating" if model.rotating else "fixed"}
    new = build({**fields, **kept})
    if changed & FREQUENCY_FIELDS:
        new.min_frequency, new.max_frequency, default = frequencies(fields, warn)  # checked as at load
        current = min(max(model.frequency, new.min_frequency), new.max_frequency)
        new.frequency = default if "defaultFrequency" in changed else current
    return new


def edited_image_size(fields: dict[str, Any], current: tuple[int, int], kind: str, name: str) -> tuple[int, int]:
    """``(width, height)`` of a Camera's or RangeFinder's (``kind``) edited ``fields`` (module docstring)."""
    width, height = _sides(fields, SIZE_FIELDS, current, kind, name)
    return (width, _ray_capped(kind, name, SIZE_FIELDS, width, height)) if kind == "RangeFinder" else (width, height)


def _lidar_size(fields: dict[str, Any], current: tuple[int, int], rotating: bool, name: str) -> tuple[int, int]:
    width, layers = _sides(fields, ("horizontalResolution", "numberOfLayers"), current, "Lidar", name)
    fov = 2 * math.pi if rotating else float(fields.get("fieldOfView", 1.5708))
    if fov > 0:
        bound = float(fields.get("verticalFieldOfView", 0.2)) * width / fov
        fitted = max(1, int(bound))
        if layers > bound and fitted != layers:
            warn(f"Lidar '{name}': numberOfLayers {layers} is more than verticalFieldOfView * horizontalResolution "
                 f"/ {'2π' if rotating else 'fieldOfView'} = {bound:g}; numberOfLayers set to {fitted}")
            layers = fitted
    return width, _ray_capped("Lidar", name, ("horizontalResolution", "numberOfLayers"), width, layers)


def _sides(fields: dict[str, Any], names: tuple[str, str], current: tuple[int, int], kind: str,
           name: str) -> tuple[int, int]:
    """The two sides ``names`` written in ``fields``; one outside 1..MAX_IMAGE_SIDE keeps its ``current`` value."""
    sides = []
    for field, now in zip(names, current, strict=True):
        value = int(fields.get(field, now))
        if not 1 <= value <= MAX_IMAGE_SIDE:
            warn(f"{kind} '{name}': {field} {value} is not in 1..{MAX_IMAGE_SIDE}; it stays {now}")
            value = now
        sides.append(value)
    return sides[0], sides[1]


def _ray_capped(kind: str, name: str, names: tuple[str, str], width: int, rows: int) -> int:
    """``rows`` cut to the rays dualtwin casts on one image (as the load cuts them), with a warning."""
    if width * rows <= MAX_DEPTH_RAYS:
        return rows
    fitted = max(1, MAX_DEPTH_RAYS // width)
    warn(f"{kind} '{name}': {names[0]} * {names[1]} = {width} * {rows} rays is more than dualtwin casts "
         f"({MAX_DEPTH_RAYS}); {names[1]} set to {fitted}")
    return fitted
