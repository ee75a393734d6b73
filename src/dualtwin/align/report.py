"""The before/after alignment report: ``report.html`` with tables, findings and three-trace overlays.

Every plot (one block per scenario) overlays the reference, the target before alignment and the target after it
(`dualtwin.reporting.svg.svg_plot`, one channel and unit per axes, inline SVG: drawing them costs milliseconds
and a few kilobytes, where matplotlib PNGs cost about 2 CPU-seconds per scenario and megabytes on the arm),
labelled by twin name, with crossing times marked. The tables take their MSE, DTW, crossing-time and endpoint
errors from `compare_runs` (reference vs before, reference vs after).
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualtwin.align.analysis_report import findings_html
from dualtwin.align.analyze import Analysis
from dualtwin.align.narrate import narrative_html
from dualtwin.artifacts import write_text
from dualtwin.divergence.comparison import RunComparison, ScenarioComparison, compare_runs
from dualtwin.divergence.metrics import ChannelDivergence
from dualtwin.reporting import evidence_html, html_table, img_html, page_head
from dualtwin.reporting.svg import SVG_POINTS, legend_html, svg_plot

if TYPE_CHECKING:
    from dualtwin.align.config import AlignConfig
    from dualtwin.align.writers import AlignResult, KnobFit


def _f(value: float | None, spec: str = ".4g") -> str:
    return "–" if value is None else format(value, spec)


def _pair(before: float | None, after: float | None) -> str:
    if before is None and after is None:
        return "–"
    arrow = ""
    if before is not None and after is not None and before != after:
        arrow = " ✓" if abs(after) < abs(before) else " ✗"
    return f"{_f(before)} → {_f(after)}{arrow}"


def trace_labels(reference_twin: str, target_twin: str) -> tuple[str, str, str]:
    """Legend labels from the runs' twin names (folder names repeat): reference, target before, target after."""
    return f"{reference_twin} (reference)", f"{target_twin} before", f"{target_twin} after"


def _abs(value: float | None) -> float | None:
    return None if value is None else abs(value)


def _crossing_error(ch: ChannelDivergence | None) -> float | None:
    if ch is None or ch.threshold is None:
        return None
    if ch.crossing_diff_s is not None:
        return abs(ch.crossing_diff_s)
    if (ch.crossing_a_s is None) != (ch.crossing_b_s is None):
        return float("inf")
    return None


def scenario_table(before: RunComparison, after: RunComparison, held: Sequence[str]) -> str:
    """Per scenario and channel: MSE, DTW, crossing-time and endpoint errors before → after."""
    rows = []
    after_by_id = {s.id: s for s in after.scenarios}
    units = before.units
    for sb in before.scenarios:
        sa = after_by_id.get(sb.id)
        role = "held out" if sb.id in held else "train"
        for name in before.channel_names:
            cb = sb.channels.get(name)
            ca = sa.channels.get(name) if sa else None
            unit = f" [{units[name]}]" if units.get(name) else ""
            rows.append([sb.id, role, name + unit, _pair(cb.mse if cb else None, ca.mse if ca else None),
                         _pair(cb.dtw if cb else None, ca.dtw if ca else None),
                         _pair(_crossing_error(cb), _crossing_error(ca)),
                         _pair(_abs(cb.final_diff) if cb else None, _abs(ca.final_diff) if ca else None)])
    return html_table(["scenario", "set", "channel", "MSE", "DTW", "|Δ crossing| [s]", "|endpoint error|"], rows,
                      left=(0, 1, 2))


def _overlay(sb: ScenarioComparison, sa: ScenarioComparison | None, channel: str, unit: str,
             labels: tuple[str, str, str]) -> str:
    """Reference, before and after traces of one scenario channel as an SVG plot; "" if nothing to draw."""
    traces = []
    crossings: list[float | None] = []
    widths: list[float] = []
    cb, ca = sb.channels.get(channel), sa.channels.get(channel) if sa else None
    for width, (label, series, cross) in zip((4.0, 1.4, 1.4), (
            (labels[0], sb.series_a.get(channel), cb.crossing_a_s if cb else None),
            (labels[1], sb.series_b.get(channel), cb.crossing_b_s if cb else None),
            (labels[2], sa.series_b.get(channel) if sa else None, ca.crossing_b_s if ca else None)), strict=True):
        if series is not None:
            traces.append((label, series.t, series.y))
            crossings.append(cross)
            # A wide translucent reference stays visible when an aligned trace lies exactly on it.
            widths.append(width)
    if not traces:
        return ""
    return svg_plot(traces, crossings=crossings, threshold=cb.threshold if cb else None, widths=widths,
                    ylabel=f"{channel} [{unit or 'unit not recorded'}]", title=channel)


