"""Webots' sensor lookup tables and output resolution (shared by DistanceSensor and TouchSensor).

Lookup table (``WbLookupTable``): rows ``input output noise``. Below the first input the first row applies, above
the last input the last row (clamped); in between, output *and* noise are interpolated linearly between the
bracketing rows. Noise is multiplicative, ``y = v·(1 + n·N(0,1))``, and no random number is drawn where
``n == 0`` (so a noiseless table never advances the generator). An empty table is the identity without noise.

Resolution (``WbMathsUtilities::discretize``): ``int(v/r + 0.5)·r`` — C's truncation toward zero, so negative
values round differently from ``floor``; ``-1`` (or any value ≤ 0) disables it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

__all__ = ["Gauss", "Table", "discretize", "lookup", "table_from_field"]

Table = list[tuple[float, float, float]]


class Gauss(Protocol):
    """A source of Gaussian draws (``random.Random``; the MuJoCo twin adapts its NumPy generator)."""

    def gauss(self, mu: float, sigma: float) -> float: ...


def table_from_field(value: object) -> Table:
    """The rows of a ``lookupTable`` field value (rows shorter than 2 are dropped; missing noise is 0)."""
    rows: Table = []
    for row in value or []:  # type: ignore[attr-defined]
        r = list(row)
        if len(r) >= 2:
            rows.append((float(r[0]), float(r[1]), float(r[2]) if len(r) > 2 else 0.0))
    return rows


def _interpolate(table: Sequence[tuple[float, float, float]], x: float) -> tuple[float, float]:
    if x <= table[0][0]:
        return table[0][1], table[0][2]
    if x >= table[-1][0]:
        return table[-1][1], table[-1][2]
    for (x0, y0, n0), (x1, y1, n1) in zip(table, table[1:], strict=False):
        if x0 <= x <= x1:
            if x1 == x0:
                return y0, n0
            f = (x - x0) / (x1 - x0)
            return y0 + f * (y1 - y0), n0 + f * (n1 - n0)
    # unsorted inputs (Webots only warns): fall back to the last row
    return table[-1][1], table[-1][2]


def lookup(table: Sequence[tuple[float, float, float]], x: float, rng: Gauss | None) -> float:
    """Output of the table at ``x``, with its multiplicative Gaussian noise drawn from ``rng``."""
    if not table:
        return x
    value, noise = _interpolate(table, x)
    if noise != 0.0 and rng is not None:
        value *= 1.0 + noise * rng.gauss(0.0, 1.0)
    return value


def discretize(value: float, resolution: float) -> float:
    """Webots' output resolution: ``int(v/r + 0.5)·r`` (truncation toward zero), disabled for ``r ≤ 0``."""
    if resolution <= 0 or not math.isfinite(value):
        return value
    return math.trunc(value / resolution + 0.5) * resolution
