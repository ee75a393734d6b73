"""Line plots as inline SVG, written by hand: no matplotlib, a few kilobytes per plot, identical for identical data.

Why: a report's overlays were matplotlib PNGs, and drawing them (text, ticks, legend placement) was most of a
small alignment's CPU time, about 2 CPU-seconds per scenario figure, while the PNGs made a many-channel
report several megabytes. A plot here is a frame, three tick labels per axis, and one ``<path>`` per
trace through `envelope` (the minimum and maximum of each run of samples, so peaks, steps and oscillations
keep their extent at screen resolution). Coordinates are whole pixels of the plot's ``viewBox``.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

#: `envelope`'s default: at most this many points per trace (an axes is a few hundred pixels wide).
MAX_POINTS = 1200
#: Points per trace in an SVG plot: about two per pixel column of its width.
SVG_POINTS = 2 * 440
#: Trace colours, in order (matplotlib's first three, so the reports look as before).
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")

_W, _H = 440, 160  # plot size in px (two side by side in a report)
_L, _R, _T, _B = 62, 8, 18, 30  # margins: left (tick labels, y label), right, top (title), bottom (ticks, x label)


def envelope(t: npt.ArrayLike, y: npt.ArrayLike, points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` reduced to about ``points`` samples that draw the same line at screen resolution.

    Why: drawing (and the legend's "best" placement, which tests every vertex) cost most of a report's time,
    for long recordings about 10,000 points per line. The samples are cut into ``points / 2`` equal runs and
    each run keeps its minimum and maximum, in time order, so peaks, steps and oscillations keep their extent
    (no averaging). Short traces, and traces with gaps (NaN), are returned as they are.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(t)
    runs = max(1, points // 2)
    if n <= points or y.shape != t.shape or np.isnan(y).any():
        return t, y
    size = -(-n // runs)  # ceil: whole runs, and one shorter run at the end
    full = n // size
    block = y[:full * size].reshape(full, size)
    start = np.arange(full) * size
    keep = [start + block.argmin(axis=1), start + block.argmax(axis=1), [0, n - 1]]
    if full * size < n:
        tail = y[full * size:]
        keep.append([full * size + int(tail.argmin()), full * size + int(tail.argmax())])
    index = np.unique(np.concatenate(keep))
    return t[index], y[index]


def _segments(t: np.ndarray, y: np.ndarray, points: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The finite stretches of a trace, each through `envelope` with its share of ``points``."""
    finite = np.isfinite(t) & np.isfinite(y)
    if finite.all():
        return [envelope(t, y, points)]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        share = max(4, round(points * (b - a) / len(t)))
        out.append(envelope(t[a:b], y[a:b], share))
    return out


def _path(xs: np.ndarray, ys: np.ndarray) -> str:
    """Pixel points as compact path data: a move, then relative steps, with runs of equal steps (a flat or
    straight stretch) merged into one, and no separator before a minus sign. Exact at pixel resolution."""
    steps = np.diff(np.stack([xs, ys], axis=1), axis=0)
    steps = steps[(steps != 0).any(axis=1)]  # a step onto the same pixel draws nothing
    if len(steps):
        new_run = np.concatenate([[True], (steps[1:] != steps[:-1]).any(axis=1)])
        starts = np.flatnonzero(new_run)
        steps = steps[starts] * np.diff(np.append(starts, len(steps)))[:, None]
    numbers = [f"{v:d}" for v in steps.ravel().tolist()]
    body = "".join(n if n[0] == "-" or k == 0 else " " + n for k, n in enumerate(numbers))
    return f"M{int(xs[0])} {int(ys[0])}" + (f"l{body}" if body else "")


def _tick(value: float, span: float) -> str:
    # A midpoint that is zero up to rounding reads 0, not 2.464e-06.
    return "0" if abs(value) < 1e-4 * span else format(value, ".4g")


