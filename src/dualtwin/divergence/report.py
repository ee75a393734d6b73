"""Divergence reports: ``metrics.json``, overlay PNGs, a self-contained ``report.html`` and a terminal table.

Everything here consumes a `RunComparison`; no metric is computed in this module. Figures use
matplotlib's object API with the Agg canvas, so no pyplot state or global backend is touched. Page, table
and plot helpers come from :mod:`dualtwin.reporting`. Twins are labelled by the twin names their run
manifests record (folder names repeat: ``runs/a/webots`` vs ``runs/b/webots``).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from rich.console import Console
from rich.markup import escape
from rich.text import Text

from dualtwin.artifacts import write_bytes, write_text
from dualtwin.divergence.comparison import RunComparison, ScenarioComparison
from dualtwin.divergence.metrics import ChannelDivergence
from dualtwin.reporting import (
    Column,
    Progress,
    ProgressCallback,
    Trace,
    esc,
    evidence_html,
    fmt,
    html_table,
    img_html,
    page_head,
    plot_overlay,
    png_bytes,
    print_table,
    slug,
)

METRICS_SCHEMA = "dualtwin.divergence/1"

__all__ = ["METRICS_SCHEMA", "Trace", "plot_channel", "plot_overlay", "print_summary", "twin_labels",
           "write_report"]


def twin_labels(comparison: RunComparison) -> tuple[str, str]:
    """Display names of the two sides from their manifests: the twin names; when both sides are the same twin
    (two recordings, two MuJoCo runs), the run folders' names, and A/B only when those are equal too."""
    a, b = comparison.twin_a or "A", comparison.twin_b or "B"
    if a == b:
        folder_a, folder_b = Path(comparison.run_a).name, Path(comparison.run_b).name
        if folder_a and folder_b and folder_a != folder_b:
            return f"{folder_a} ({a})", f"{folder_b} ({b})"
        return f"{a} (A)", f"{b} (B)"
    return a, b


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
        ylabel=f"{channel} [{unit or 'unit not recorded'}]",
        title=f"{scenario.id}: {channel}",
    )
    return fig


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

def _status(status: str) -> str:
    return f'<span class="{html.escape(status)}">{html.escape(status)}</span>'


def _metrics_table(channels: dict[str, ChannelDivergence], units: dict[str, str]) -> str:
    rows = []
    for name, ch in channels.items():
        unit = f" [{units[name]}]" if units.get(name) else ""
        rows.append([name + unit, *(getattr(ch, attr) for _, attr in _COLUMNS)])
    return html_table(["channel", *(t for t, _ in _COLUMNS)], rows)


