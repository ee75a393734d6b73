"""Unit conversion at import: a recorded channel must arrive in the unit its binding declares.

A recording states each channel's unit (the mapping file says it; the paper's header names imply it). The
binding declares the unit the run is written in. Known units convert with an exact factor; anything else
must match the binding's unit string exactly, so a channel in the wrong unit is an import error and never a
silent mismatch in a comparison later. A sign convention is not a unit: the mapping's ``scale`` says it.
"""

from __future__ import annotations

from dualtwin.errors import DualtwinError

#: Factor to the SI base of each dimension. Only units with an exact, unambiguous conversion are listed.
KNOWN_UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "cm": ("length", 0.01),
    "mm": ("length", 0.001),
    "rad": ("angle", 1.0),
    "mrad": ("angle", 0.001),
    "deg": ("angle", 3.141592653589793 / 180.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "ns": ("time", 1e-9),
}

#: Time units a time column may be in.
TIME_UNITS = ("s", "ms", "us", "ns")


def _parse(unit: str) -> tuple[tuple[str, float], tuple[str, float]] | None:
    """``'deg/s'`` → ((angle, f), (time, 1)); None when any part is not a known unit."""
    parts = unit.replace(" ", "").split("/")
    if len(parts) > 2 or not parts[0]:
        return None
    num = KNOWN_UNITS.get(parts[0])
    den = KNOWN_UNITS.get(parts[1]) if len(parts) == 2 else ("", 1.0)
    if num is None or den is None:
        return None
    return num, den


def conversion_factor(unit: str, target: str, where: str) -> float:
    """The factor that takes a value in ``unit`` to ``target``.

    Raises:
        DualtwinError: If the two units measure different things (``deg`` into ``m``), or either is not a
            known unit and the two strings differ. ``where`` starts the message (file, channel).
    """
    if unit == target:
        return 1.0
    a, b = _parse(unit), _parse(target)
    if a is None or b is None:
        unknown = unit if a is None else target
        raise DualtwinError(f"{where}: unit {unit!r} does not match the binding's {target!r} "
                            f"({unknown!r} is not a unit dualtwin converts; known: {', '.join(KNOWN_UNITS)} "
                            "and ratios of them such as m/s or deg/s)")
    (dim_a, fa), (tdim_a, ta) = a
    (dim_b, fb), (tdim_b, tb) = b
    if dim_a != dim_b or tdim_a != tdim_b:
        raise DualtwinError(f"{where}: unit {unit!r} cannot be converted to the binding's {target!r} "
                            "(they measure different quantities)")
    return (fa / ta) / (fb / tb)
