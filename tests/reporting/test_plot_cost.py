"""Report plots stay cheap and small: traces are drawn through a min/max envelope, PNGs use a palette."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from dualtwin.reporting.pages import png_bytes
from dualtwin.reporting.plots import MAX_POINTS, envelope, plot_overlay


def _signal(n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 10.0, n)
    return t, np.sin(3.0 * t) + 0.05 * np.random.default_rng(0).normal(size=n) + (t > 7.3) * 0.8


def test_envelope_keeps_every_extreme_and_the_ends() -> None:
    t, y = _signal(12_001)
    et, ey = envelope(t, y)
    assert len(et) <= MAX_POINTS + 2 and len(et) < len(t) / 8
    assert ey.max() == y.max() and ey.min() == y.min()
    assert (et[0], et[-1]) == (t[0], t[-1]) and np.all(np.diff(et) > 0)
    # every kept sample is a real sample, and each tenth of the trace keeps its own extremes
    assert set(et) <= set(t)
    for part in np.array_split(np.arange(len(t)), 10):
        inside = (et >= t[part[0]]) & (et <= t[part[-1]])
        assert ey[inside].max() >= y[part].max() - 0.2  # runs straddle the tenth's borders
    # short traces and traces with gaps are drawn as they are
    short = _signal(500)
    assert envelope(*short)[0] is short[0] or np.array_equal(envelope(*short)[0], short[0])
    gap = y.copy()
    gap[100] = np.nan
    assert len(envelope(t, gap)[0]) == len(t)


def _figure() -> Figure:
    fig = Figure(figsize=(8.0, 3.0), dpi=90)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    t, y = _signal(10_000)
    lines = plot_overlay(ax, [("reference", t, y), ("after", t, y + 0.1)], ylabel="x [m]")
    assert len(lines[0].get_xdata()) <= MAX_POINTS + 2
    return fig


def test_report_pngs_use_a_palette_and_are_deterministic() -> None:
    small, full = png_bytes(_figure()), png_bytes(_figure(), palette=False)
    assert Image.open(io.BytesIO(small)).mode == "P"
    assert Image.open(io.BytesIO(full)).mode == "RGB"
    assert len(small) * 2 < len(full)
    assert png_bytes(_figure()) == small
