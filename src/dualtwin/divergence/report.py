"""Divergence reports: ``metrics.json``, overlay PNGs, a self-contained ``report.html`` and a terminal table.

Everything here consumes a `RunComparison`; no metric is computed in this module. Figures use
matplotlib's object API with the Agg canvas, so no pyplot state or global backend is touched.
"""

from __future__ import annotations

import base64
import html
import io
import json
import os
import re
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from dualtwin.divergence.metrics import ChannelDivergence, Threshold
from dualtwin.divergence.runs import RunComparison, ScenarioComparison

METRICS_SCHEMA = "dualtwin.divergence/1"
#: A trace for `plot_overlay`: ``(label, t, y)``.
Trace = tuple[str, npt.ArrayLike, npt.ArrayLike]


def _atomic_write(path: Path, data: bytes) -> None:
    """Write to a temp file beside ``path`` then rename, so readers never see a partial file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def plot_overlay(
    ax: Axes,
    traces: Sequence[Trace],
    *,
    crossings: Sequence[float | None] | None = None,
    threshold: Threshold | None = None,
    ylabel: str = "",
    title: str = "",
) -> list[Line2D]:
    """Overlay any number of traces on one axes, with optional threshold and crossing markers.

    Args:
        ax: Target axes.
        traces: ``(label, t, y)`` per line, e.g. two twins, or before/after alignment.
        crossings: Crossing time per trace (None: no marker), drawn as a dotted line in the trace's colour.
        threshold: Drawn as dashed grey line(s); both signs for an ``abs`` threshold.
        ylabel: Y axis label.
        title: Axes title.

    Returns:
        The trace lines, in order.
    """
    if crossings is not None and len(crossings) != len(traces):
        raise ValueError(f"{len(crossings)} crossing times for {len(traces)} traces")
    lines: list[Line2D] = []
    for label, t, y in traces:
        (line,) = ax.plot(np.asarray(t, dtype=float), np.asarray(y, dtype=float), label=label, linewidth=1.4)
        lines.append(line)
    if threshold is not None:
        levels = [threshold.value, -threshold.value] if threshold.mode == "abs" else [threshold.value]
        for level in levels:
            ax.axhline(level, color="0.5", linestyle="--", linewidth=0.8)
    for line, when in zip(lines, crossings or [], strict=False):
        if when is not None:
            ax.axvline(when, color=line.get_color(), linestyle=":", linewidth=1.2)
            ax.plot([when], [0.0], marker="v", color=line.get_color(), markersize=6, clip_on=False)
    ax.set_xlabel("time [s]")
    if ylabel:
        ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    if traces:
        ax.legend(loc="best", fontsize=8)
    return lines


def plot_channel(
    scenario: ScenarioComparison, channel: str, label_a: str, label_b: str, unit: str = ""
) -> Figure:
    """Both twins' traces of one scenario channel on a new Agg figure, crossings marked."""
    fig = Figure(figsize=(7.0, 3.2), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    traces: list[Trace] = []
    crossings: list[float | None] = []
    metrics = scenario.channels.get(channel)
    for label, series, cross in (
        (label_a, scenario.series_a.get(channel), metrics.crossing_a_s if metrics else None),
        (label_b, scenario.series_b.get(channel), metrics.crossing_b_s if metrics else None),
    ):
        if series is not None:
            traces.append((label, series.t, series.y))
            crossings.append(cross)
    plot_overlay(
        ax,
        traces,
        crossings=crossings,
        threshold=metrics.threshold if metrics else None,
        ylabel=f"{channel} [{unit}]" if unit else channel,
        title=f"{scenario.id}: {channel}",
    )
    return fig


def _png_bytes(fig: Figure) -> bytes:
    buf = io.BytesIO()
    # No "Software" stamp, so identical data gives identical files.
    fig.savefig(buf, format="png", metadata={"Software": None})
    return buf.getvalue()


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "x"


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


# (column title, attribute) shared by the HTML and terminal tables.
_COLUMNS: tuple[tuple[str, str], ...] = (
    ("RMSE", "rmse"),
    ("DTW rms", "dtw_rms"),
    ("DTW", "dtw"),
    ("max |err|", "max_abs_error"),
    ("final Δ", "final_diff"),
    ("r", "correlation"),
    ("lag [s]", "lag_s"),
    ("slope", "slope"),
    ("sign inv.", "sign_inverted"),
    ("cross A [s]", "crossing_a_s"),
    ("cross B [s]", "crossing_b_s"),
    ("Δcross [s]", "crossing_diff_s"),
    ("score", "score"),
)

_CSS = """
body{font-family:system-ui,sans-serif;margin:2em;color:#222;max-width:1200px}
table{border-collapse:collapse;margin:0.6em 0 1.2em}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;font-size:13px}
th{background:#f2f2f2}td.l,th.l{text-align:left}
.completed{color:#1a7f37}.failed{color:#b35900}.unstable{color:#c62828;font-weight:bold}
.viol{color:#c62828}img{max-width:100%;margin:4px 0}code{background:#f5f5f5;padding:0 3px}
section{border-top:2px solid #ddd;margin-top:1.5em}
"""


def _e(value: Any) -> str:
    return html.escape(_fmt(value))


def _status(status: str) -> str:
    return f'<span class="{html.escape(status)}">{html.escape(status)}</span>'


def _metrics_table(channels: dict[str, ChannelDivergence], units: dict[str, str]) -> str:
    head = (
        '<tr><th class="l">channel</th>'
        + "".join(f"<th>{html.escape(t)}</th>" for t, _ in _COLUMNS)
        + "</tr>"
    )
    rows = []
    for name, ch in channels.items():
        unit = f" [{units.get(name, '')}]" if units.get(name) else ""
        cells = "".join(f"<td>{_e(getattr(ch, attr))}</td>" for _, attr in _COLUMNS)
        rows.append(f'<tr><td class="l">{html.escape(name + unit)}</td>{cells}</tr>')
    return f"<table>{head}{''.join(rows)}</table>"


def _render_html(
    comparison: RunComparison, label_a: str, label_b: str, images: dict[tuple[str, str], bytes]
) -> str:
    units = dict(comparison.units)
    parts: list[str] = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>Divergence: {html.escape(label_a)} vs {html.escape(label_b)}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>Divergence report: {html.escape(label_a)} vs {html.escape(label_b)}</h1>",
        "<table>",
        f'<tr><th class="l">robot</th><td class="l">{_e(comparison.robot)}</td></tr>',
        f'<tr><th class="l">suite</th><td class="l">{_e(comparison.suite_name)}</td></tr>',
        f'<tr><th class="l">A: {html.escape(label_a)}</th><td class="l">{_e(comparison.twin_a)} '
        f"<code>{_e(comparison.run_a)}</code></td></tr>",
        f'<tr><th class="l">B: {html.escape(label_b)}</th><td class="l">{_e(comparison.twin_b)} '
        f"<code>{_e(comparison.run_b)}</code></td></tr>",
        f'<tr><th class="l">summary score</th><td class="l"><b>{_e(comparison.summary_score)}</b> '
        "(0 = identical, 1 = maximal)</td></tr>",
        f'<tr><th class="l">within tolerances</th><td class="l">{_e(comparison.within_tolerance)}</td></tr>',
        "</table>",
    ]

    contributions = comparison.contributions()[:10]
    if contributions:
        parts.append("<h2>What dominates the divergence</h2><table>")
        parts.append(
            '<tr><th class="l">scenario</th><th class="l">channel</th><th>contribution</th><th>share</th></tr>'
        )
        for c in contributions:
            parts.append(
                f'<tr><td class="l">{_e(c.scenario_id)}</td><td class="l">{_e(c.channel or "(instability)")}</td>'
                f"<td>{_e(c.contribution)}</td><td>{c.share * 100:.1f} %</td></tr>"
            )
        parts.append("</table>")

    parts.append("<h2>Scenarios</h2><table>")
    parts.append(
        f'<tr><th class="l">scenario</th><th>{html.escape(label_a)}</th><th>{html.escape(label_b)}</th>'
        '<th>score</th><th class="l">tolerances</th><th class="l">note</th></tr>'
    )
    for sc in comparison.scenarios:
        tol = (
            "ok"
            if sc.within_tolerance
            else f'<span class="viol">{len(sc.tolerance_violations)} exceeded</span>'
        )
        parts.append(
            f'<tr><td class="l"><a href="#{_slug(sc.id)}">{_e(sc.id)}</a></td><td>{_status(sc.status_a)}</td>'
            f'<td>{_status(sc.status_b)}</td><td>{_e(sc.score)}</td><td class="l">{tol}</td>'
            f'<td class="l">{_e(sc.note)}</td></tr>'
        )
    parts.append("</table>")

    settings = comparison.settings
    parts.append("<h2>Settings and definitions</h2><table>")
    for key, value in settings.get("definitions", {}).items():
        parts.append(f'<tr><th class="l">{_e(key)}</th><td class="l">{_e(value)}</td></tr>')
    for key in ("weights", "thresholds", "max_lag_s", "dtw_window"):
        parts.append(
            f'<tr><th class="l">{key}</th><td class="l"><code>{html.escape(json.dumps(settings.get(key)))}</code></td></tr>'
        )
    parts.append("</table>")

    for sc in comparison.scenarios:
        parts.append(f'<section id="{_slug(sc.id)}"><h2>{_e(sc.id)}</h2>')
        parts.append(
            f"<p>{html.escape(label_a)}: {_status(sc.status_a)} · {html.escape(label_b)}: {_status(sc.status_b)}"
            f" · score <b>{_e(sc.score)}</b></p>"
        )
        for label, failure in ((label_a, sc.failure_a), (label_b, sc.failure_b)):
            if failure:
                parts.append(
                    f"<p>{html.escape(label)} failure: <code>{html.escape(json.dumps(failure))}</code></p>"
                )
        if sc.note:
            parts.append(f"<p><i>{_e(sc.note)}</i></p>")
        if sc.channels:
            parts.append(_metrics_table(dict(sc.channels), units))
        if sc.tolerance_violations:
            parts.append('<ul class="viol">')
            for v in sc.tolerance_violations:
                parts.append(f"<li>{_e(v.channel)} {_e(v.metric)} = {_e(v.value)} &gt; {_e(v.limit)}</li>")
            parts.append("</ul>")
        for channel in comparison.channel_names:
            png = images.get((sc.id, channel))
            if png is not None:
                data = base64.b64encode(png).decode("ascii")
                parts.append(f'<img alt="{_e(sc.id)} {_e(channel)}" src="data:image/png;base64,{data}">')
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(comparison: RunComparison, out_dir: Path, label_a: str, label_b: str) -> Path:
    """Write ``metrics.json``, ``plots/<scenario>__<channel>.png`` and ``report.html`` into ``out_dir``.

    Every file is written atomically (temp name, then ``os.replace``).

    Args:
        comparison: Result of `compare_runs`.
        out_dir: Output directory, created if needed.
        label_a: Display name of twin A (e.g. ``"Webots"``).
        label_b: Display name of twin B.

    Returns:
        Path of ``report.html``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    metrics = {
        "schema": METRICS_SCHEMA,
        "label_a": label_a,
        "label_b": label_b,
        "comparison": comparison.to_dict(),
    }
    _atomic_write(out_dir / "metrics.json", (json.dumps(metrics, indent=2, allow_nan=False) + "\n").encode())

    images: dict[tuple[str, str], bytes] = {}
    for sc in comparison.scenarios:
        for channel in comparison.channel_names:
            if channel not in sc.series_a and channel not in sc.series_b:
                continue
            fig = plot_channel(sc, channel, label_a, label_b, comparison.units.get(channel, ""))
            png = _png_bytes(fig)
            images[(sc.id, channel)] = png
            _atomic_write(out_dir / "plots" / f"{_slug(sc.id)}__{_slug(channel)}.png", png)

    report = out_dir / "report.html"
    _atomic_write(report, _render_html(comparison, label_a, label_b, images).encode("utf-8"))
    return report


def print_summary(comparison: RunComparison, console: Console, *, top: int = 5) -> None:
    """Print a per-scenario, per-channel table, the summary score and the top contributors."""
    table = Table(title=f"Divergence: {comparison.twin_a} (A) vs {comparison.twin_b} (B), {comparison.robot}")
    for col in ("scenario", "A", "B", "channel", "RMSE", "DTW rms", "lag [s]", "Δcross [s]", "r", "score"):
        table.add_column(col, justify="left" if col in ("scenario", "A", "B", "channel") else "right")
    style = {"completed": "green", "failed": "yellow", "unstable": "bold red"}
    for sc in comparison.scenarios:
        a = Text(sc.status_a, style=style.get(sc.status_a, ""))
        b = Text(sc.status_b, style=style.get(sc.status_b, ""))
        if not sc.channels:
            table.add_row(Text(sc.id), a, b, "–", "–", "–", "–", "–", "–", _fmt(sc.score))
        for i, (name, ch) in enumerate(sc.channels.items()):
            first = i == 0
            table.add_row(
                Text(sc.id) if first else "",
                a if first else "",
                b if first else "",
                Text(name),
                _fmt(ch.rmse),
                _fmt(ch.dtw_rms),
                _fmt(ch.lag_s),
                _fmt(ch.crossing_diff_s),
                _fmt(ch.correlation),
                _fmt(ch.score),
            )
        table.add_section()
    console.print(table)
    console.print(f"summary score: [bold]{_fmt(comparison.summary_score)}[/] (0 = identical, 1 = maximal)")
    for c in comparison.contributions()[:top]:
        console.print(
            f"  {c.share * 100:5.1f} %  {escape(c.scenario_id)} / {escape(c.channel or '(instability)')}"
        )
    for sc in comparison.scenarios:
        for v in sc.tolerance_violations:
            console.print(
                f"  [red]tolerance exceeded[/] {escape(sc.id)} / {escape(v.channel)}: "
                f"{v.metric} = {_fmt(v.value)} > {_fmt(v.limit)}"
            )