def scenario_svg(sb: ScenarioComparison, sa: ScenarioComparison | None, channels: Sequence[str],
                 units: Mapping[str, str], labels: tuple[str, str, str] = ("reference", "before", "after")) -> str:
    """One block per scenario: every channel's three-trace overlay (inline SVG plots, two per row)."""
    plots = [_overlay(sb, sa, channel, units.get(channel, ""), labels) for channel in channels]
    return "<div class='plots'>" + "".join(p for p in plots if p) + "</div>"


def _interval(k: KnobFit) -> str:
    return "–" if k.interval_95 is None else f"[{k.interval_95[0]:.4g}, {k.interval_95[1]:.4g}]"


def _comparison(analysis: Analysis, reference: Path, run: Path, thresholds: Mapping[str, float] | None
                ) -> RunComparison:
    """``reference`` against ``run``: the analysis's comparison when it compared the same runs alike."""
    same = (Path(analysis.config.run_a), Path(analysis.config.run_b), analysis.config.thresholds) == (
        Path(reference), Path(run), None if thresholds is None else dict(thresholds))
    return analysis.comparison if same else compare_runs(reference, run, thresholds)


def write_align_report(out_dir: Path, result: AlignResult, reference: Path, before: Path, after: Path,
                       analysis_before: Analysis, analysis_after: Analysis, train: Sequence[str],
                       held: Sequence[str], thresholds: Mapping[str, float] | None = None) -> Path:
    """Write ``report.html`` (plots inline) into ``out_dir``; returns the report path.

    The comparisons are the analyses' own (``reference`` against ``before`` and ``after`` with ``thresholds``),
    not computed again; a caller whose analyses compared other runs gets them compared here."""
    comp_before = _comparison(analysis_before, reference, before, thresholds)
    comp_after = _comparison(analysis_after, reference, after, thresholds)
    labels = trace_labels(comp_before.twin_a, comp_before.twin_b)
    knob_rows = [[k.name, f"{k.nominal:.5g}", f"<b>{k.fitted:.5g}</b>", _f(k.half_width_95, ".2g"),
                  _interval(k), k.method or "", f"[{k.lower:.4g}, {k.upper:.4g}]",
                  "; ".join(x for x in (k.at_bound or "", f"tied: {k.tied}" if k.tied else "") if x)]
                 for k in result.knobs.values()]
    summary = [
        ("optimizer", result.optimizer), ("stop", result.stop_reason),
        ("evaluations", str(result.evaluations)), ("iterations", str(result.iterations)),
        ("objective (train)", _pair(result.objective_before, result.objective_after)),
        ("objective (held out)", _pair(result.holdout_before, result.holdout_after) if held else "no held-out scenarios"),
        ("|residual|² (train, least-squares criterion)", _pair(result.residual_before, result.residual_after)),
        ("summary divergence score", _pair(comp_before.summary_score, comp_after.summary_score)),
        ("cond(JᵀJ)", _f(result.condition_number, ".3g")),
        ("train / held out", f"{', '.join(train)} / {', '.join(held) or '–'}"),
    ]
    parts = [
        page_head(f"Alignment: {comp_before.twin_b} to {comp_before.twin_a}"),
        f"<h1>Alignment: {html.escape(comp_before.twin_b)} to the reference ({html.escape(comp_before.twin_a)})</h1>",
        html_table(["", ""], summary, left=(0, 1)),
        "<h2>Knobs</h2>",
        html_table(["knob", "nominal", "fitted", "± 95 %", "95 % interval", "method", "bounds", "note"], knob_rows,
                   left=(0, 4, 5, 7), raw=(2,)),
    ]
    before_check = result.identifiability.get("before", {})
    correlated = result.identifiability.get("after", {}).get("correlated", [])
    if before_check.get("advice") or correlated:
        parts.append("<h2>Identifiability</h2><p>Before the fit (from the suite and the knobs alone):</p><ul>"
                     + "".join(f"<li>{html.escape(a)}</li>" for a in before_check.get("advice", []))
                     + ("" if before_check.get("advice") else "<li>no trade-off found</li>")
                     + "</ul><p>After the fit (pairs with |r| &gt; 0.9):</p><ul>"
                     + "".join(f"<li>{html.escape(e['knobs'][0])} and {html.escape(e['knobs'][1])}: r = "
                               f"{e['r']:+.3f}</li>" for e in correlated)
                     + ("" if correlated else "<li>none</li>") + "</ul>")
    if result.nuisance:
        # Initial conditions and time offsets of this reference: fitted with the physics, not part of the model.
        nuisance_rows = [[k.name, f"{k.nominal:.5g}", f"<b>{k.fitted:.5g}</b>", _f(k.half_width_95, ".2g"),
                          _interval(k), f"[{k.lower:.4g}, {k.upper:.4g}]", k.unit, k.at_bound or ""]
                         for k in result.nuisance.values()]
        parts += ["<h2>Nuisance knobs (this reference's initial conditions and time offsets; not in the aligned "
                  "model)</h2>",
                  html_table(["knob", "nominal", "fitted", "± 95 %", "95 % interval", "bounds", "unit", "at bound"],
                             nuisance_rows, left=(0, 4, 6, 7), raw=(2,))]
    if result.warnings:
        parts.append("<h2>Warnings</h2><ul class='viol'>" + "".join(f"<li>{html.escape(w)}</li>"
                                                                      for w in result.warnings) + "</ul>")
    if result.proposals:
        parts.append("<h2>Proposals</h2><ul>" + "".join(
            f"<li>{evidence_html(dict(p.knobs))} {html.escape(p.reason)}</li>" for p in result.proposals)
            + "</ul>")
    parts.append(narrative_html(result.narrative))
    parts += ["<h2>Per scenario (reference vs target: before → after)</h2>",
              scenario_table(comp_before, comp_after, held),
              "<h2>Findings before alignment</h2>", findings_html(analysis_before.findings),
              "<h2>Findings after alignment</h2>", findings_html(analysis_after.findings),
              "<h2>Overlays</h2>"]
    after_by_id = {s.id: s for s in comp_after.scenarios}
    # Vector plots of at most SVG_POINTS points per trace (each run of samples keeps its minimum and maximum);
    # the full traces are the runs' ground_truth.tsv files.
    parts.append("<p>Every trace is drawn through the minimum and maximum of each run of samples (at most "
                 f"{SVG_POINTS} points: peaks keep their extent); the full traces are in the runs' "
                 "<code>ground_truth.tsv</code> files.</p>" + legend_html(labels))
    for sb in comp_before.scenarios:
        parts.append(f"<h3>{html.escape(sb.id)}{' (held out)' if sb.id in held else ''}</h3>")
        parts.append(scenario_svg(sb, after_by_id.get(sb.id), comp_before.channel_names, comp_before.units, labels))
    parts.append("</body></html>")
    path = out_dir / "report.html"
    write_text(path, "\n".join(parts))
    return path


