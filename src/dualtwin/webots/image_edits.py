"""What a supervisor's edit of a Lidar's, RangeFinder's or Camera's image size, or of a Lidar's frequencies or
type, does at run time.

Webots connects each of these fields to an ``update*`` slot of the device (WbLidar, WbAbstractCamera) that sets
the device up again and configures its controller at the next step. The reference (webots-devices.md §3.1, §4)
gives the fields and the load-time layer check; it is silent on run-time edits of these fields, so this module's
choices are:

* a Camera's or RangeFinder's ``width``/``height``: the next image has the new size and ``getWidth``/
  ``getHeight`` follow (the image reads zeros of that size until the next sample); a side outside
  1..``MAX_IMAGE_SIDE`` keeps the current one, with a warning (at load such a side takes its default), and a
  RangeFinder's height is cut to the rays dualtwin casts on one image (``MAX_DEPTH_RAYS``), as at load.

* ``horizontalResolution`` and ``numberOfLayers``: the next scan has the new size and the controller's
  ``getHorizontalResolution``/``getNumberOfLayers`` follow (the image is cleared to zeros of that size until
  the next sample), after the load's checks: the layer check of §3.1 (``numberOfLayers`` at most
  ``verticalFieldOfView · horizontalResolution / fieldOfView``, 2π for a rotating lidar, else the largest whole
  number that fits, with a warning) and the ray cap dualtwin puts on one image (``MAX_DEPTH_RAYS``).
* ``minFrequency``/``maxFrequency``: the bounds of ``setFrequency`` and their getters, checked as at load; a
  current frequency left outside the new bounds is clamped into them. ``defaultFrequency``: the lidar's
  frequency from the next step (a frequency the controller set is replaced, as writing the field in Webots'
  scene tree sets the device's frequency), clamped into the bounds as at load.
* ``type``: a fixed lidar does not become a rotating one nor the reverse (its rotating head and its image's
  2π span are set up at load); the edit is named in one warning line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from dualtwin.webots.api_args import warn
from dualtwin.webots.lidar_head import frequencies
from dualtwin.webots.physics.build import MAX_DEPTH_RAYS
from dualtwin.webots.protos import MAX_IMAGE_SIDE

__all__ = ["HEAD_FIELDS", "SIZE_FIELDS", "edited_frequencies", "edited_image_size", "edited_model", "edited_lidar_size",
           "warn_type_edit"]

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
    """The model ``build`` makes of the edited ``fields`` (the rays of the next scan: field of view, ranges,
    noise, resolution), with the size and frequencies this module's docstring gives and the load's type."""
    width, layers = model.width, model.layers
    if changed & LIDAR_SIZE_FIELDS:
        width, layers = edited_lidar_size(fields, model.rotating, name, warn)
    if "type" in changed:
        warn_type_edit(fields, model.rotating, name, warn)
    kept = {"horizontalResolution": width, "numberOfLayers": layers, "minFrequency": model.min_frequency,
            "maxFrequency": model.max_frequency, "defaultFrequency": model.frequency,
            "type": "rotating" if model.rotating else "fixed"}
    new = build({**fields, **kept})
    if changed & FREQUENCY_FIELDS:
        new.min_frequency, new.max_frequency, new.frequency = edited_frequencies(
            fields, changed & FREQUENCY_FIELDS, model.frequency, warn)
    return new


def edited_lidar_size(fields: dict[str, Any], rotating: bool, name: str, warn: Callable[[str], None]) -> tuple[int, int]:
    """``(horizontalResolution, numberOfLayers)`` of the edited ``fields``, checked as the load checks them."""
    width = max(1, int(fields.get("horizontalResolution", 512)))
    layers = max(1, int(fields.get("numberOfLayers", 4)))
    fov = 2 * math.pi if rotating else float(fields.get("fieldOfView", 1.5708))
    if fov > 0:
        bound = float(fields.get("verticalFieldOfView", 0.2)) * width / fov
        fitted = max(1, int(bound))
        if layers > bound and fitted != layers:
            warn(f"Lidar '{name}': numberOfLayers {layers} is more than verticalFieldOfView * horizontalResolution "
                 f"/ {'2π' if rotating else 'fieldOfView'} = {bound:g}; numberOfLayers set to {fitted}")
            layers = fitted
    if width * layers > MAX_DEPTH_RAYS:
        fitted = max(1, MAX_DEPTH_RAYS // width)
        warn(f"Lidar '{name}': horizontalResolution * numberOfLayers = {width} * {layers} rays is more than "
             f"dualtwin casts ({MAX_DEPTH_RAYS}); numberOfLayers set to {fitted}")
        layers = fitted
    return width, layers


def edited_frequencies(
    fields: dict[str, Any], changed: frozenset[str], current: float, warn: Callable[[str], None]
) -> tuple[float, float, float]:
    """``(minFrequency, maxFrequency, frequency)`` after an edit of the frequency fields ``changed``: the bounds
    checked as at load, the frequency the edited default or ``current`` (what the controller set) clamped."""
    fmin, fmax, default = frequencies(fields, warn)
    frequency = default if "defaultFrequency" in changed else min(max(current, fmin), fmax)
    return fmin, fmax, frequency


def warn_type_edit(fields: dict[str, Any], rotating: bool, name: str, warn: Callable[[str], None]) -> None:
    """One warning line when an edit made ``type`` differ from the type the lidar was set up with."""
    if (str(fields.get("type", "fixed")) == "rotating") != rotating:
        warn(f"Lidar '{name}': a run-time edit of type is not applied; it stays "
             f"{'rotating' if rotating else 'fixed'}")


def edited_image_size(fields: dict[str, Any], current: tuple[int, int], kind: str, name: str) -> tuple[int, int]:
    """``(width, height)`` of a Camera's or RangeFinder's (``kind``) edited ``fields`` (module docstring)."""
    sides = []
    for field, now in zip(SIZE_FIELDS, current, strict=True):
        value = int(fields.get(field, now))
        if not 1 <= value <= MAX_IMAGE_SIDE:
            warn(f"{kind} '{name}': {field} {value} is not in 1..{MAX_IMAGE_SIDE}; it stays {now}")
            value = now
        sides.append(value)
    width, height = sides
    if kind == "RangeFinder" and width * height > MAX_DEPTH_RAYS:
        fitted = max(1, MAX_DEPTH_RAYS // width)
        warn(f"RangeFinder '{name}': width * height = {width} * {height} rays is more than dualtwin casts "
             f"({MAX_DEPTH_RAYS}); height set to {fitted}")
        height = fitted
    return width, height
