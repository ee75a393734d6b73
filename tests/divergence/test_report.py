"""Report files: metrics.json round trip, PNGs, self-contained HTML, terminal summary, reusable overlay."""

from __future__ import annotations

import io
import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from rich.console import Console

from dualtwin.divergence import (
    RunComparison,
    Threshold,
    compare_runs,
    plot_overlay,
    print_summary,
    write_report,
)
from tests.support.rundirs import cartpole_like

T = np.arange(0, 100) * 0.032
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def comparison(make_run: Callable[..., Path]) -> RunComparison:
    short = {k: (t[:30], y[:30]) for k, (t, y) in cartpole_like(T).items()}
    a = make_run("webots", {"00_Step": cartpole_like(T), "01_Push": cartpole_like(T)}, twin="webots")
    b = make_run(
        "mujoco",
        {"00_Step": cartpole_like(T, delay=0.05, gain=1.1), "01_Push": short},
        statuses={"01_Push": "unstable"},
    )
    return compare_runs(a, b)


def test_report_files_exist_and_html_is_self_contained(comparison: RunComparison, tmp_path: Path) -> None:
    out = tmp_path / "report"
    html_path = write_report(comparison, out, "Webots", "MuJoCo")
    assert html_path == out / "report.html"
    pngs = sorted((out / "plots").glob("*.png"))
    assert [p.name for p in pngs] == sorted(
        f"{sid}__{ch}.png"
        for sid in ("00_Step", "01_Push")
        for ch in ("pole_angle_rad", "cart_pos_m", "wheel_vel_rad_s")
    )
    assert all(p.read_bytes().startswith(PNG_MAGIC) for p in pngs)
    assert not list(out.rglob("*.tmp"))  # atomic writes leave no temp files behind

    text = html_path.read_text(encoding="utf-8")
    images = re.findall(r'<img[^>]*src="([^"]+)"', text)
    assert len(images) == len(pngs)
    assert all(src.startswith("data:image/png;base64,") for src in images)
    for bad in ("http://", "https://", "<link", "<script", "url("):
        assert bad not in text
    assert "unstable" in text and "What dominates the divergence" in text
    assert "Webots" in text and "MuJoCo" in text


def test_metrics_json_round_trips(comparison: RunComparison, tmp_path: Path) -> None:
    write_report(comparison, tmp_path, "A", "B")
    data = json.loads((tmp_path / "metrics.json").read_text(encoding="utf-8"))
    assert data["label_a"] == "A" and data["label_b"] == "B"
    assert data["comparison"] == comparison.to_dict()
    reloaded = RunComparison.from_dict(data["comparison"])
    assert reloaded.to_dict() == data["comparison"]
    assert reloaded.scenarios[0].channels == comparison.scenarios[0].channels
    assert data["comparison"]["settings"]["thresholds"]["pole_angle_rad"] == {"value": 0.99, "mode": "abs"}


def test_print_summary_lists_scenarios_and_score(comparison: RunComparison) -> None:
    buf = io.StringIO()
    print_summary(comparison, Console(file=buf, width=160, color_system=None))
    out = buf.getvalue()
    assert "00_Step" in out and "01_Push" in out and "unstable" in out
    assert "summary score" in out


def test_plot_overlay_takes_any_number_of_traces() -> None:
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    t = np.linspace(0, 1, 20)
    traces = [("webots", t, t), ("mujoco before", t, 1.1 * t), ("mujoco after", t, 1.01 * t)]
    lines = plot_overlay(ax, traces, crossings=[0.5, None, 0.6], threshold=Threshold(0.99), ylabel="rad")
    assert [line.get_label() for line in lines] == ["webots", "mujoco before", "mujoco after"]
    # Crossing markers reuse the colour of their trace.
    vlines = [line for line in ax.get_lines() if line not in lines and line.get_linestyle() == ":"]
    assert [v.get_color() for v in vlines] == [lines[0].get_color(), lines[2].get_color()]
    with pytest.raises(ValueError):
        plot_overlay(ax, traces, crossings=[0.5])
