"""The analysis' outputs: ``analysis.json``, ``analysis.html`` (findings, sensitivities, the dominant pairs'
plots, next to the divergence report) and the terminal summary of :func:`dualtwin.align.analyze.analyze_runs`."""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.markup import escape

from dualtwin.align.analyze import Analysis, Finding, KnobSensitivity, floor_table
from dualtwin.align.narrate import narrative_html, print_narrative
from dualtwin.artifacts import write_json, write_text


def findings_html(findings: Sequence[Finding]) -> str:
    """An ordered list of findings with their evidence (as small tables with rounded numbers), for reports."""
    from dualtwin.reporting import evidence_html

    if not findings:
        return "<p>No finding: the runs agree within the detectors' thresholds.</p>"
    items = []
    for f in findings:
        knobs = f" <br><small>knobs to try: <code>{html.escape(', '.join(f.knobs))}</code></small>" if f.knobs else ""
        items.append(f"<li><b>{html.escape(f.kind.replace('_', ' '))}</b> ({100 * f.share:.0f} % of the divergence): "
                     f"{html.escape(f.message)}{knobs}<br><small>evidence:</small>{evidence_html(f.evidence)}</li>")
    return "<ol>" + "".join(items) + "</ol>"


def _change_text(s: KnobSensitivity, direction: str) -> str:
    """A sensitivity cell in words where there is no number: never ``nan``."""
    value = s.change.get(direction)
    if value is None:
        return "not tried (at bound)" if s.tried else "not computed"
    if not math.isfinite(value):
        return f"unstable ({', '.join(s.unstable)})" if s.unstable else "not computed"
    return "no effect" if value == 0 else f"{value:+.3g}"


def direction_text(s: KnobSensitivity) -> str:
    """Which way to move a knob, in words: ``none`` means the nominal beat both tries (or nothing changed)."""
    if s.best_direction != "none":
        return s.best_direction
    return "no effect" if s.sensitivity == 0 else "keep nominal (both directions worse)"


def sensitivity_html(sensitivity: Sequence[KnobSensitivity], top: int = 15) -> str:
    from dualtwin.reporting import html_table

    if not sensitivity:
        return ""
    rows = []
    for s in sensitivity[:top]:
        sens = ("not computed" if not math.isfinite(s.sensitivity)
                else "no effect" if s.sensitivity == 0 else f"{s.sensitivity:.3g}")
        direction = direction_text(s)
        rows.append([s.knob + (f" [{s.unit}]" if s.unit else ""), f"{s.nominal:.4g}", _change_text(s, "up"),
                     _change_text(s, "down"), sens, direction])
    return html_table(["knob", "nominal", "Δobjective up", "Δobjective down", "sensitivity", "to move toward A"],
                      rows, left=(0, 5))


def write_analysis(analysis: Analysis, out_dir: Path) -> Path:
    """Write ``analysis.json``, the divergence report (``report.html``) and ``analysis.html``; returns the latter."""
    from dualtwin.divergence.report import plot_channel, twin_labels, write_report
    from dualtwin.reporting import CSS, png_bytes

    out_dir = Path(out_dir)
    label_a, label_b = twin_labels(analysis.comparison)  # twin names from the manifests, not folder names
    write_report(analysis.comparison, out_dir, label_a, label_b)
    write_json(out_dir / "analysis.json", analysis.to_dict())
    images = []
    shown: set[tuple[str, str]] = set()
    for c in analysis.dominant:
        if c.channel is None or (c.scenario_id, c.channel) in shown or len(shown) >= 4:
            continue
        shown.add((c.scenario_id, c.channel))
        sc = next(s for s in analysis.comparison.scenarios if s.id == c.scenario_id)
        png = png_bytes(plot_channel(sc, c.channel, label_a, label_b, analysis.comparison.units.get(c.channel, "")))
        images.append(f'<img alt="{html.escape(c.scenario_id)}" src="data:image/png;base64,'
                      f'{base64.b64encode(png).decode("ascii")}">')
    score = analysis.comparison.summary_score
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>Why {html.escape(label_b)} diverges from {html.escape(label_a)}</title><style>{CSS}</style></head><body>",
        f"<h1>Why {html.escape(label_b)} diverges from {html.escape(label_a)}</h1>",
        f"<p>Summary divergence score {'–' if score is None else f'{score:.4g}'} (0 = identical). "
        "Full metrics: <a href='report.html'>report.html</a>.</p>",
        "<h2>Findings</h2>", findings_html(analysis.findings),
    ]
    if analysis.sensitivity:
        parts += ["<h2>Knob sensitivity</h2>",
                  f"<p>Objective at nominal: {f'{analysis.objective.total:.4g}' if analysis.objective else 'not computed'}; "
                  f"each knob moved by {analysis.config.step:g} of its range.</p>",
                  sensitivity_html(analysis.sensitivity)]
    if analysis.notes:
        parts.append("<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in analysis.notes) + "</ul>")
    parts.append(narrative_html(analysis.narrative))
    parts += ["<h2>Dominant scenario × channel pairs</h2>", *images, "</body></html>"]
    path = out_dir / "analysis.html"
    write_text(path, "\n".join(parts))
    return path


def print_analysis(analysis: Analysis, console: Console, *, top: int = 10) -> None:
    """Findings (ranked, with the knobs to try) and the most sensitive knobs, for the terminal."""
    score = analysis.comparison.summary_score
    console.print(f"summary divergence score: [bold]{'–' if score is None else f'{score:.4g}'}[/] "
                  "(0 = identical, 1 = maximal)")
    if not analysis.findings:
        console.print("no finding: the runs agree within the detectors' thresholds")
    for i, finding in enumerate(analysis.findings[:top], start=1):
        console.print(f"{i:2d}. [bold]{escape(finding.kind.replace('_', ' '))}[/] ({100 * finding.share:.0f} %): "
                      f"{escape(finding.message)}")
        if finding.knobs:
            console.print(f"    knobs to try: {escape(', '.join(finding.knobs[:4]))}")
    floors = floor_table(analysis.comparison)
    if floors:
        console.print("against the reproducibility floor (most significant first):")
        for row in floors[:top]:
            console.print(f"    {escape(row['scenario'])} / {escape(row['channel'])}: {escape(row['verdict'])}")
    if analysis.sensitivity:
        from dualtwin.reporting import Column, print_table

        console.print("most sensitive knobs:")
        print_table(console, [Column("knob", False), Column("sensitivity"), Column("to move toward A", False)],
                    [[s.knob, "no effect" if s.sensitivity == 0 else f"{s.sensitivity:.4g}",
                      direction_text(s)]
                     for s in analysis.sensitivity[:5]])
    for note in analysis.notes:
        console.print(f"[yellow]note:[/] {escape(note)}")
    print_narrative(analysis.narrative, console)