def svg_plot(traces: Sequence[tuple[str, npt.ArrayLike, npt.ArrayLike]], *, title: str = "", ylabel: str = "",
             xlabel: str = "time [s]", crossings: Sequence[float | None] | None = None, threshold: Any = None,
             widths: Sequence[float] | None = None) -> str:
    """One axes of overlaid ``(label, t, y)`` traces as an inline ``<svg>`` element (colours `COLOURS` in order;
    styled by `dualtwin.reporting.pages.SVG_CSS`, which the page includes; the labels are for `legend_html`).

    ``crossings``: a time per trace (None: none), drawn dotted in the trace's colour; ``threshold``: an object
    with ``value`` and ``mode`` (``"abs"``: both signs), drawn dashed grey; ``widths``: line width per trace
    (default 1.4; a wide translucent line stays visible under one drawn exactly on it).
    """
    series = [(label, np.asarray(t, dtype=float), np.asarray(y, dtype=float)) for label, t, y in traces]
    levels = [] if threshold is None else (
        [threshold.value, -threshold.value] if threshold.mode == "abs" else [threshold.value])
    finite_t = [v for _, t, _ in series for v in (np.nanmin(t), np.nanmax(t)) if t.size and np.isfinite(t).any()]
    finite_y = [v for _, _, y in series for v in (np.nanmin(y), np.nanmax(y)) if y.size and np.isfinite(y).any()]
    finite_y += [float(v) for v in levels if math.isfinite(v)]
    t0, t1 = (min(finite_t), max(finite_t)) if finite_t else (0.0, 1.0)
    y0, y1 = (min(finite_y), max(finite_y)) if finite_y else (0.0, 1.0)
    if t1 <= t0:
        t1 = t0 + 1.0
    if y1 <= y0:
        pad = abs(y0) * 0.1 or 1.0
        y0, y1 = y0 - pad, y1 + pad
    else:
        pad = 0.05 * (y1 - y0)
        y0, y1 = y0 - pad, y1 + pad
    pw, ph = _W - _L - _R, _H - _T - _B

    def px(t: np.ndarray) -> np.ndarray:
        return np.rint(_L + (t - t0) / (t1 - t0) * pw).astype(np.int64)

    def py(y: np.ndarray) -> np.ndarray:
        return np.rint(_T + (y1 - y) / (y1 - y0) * ph).astype(np.int64)

    out = [f'<svg viewBox="0 0 {_W} {_H}" width="{_W}" height="{_H}" class="plot">'
           f'<rect x="{_L}" y="{_T}" width="{pw}" height="{ph}"/>']
    grid, ticks = [], []
    for frac in (0.0, 0.5, 1.0):
        yv, tv = y0 + frac * (y1 - y0), t0 + frac * (t1 - t0)
        ypix, xpix = int(py(np.array([yv]))[0]), int(px(np.array([tv]))[0])
        grid.append(f"M{_L} {ypix}h{pw}")
        ticks.append(f'<text x="{_L - 3}" y="{ypix + 3}" class="e">{_tick(yv, y1 - y0)}</text>'
                     f'<text x="{xpix}" y="{_T + ph + 12}">{_tick(tv, t1 - t0)}</text>')
    out.append(f'<path class="g" d="{"".join(grid)}"/>' + "".join(ticks))
    out.append(f'<text x="{_L + pw // 2}" y="{_H - 3}">{html.escape(xlabel)}</text>')
    if ylabel:
        out.append(f'<text transform="translate(10 {_T + ph // 2}) rotate(-90)">{html.escape(ylabel)}</text>')
    if title:
        out.append(f'<text x="{_L + pw // 2}" y="12" class="h">{html.escape(title)}</text>')
    marks = [f"M{_L} {int(py(np.array([v]))[0])}h{pw}" for v in levels if math.isfinite(v)]
    if marks:
        out.append(f'<path class="d" d="{"".join(marks)}"/>')
    for k, (_, t, y) in enumerate(series):
        colour = COLOURS[k % len(COLOURS)]
        width = widths[k] if widths else 1.4
        style = f'stroke="{colour}"' + (f' stroke-width="{width:g}"' if width != 1.4 else "") + (
            ' stroke-opacity=".45"' if width > 2 else "")
        for st, sy in _segments(t, y, SVG_POINTS) if t.shape == y.shape else []:
            out.append(f'<path {style} d="{_path(px(st), py(sy))}"/>')
        when = crossings[k] if crossings is not None and k < len(crossings) else None
        if when is not None and math.isfinite(when):
            out.append(f'<path class="c" stroke="{colour}" d="M{int(px(np.array([when]))[0])} {_T}v{ph}"/>')
    out.append("</svg>")
    return "".join(out)


def legend_html(labels: Sequence[str]) -> str:
    """A one-line legend for plots drawn with `svg_plot` (colours in the same order)."""
    return "<p>" + " ".join(f'<span style="color:{COLOURS[k % len(COLOURS)]}">━━</span> {html.escape(label)}'
                            for k, label in enumerate(labels)) + "</p>"
