"""Which clock stamped a recording: a simulation's (regular) or a wall clock (irregular), from the gaps.

A simulation logs at fixed instants: every gap between stamps is a whole number of control periods, or one
constant step (a log written every basic time step). A process that paces itself with ``sleep`` and stamps
with the wall clock logs whenever the operating system wakes it: its gaps scatter around the period and
follow the OS timer (the paper's MuJoCo logs: 31, 47 and 63 ms gaps, multiples of Windows' 15.6 ms tick,
with a 32 ms control period). The import keeps such stamps (they are interpolated onto the twin's grid)
but must say that they are wall-clock and how much they jitter, since timing comparisons inherit it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: A gap within this fraction of a control period of a whole number of periods (or of the log's constant
#: step) is regular; stamps rounded coarser than that widen it to their rounding.
REGULAR_FRACTION = 0.01
#: Irregular stamps: more than this fraction of gaps off the grid (one stray gap is a dropped line, not a clock).
IRREGULAR_SHARE = 0.05


def _stamp_rounding(t: FloatArray) -> float:
    for decimals in range(10):
        scaled = t * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-6 * np.maximum(1.0, np.abs(scaled))):
            return float(10.0**-decimals)
    return 0.0


def gap_statistics(t: FloatArray, period: float) -> dict[str, Any] | None:
    """The gaps' figures against the control period, and the verdict ``clock``: simulation or wall-clock."""
    t = np.asarray(t, dtype=np.float64)
    gaps = np.diff(t)
    if gaps.size < 3:
        return None
    tol = max(REGULAR_FRACTION * period, 1e-9, _stamp_rounding(t))
    periods = np.round(gaps / period)
    off_period = np.abs(gaps - periods * period)
    off_period[periods < 1] = np.abs(gaps[periods < 1] - period)
    median = float(np.median(gaps))
    off_constant = np.abs(gaps - median)
    irregular = off_period > tol
    uniform = float(np.mean(off_constant > tol)) <= IRREGULAR_SHARE
    wall = float(np.mean(irregular)) > IRREGULAR_SHARE and not uniform
    ms = np.round(gaps * 1000.0).astype(np.int64)
    values, counts = np.unique(ms, return_counts=True)
    order = np.argsort(-counts, kind="stable")[:5]
    return {
        "clock": "wall-clock" if wall else "simulation",
        "control_period_s": period,
        "gaps": int(gaps.size),
        "median_dt_s": median,
        "mean_dt_s": float(np.mean(gaps)),
        "std_dt_s": float(np.std(gaps)),
        "min_dt_s": float(gaps.min()),
        "max_dt_s": float(gaps.max()),
        "off_period_share": float(np.mean(irregular)),
        "max_off_period_s": float(off_period.max()),
        "common_gaps_ms": {str(int(values[i])): int(counts[i]) for i in sorted(order)},
    }


def sampling_clock(logs: Sequence[FloatArray], period: float) -> dict[str, Any] | None:
    """The clock verdict of a scenario's recording from each of its logs' stamps (a file, a bag topic):
    wall-clock if any is irregular; the figures are those of its most irregular log."""
    stats = [s for s in (gap_statistics(t, period) for t in logs) if s is not None]
    if not stats:
        return None
    return max(stats, key=lambda s: (s["clock"] == "wall-clock", s["off_period_share"], s["std_dt_s"]))


def clock_note(stats: dict[str, Any]) -> str:
    """One line for the terminal and the manifest notes."""
    gaps = ", ".join(f"{k} ms" for k in stats["common_gaps_ms"])
    return (f"timing origin: wall-clock (irregular stamps: {100 * stats['off_period_share']:.0f}% of "
            f"{stats['gaps']} gaps are not whole control periods of {1000 * stats['control_period_s']:g} ms; "
            f"gaps {1000 * stats['min_dt_s']:.3g}-{1000 * stats['max_dt_s']:.3g} ms, std "
            f"{1000 * stats['std_dt_s']:.3g} ms; most common {gaps}): interpolated onto the control grid, "
            "timings inherit the jitter")