def _render_html(
    comparison: RunComparison, label_a: str, label_b: str, images: dict[tuple[str, str], bytes]
) -> str:
    units = dict(comparison.units)
    title = f"Divergence: {label_a} vs {label_b}"
    parts: list[str] = [
        page_head(title),
        f"<h1>Divergence report: {html.escape(label_a)} vs {html.escape(label_b)}</h1>",
        html_table(["", ""], [
            ["robot", comparison.robot],
            ["suite", comparison.suite_name],
            [f"A: {label_a}", f"twin {comparison.twin_a}, run {comparison.run_a}"],
            [f"B: {label_b}", f"twin {comparison.twin_b}, run {comparison.run_b}"],
            ["summary score", f"{fmt(comparison.summary_score)} (0 = identical, 1 = maximal)"],
            ["within tolerances", comparison.within_tolerance],
        ], left=(0, 1)),
    ]

    contributions = comparison.contributions()[:10]
    if contributions:
        parts.append("<h2>What dominates the divergence</h2>")
        parts.append(html_table(
            ["scenario", "channel", "contribution", "share"],
            [[c.scenario_id, c.channel or "(instability)", c.contribution, f"{c.share * 100:.1f} %"]
             for c in contributions], left=(0, 1)))

    left_out = [[what[:-1], name, why] for what, names in comparison.left_out.items() for name, why in names.items()]
    if left_out:
        parts.append("<h2>Left out</h2><p>Only what both runs have is compared.</p>")
        parts.append(html_table(["what", "name", "why"], left_out, left=(0, 1, 2)))
    floors = [[sc.id, name, sc.channels[name].dtw, judged.floor_dtw, judged.ratio, judged.verdict]
              for sc in comparison.scenarios for name, judged in sc.floors.items() if name in sc.channels]
    if floors:
        parts.append("<h2>Against the reproducibility floor</h2><p>The floor is each side's ensemble members "
                     "against its unperturbed member; a ratio near 1 is as close as the physics allows.</p>")
        parts.append(html_table(["scenario", "channel", "DTW", "floor DTW", "ratio", "verdict"], floors,
                                left=(0, 1, 5)))

    parts.append("<h2>Scenarios</h2>")
    rows = []
    for sc in comparison.scenarios:
        tol = "ok" if sc.within_tolerance else f'<span class="viol">{len(sc.tolerance_violations)} exceeded</span>'
        rows.append([f'<a href="#{slug(sc.id)}">{html.escape(sc.id)}</a>', _status(sc.status_a),
                     _status(sc.status_b), sc.score, tol, esc(sc.note, missing="")])
    parts.append(html_table(["scenario", label_a, label_b, "score", "tolerances", "note"], rows,
                            left=(0, 4, 5), raw=(0, 1, 2, 4, 5)))

    settings = comparison.settings
    parts.append("<h2>Settings and definitions</h2>")
    setting_rows: list[list[Any]] = [[key, esc(value)] for key, value in settings.get("definitions", {}).items()]
    setting_rows += [[key, evidence_html(settings.get(key))] for key in ("weights", "thresholds", "max_lag_s",
                                                                          "dtw_window")]
    parts.append(html_table(["setting", "value"], setting_rows, left=(0, 1), raw=(1,)))

    for sc in comparison.scenarios:
        parts.append(f'<section id="{slug(sc.id)}"><h2>{esc(sc.id)}</h2>')
        parts.append(
            f"<p>{html.escape(label_a)}: {_status(sc.status_a)} · {html.escape(label_b)}: {_status(sc.status_b)}"
            f" · score <b>{esc(sc.score)}</b></p>"
        )
        for label, failure in ((label_a, sc.failure_a), (label_b, sc.failure_b)):
            if failure:
                parts.append(f"<p>{html.escape(label)} failure:</p>{evidence_html(failure)}")
        if sc.note:
            parts.append(f"<p><i>{esc(sc.note)}</i></p>")
        if sc.channels:
            parts.append(_metrics_table(dict(sc.channels), units))
        if sc.tolerance_violations:
            parts.append('<ul class="viol">')
            for v in sc.tolerance_violations:
                parts.append(f"<li>{esc(v.channel)} {esc(v.metric)} = {esc(v.value)} &gt; {esc(v.limit)}</li>")
            parts.append("</ul>")
        for channel in comparison.channel_names:
            png = images.get((sc.id, channel))
            if png is not None:
                parts.append(img_html(png, f"{sc.id} {channel}"))
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(comparison: RunComparison, out_dir: Path, label_a: str | None = None,
                 label_b: str | None = None, *, progress: ProgressCallback | None = None) -> Path:
    """Write ``metrics.json``, ``plots/<scenario>__<channel>.png`` and ``report.html`` into ``out_dir``.

    Every file is written atomically (`dualtwin.artifacts`).

    Args:
        comparison: Result of `compare_runs`.
        out_dir: Output directory, created if needed.
        label_a: Display name of side A (default: its twin name, from the run manifest; see `twin_labels`).
        label_b: Display name of side B.
        progress: Called after each scenario's plots (stage ``report``).

    Returns:
        Path of ``report.html``.
    """
    default_a, default_b = twin_labels(comparison)
    label_a, label_b = label_a or default_a, label_b or default_b
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    metrics = {
        "schema": METRICS_SCHEMA,
        "label_a": label_a,
        "label_b": label_b,
        "comparison": comparison.to_dict(),
    }
    write_text(out_dir / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")

    images: dict[tuple[str, str], bytes] = {}
    counter = Progress(progress, "report", len(comparison.scenarios))
    for sc in comparison.scenarios:
        for channel in comparison.channel_names:
            if channel not in sc.series_a and channel not in sc.series_b:
                continue
            fig = plot_channel(sc, channel, label_a, label_b, comparison.units.get(channel, ""))
            png = png_bytes(fig)
            images[(sc.id, channel)] = png
            write_bytes(out_dir / "plots" / f"{slug(sc.id)}__{slug(channel)}.png", png)
        counter.advance(message=sc.id)

    report = out_dir / "report.html"
    write_text(report, _render_html(comparison, label_a, label_b, images))
    return report


#: Columns of the terminal summary table.
SUMMARY_COLUMNS = (Column("scenario", False, group=True), Column("A", False, group=True),
                   Column("B", False, group=True), Column("channel", False),
                   Column("RMSE"), Column("DTW rms"), Column("lag [s]"), Column("Δcross [s]"), Column("r"),
                   Column("score"))


def summary_rows(comparison: RunComparison) -> list[list[str | Text] | None]:
    """One row per scenario and channel (complete on every row, so piped output can be filtered)."""
    style = {"completed": "green", "failed": "yellow", "unstable": "bold red"}
    rows: list[list[str | Text] | None] = []
    for sc in comparison.scenarios:
        a = Text(sc.status_a, style=style.get(sc.status_a, ""))
        b = Text(sc.status_b, style=style.get(sc.status_b, ""))
        if not sc.channels:
            rows.append([sc.id, a, b, "–", "–", "–", "–", "–", "–", fmt(sc.score)])
        for name, ch in sc.channels.items():
            rows.append([sc.id, a, b, name, fmt(ch.rmse), fmt(ch.dtw_rms), fmt(ch.lag_s), fmt(ch.crossing_diff_s),
                         fmt(ch.correlation), fmt(ch.score)])
        rows.append(None)
    return rows


def print_summary(comparison: RunComparison, console: Console, *, top: int = 5) -> None:
    """Print a per-scenario, per-channel table, the summary score and the top contributors."""
    label_a, label_b = twin_labels(comparison)
    print_table(console, SUMMARY_COLUMNS, summary_rows(comparison),
                title=f"Divergence: {label_a} vs {label_b}, {comparison.robot}")
    console.print(f"summary score: [bold]{fmt(comparison.summary_score)}[/] (0 = identical, 1 = maximal)")
    for c in comparison.contributions()[:top]:
        console.print(
            f"  {c.share * 100:5.1f} %  {escape(c.scenario_id)} / {escape(c.channel or '(instability)')}"
        )
    for sc in comparison.scenarios:
        for v in sc.tolerance_violations:
            console.print(
                f"  [red]tolerance exceeded[/] {escape(sc.id)} / {escape(v.channel)}: "
                f"{v.metric} = {fmt(v.value)} > {fmt(v.limit)}"
            )
