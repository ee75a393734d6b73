"""Calibrated domain randomisation: per fitted knob, a range of values the data cannot tell apart.

Format of ``dr_ranges.json`` (read by the RL side)::

    {"schema": "dualtwin.dr/1", "source": "cma-population" | "lsq-interval",
     "knobs": {"joint.pole_hinge.damping": {"nominal": 0.0, "fitted": 0.05, "low": 0.047, "high": 0.053,
                                            "distribution": "uniform", "unit": "N*m*s/rad"}}}

Values are absolute (not factors) and lie within the knob's bounds; ``low <= fitted <= high`` always.
The CMA-ES source is the spread of the best ``top_fraction`` of the last generations' candidates. The
least-squares source is the fitted value ± the 95 % half-width. A range narrower than ``min_rel_width``
of the fitted value (of the bound span when the value is 0) is widened to it, because a zero-width
range randomises nothing; such knobs are listed in ``widened``. Integer knobs are not widened: their
range is the integers their 95 % interval holds, possibly just the fitted one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from dualtwin.align.knobs import KnobSpec

DR_SCHEMA = "dualtwin.dr/1"


def ranges_from_population(specs: Sequence[KnobSpec], population: Sequence[tuple[Sequence[float], float]],
                           top_fraction: float = 0.25) -> dict[str, tuple[float, float]]:
    """Per-knob (low, high) over the best ``top_fraction`` of ``(unit point, objective)`` candidates."""
    finite = sorted((p for p in population if math.isfinite(p[1])), key=lambda p: p[1])
    if not finite:
        return {}
    keep = finite[:max(1, math.ceil(top_fraction * len(finite)))]
    out: dict[str, tuple[float, float]] = {}
    for i, spec in enumerate(specs):
        values = [spec.from_unit(float(u[i])) for u, _ in keep]
        out[spec.name] = (min(values), max(values))
    return out


def ranges_from_intervals(specs: Sequence[KnobSpec], fitted: Mapping[str, float],
                          half_widths: Mapping[str, float | None]) -> dict[str, tuple[float, float]]:
    """Per-knob fitted ± half-width; a knob without a finite half-width spans its bounds."""
    out: dict[str, tuple[float, float]] = {}
    for spec in specs:
        hw = half_widths.get(spec.name)
        value = fitted[spec.name]
        if hw is None or not math.isfinite(hw):
            out[spec.name] = (spec.lower, spec.upper)
        else:
            out[spec.name] = (value - hw, value + hw)
    return out


def dr_document(specs: Sequence[KnobSpec], fitted: Mapping[str, float], ranges: Mapping[str, tuple[float, float]],
                source: str, min_rel_width: float = 0.02) -> dict[str, Any]:
    """The ``dr_ranges.json`` document: ranges clipped to bounds, containing the fitted value, never empty."""
    knobs: dict[str, Any] = {}
    widened: list[str] = []
    for spec in specs:
        value = fitted[spec.name]
        low, high = ranges.get(spec.name, (value, value))
        low, high = min(low, value), max(high, value)
        reference = abs(value) if value != 0 else spec.upper - spec.lower
        min_width = min_rel_width * reference
        if high - low < min_width and not spec.integer:
            widened.append(spec.name)
            low, high = min(low, value - min_width / 2), max(high, value + min_width / 2)
        low, high = max(spec.lower, low), min(spec.upper, high)
        if spec.integer:
            # The integers inside the range; a single one is an honest answer (the data tells it apart).
            low, high = float(math.ceil(low - 1e-9)), float(math.floor(high + 1e-9))
        entry: dict[str, Any] = {"nominal": spec.nominal, "fitted": value, "low": low, "high": high,
                                 "distribution": "uniform", "unit": spec.unit}
        if spec.integer:
            entry["integer"] = True
        knobs[spec.name] = entry
    return {"schema": DR_SCHEMA, "source": source, "min_rel_width": min_rel_width, "widened": widened,
            "knobs": knobs}
