"""Plot helpers on matplotlib's object API (Agg canvas; no pyplot state, no global backend).

Rule: one unit per axis. Traces of different units go on separate axes (`plot_unit_groups`), and every
axis label carries its unit.

Labels, titles and legend entries are drawn as literal text (no mathtext): they hold names read from run
folders and recordings, which are data, and matplotlib parses any text with two ``$`` as TeX, so a channel or
scenario named ``$x^$`` would end the whole report in a parse error (``$a$`` would silently lose its dollars).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.figure import FigureBase
from matplotlib.legend import Legend
from matplotlib.lines import Line2D

from dualtwin.reporting.svg import MAX_POINTS, envelope

#: A trace for `plot_overlay`: ``(label, t, y)``.
Trace = tuple[str, npt.ArrayLike, npt.ArrayLike]

__all__ = ["MAX_DRAWN", "MAX_POINTS", "Trace", "envelope", "literal_legend", "plot_overlay", "plot_unit_groups"]


#: Values are drawn clipped to ±this: a run that blew up logs numbers near 1e308, and matplotlib's view margins
#: and tick steps (a few times the data range) then overflow to infinity and the figure cannot be drawn
#: ("arange: cannot compute length"). Beyond 1e300 a trace is off any readable scale anyway.
MAX_DRAWN = 1e300


def _drawable(values: npt.ArrayLike) -> np.ndarray:
    """``values`` as floats, finite ones clipped to ±`MAX_DRAWN` (NaN and infinities stay gaps)."""
    v = np.asarray(values, dtype=float)
    return np.where(np.isfinite(v), np.clip(v, -MAX_DRAWN, MAX_DRAWN), v)


def literal_legend(legend: Legend | None) -> Legend | None:
    """``legend`` with its entries drawn as literal text: labels are names from data, never mathtext."""
    if legend is not None:
        for text in legend.get_texts():
            text.set_parse_math(False)
    return legend


def plot_overlay(
    ax: Axes,
    traces: Sequence[Trace],
    *,
    crossings: Sequence[float | None] | None = None,
    threshold: Any = None,
    ylabel: str = "",
    title: str = "",
    xlabel: str = "time [s]",
) -> list[Line2D]:
    """Overlay any number of traces (of one unit) on one axes, with optional threshold and crossing markers.

    Args:
        ax: Target axes.
        traces: ``(label, t, y)`` per line, e.g. two twins, or before/after alignment; each is drawn through
            its `envelope` (at most `MAX_POINTS` points, the same line on screen).
        crossings: Crossing time per trace (None: no marker), drawn as a dotted line in the trace's colour.
        threshold: An object with ``value`` and ``mode`` (``"abs"`` draws both signs), drawn dashed grey.
        ylabel: Y axis label, with its unit.
        title: Axes title.
        xlabel: X axis label.

    Returns:
        The trace lines, in order.
    """
    if crossings is not None and len(crossings) != len(traces):
        raise ValueError(f"{len(crossings)} crossing times for {len(traces)} traces")
    lines: list[Line2D] = []
    for label, t, y in traces:
        (line,) = ax.plot(*envelope(_drawable(t), _drawable(y)), label=label, linewidth=1.4)
        lines.append(line)
    if threshold is not None:
        levels = [threshold.value, -threshold.value] if threshold.mode == "abs" else [threshold.value]
        for level in levels:
            ax.axhline(level, color="0.5", linestyle="--", linewidth=0.8)
    for line, when in zip(lines, crossings or [], strict=False):
        if when is not None:
            ax.axvline(when, color=line.get_color(), linestyle=":", linewidth=1.2)
            ax.plot([when], [0.0], marker="v", color=line.get_color(), markersize=6, clip_on=False)
    ax.set_xlabel(xlabel, parse_math=False)
    if ylabel:
        ax.set_ylabel(ylabel, parse_math=False)
    if title:
        ax.set_title(title, fontsize=10, parse_math=False)
    ax.grid(True, alpha=0.3)
    if traces:
        literal_legend(ax.legend(loc="best", fontsize=8))
    return lines


def plot_unit_groups(fig: FigureBase, series: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]],
                     unit_of: Callable[[str], str], *, quantity: str, xlabel: str, log: bool = False,
                     max_axes: int = 4) -> list[Axes]:
    """One axes per unit for named ``(x, y)`` series, labelled ``<quantity> [<unit>]``.

    Series keep their order; units appear in order of first use; at most ``max_axes`` units are drawn.
    """
    groups: dict[str, list[str]] = {}
    for name in series:
        groups.setdefault(unit_of(name), []).append(name)
    chosen = list(groups.items())[:max_axes]
    axes = fig.subplots(1, max(1, len(chosen)), squeeze=False).ravel().tolist()
    for ax, (unit, names) in zip(axes, chosen, strict=False):
        for name in names:
            x, y = series[name]
            ax.plot(_drawable(x), _drawable(y), marker=".", label=name)
        if log:
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set_xlabel(xlabel, parse_math=False)
        ax.set_ylabel(f"{quantity} [{unit}]", parse_math=False)
        ax.grid(True, which="both", alpha=0.3)
        literal_legend(ax.legend(fontsize=7))
    return axes