def prediction_report_html(result: AlignResult, before: Mapping[str, Any], after: Mapping[str, Any],
                           config: AlignConfig) -> str:
    """``report.html`` of the prediction objective: the fitted knobs and the prediction error before and after."""
    knobs = html_table(["knob", "nominal", "fitted", "± 95 %", "unit"],
                       [[n, f"{k.nominal:.5g}", f"{k.fitted:.5g}",
                         "–" if k.half_width_95 is None else f"{k.half_width_95:.2g}", k.unit]
                        for n, k in result.knobs.items()])
    horizons = [str(h) for h in config.horizons]
    pred = html_table(["horizon [periods]", "before", "after"],
                      [[h, before.get("by_horizon", {}).get(h, {}).get("normalized_rms"),
                        after.get("by_horizon", {}).get(h, {}).get("normalized_rms")] for h in horizons], left=())
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in result.warnings)
    image = ""
    if "plot" in result.files:
        image = img_html((result.out_dir / result.files["plot"]).read_bytes(), "prediction error")
    cond = "–" if result.condition_number is None else f"{result.condition_number:.4g}"
    return (f"{page_head('Prediction alignment')}<h1>Alignment with the prediction objective</h1>"
            f"<p>target <b>{html.escape(config.target)}</b>, reference <code>{html.escape(config.reference)}</code>, "
            f"optimizer {html.escape(result.optimizer)}: {html.escape(result.stop_reason)}; "
            f"{result.evaluations} evaluations; cond(JᵀJ) {cond}</p>"
            f"<p>objective (mean squared normalised prediction error): {result.objective_before:.4g} → "
            f"<b>{result.objective_after:.4g}</b></p>{knobs}"
            f"<h2>Normalised RMS prediction error</h2>{pred}{image}<ul>{warnings}</ul></body></html>")
