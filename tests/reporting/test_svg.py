"""Report overlays as hand-written inline SVG: cheap, small, identical for identical data, and no matplotlib."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np

from dualtwin.reporting.svg import SVG_POINTS, svg_plot


def _points(svg: str) -> list[np.ndarray]:
    """The traces' pixel points: each trace path is a move then relative steps ("M x y l dx dy ...")."""
    out = []
    for d in re.findall(r' d="(M\d+ \d+l[^"]*)"', svg):
        numbers = [int(v) for v in re.findall(r"-?\d+", d)]
        out.append(np.cumsum(np.array(numbers).reshape(-1, 2), axis=0))
    return out


def test_a_long_trace_is_small_and_keeps_its_peaks() -> None:
    t = np.linspace(0.0, 10.0, 200_001)
    y = np.sin(t)
    y[123_457] = 5.0  # a one-sample spike: it must still reach the top of the plot
    svg = svg_plot([("reference", t, y), ("after", t, y * 0.5)], title="q", ylabel="q [rad]")
    assert len(svg) < 40_000
    lines = _points(svg)
    assert len(lines) == 2 and all(2 < len(p) <= SVG_POINTS + 2 for p in lines)
    top = min(int(v) for v in re.findall(r'<rect x="\d+" y="(\d+)"', svg))
    # The y range is padded by 5 %: the spike sits that far below the frame's top edge, not clipped away.
    height = int(re.findall(r'<rect x="\d+" y="\d+" width="\d+" height="(\d+)"', svg)[0])
    assert lines[0][:, 1].min() <= top + 0.05 * height + 1
    assert lines[1][:, 1].min() > lines[0][:, 1].min() + 20


def test_same_data_same_bytes_and_gaps_split_the_line() -> None:
    t = np.linspace(0.0, 1.0, 500)
    y = np.cos(t)
    y[200:220] = np.nan
    first = svg_plot([("a", t, y)], crossings=[0.5], title="x")
    assert first == svg_plot([("a", t.copy(), y.copy())], crossings=[0.5], title="x")
    assert len(_points(first)) == 2  # the NaN stretch is a gap, not a line to zero


def test_the_align_report_module_does_not_import_matplotlib() -> None:
    code = "import sys, dualtwin.align.report; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
