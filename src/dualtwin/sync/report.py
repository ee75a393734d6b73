"""The synchronisation report: prediction-error curves, drift over time, alarms and re-alignments.

``write_sync_report(out, lockstep=..., prediction=..., events=...)`` writes ``report.json`` (every number
shown) and a self-contained ``report.html`` with embedded PNGs, built with the divergence report's helpers
(:func:`dualtwin.divergence.report.plot_overlay`, its stylesheet and PNG writer).
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from dualtwin.artifacts import json_safe, write_json, write_text
from dualtwin.divergence.report import _CSS, _png_bytes, plot_overlay
from dualtwin.divergence.runs import load_tsv
from dualtwin.errors import DualtwinError
from dualtwin.suite.loader import read_json
from dualtwin.sync.lockstep import LockstepResult
from dualtwin.sync.monitor import read_events
from dualtwin.sync.predict import PredictionResult, plot_prediction

REPORT_SCHEMA = "dualtwin.sync-report/1"
#: Monitor events listed in the alarms table.
TABLE_EVENTS = ("alarm_raised", "alarm_cleared", "realign_started", "knobs_updated", "realign_rejected",
                "realign_failed", "realign_skipped")


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else "–"
    return html.escape(str(value))


def _lockstep_data(source: LockstepResult | Path) -> tuple[Path, dict[str, Any]]:
    if isinstance(source, LockstepResult):
        return source.out_dir, source.manifest
    folder = Path(source)
    return folder, read_json(folder / "manifest.json")


def _drift_png(folder: Path, manifest: Mapping[str, Any], events: Sequence[Mapping[str, Any]]) -> tuple[bytes, list[dict[str, Any]]]:
    """Normalised error over simulated time (episodes back to back), re-syncs and monitor events marked."""
    fig = Figure(figsize=(10.0, 3.6), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    traces = []
    series: list[dict[str, Any]] = []
    offset = 0.0
    resync_times: list[float] = []
    for episode in manifest.get("episodes", []):
        path = folder / episode["state_diff"]
        if not path.is_file():
            continue
        header, data = load_tsv(path)
        if not len(data):
            continue
        t = data[:, 0] + offset
        err = data[:, header.index("error")]
        resync_times += list(t[data[:, header.index("resynced")] > 0])
        traces.append((episode["id"], t, err))
        series.append({"episode": episode["id"], "start_s": offset, "end_s": float(t[-1]),
                       "mean_error": float(np.mean(err)), "max_error": float(np.max(err))})
        offset = float(t[-1])
    plot_overlay(ax, traces, ylabel="normalised state error", title="drift over time (episodes back to back)")
    for when in resync_times[:400]:
        ax.axvline(when, color="0.8", linewidth=0.5, zorder=0)
    colors = {"alarm_raised": "red", "alarm_cleared": "green", "knobs_updated": "purple"}
    for event in events:
        if event.get("event") in colors:
            ax.axvline(float(event["t"]), color=colors[event["event"]], linestyle="--", linewidth=1.2)
    return _png_bytes(fig), series


def write_sync_report(out_dir: Path, *, lockstep: LockstepResult | Path | None = None,
                      prediction: PredictionResult | Path | Sequence[tuple[str, PredictionResult | Path]] | None = None,
                      events: Path | Sequence[Mapping[str, Any]] | None = None, title: str = "Twin synchronisation") -> Path:
    """Write ``report.html`` and ``report.json`` into ``out_dir``; returns the HTML path.

    Args:
        lockstep: A lockstep result or its folder (drift over time, error by horizon, episodes).
        prediction: A prediction-error result or folder, or labelled ones (``[("before", a), ("after", b)]``).
        events: A monitor event log (JSONL path or events); defaults to the lockstep folder's log, if any.
    """
    if lockstep is None and prediction is None and events is None:
        raise DualtwinError("nothing to report: give a lockstep run, a prediction-error run or monitor events")
    out = Path(out_dir)
    record: dict[str, Any] = {"schema": REPORT_SCHEMA, "title": title}
    parts = ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>", f"<title>{html.escape(title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"]

    event_list: list[dict[str, Any]] = []
    folder: Path | None = None
    manifest: dict[str, Any] = {}
    if lockstep is not None:
        folder, manifest = _lockstep_data(lockstep)
        log = folder / "monitor_events.jsonl"
        if events is None and log.is_file():
            events = log
    if events is not None:
        event_list = read_events(Path(events)) if isinstance(events, str | Path) else [dict(e) for e in events]

    # Prediction error.
    labelled: list[tuple[str, dict[str, Any]]] = []
    if prediction is not None:
        items: list[tuple[str, PredictionResult | Path]]
        if isinstance(prediction, PredictionResult | Path):
            items = [("prediction", prediction)]
        else:
            items = list(prediction)
        for label, item in items:
            if isinstance(item, PredictionResult):
                labelled.append((str(label), item.table))
            else:
                labelled.append((str(label), read_json(Path(item) / "prediction.json")["table"]))
        png_path = plot_prediction(labelled, out / "prediction.png")
        record["prediction"] = {label: {h: row["normalized_rms"] for h, row in table["by_horizon"].items()}
                                for label, table in labelled}
        parts.append("<h2>Short-horizon prediction error</h2><p>From synchronised start states along the "
                     "reference trajectories; normalised RMS over all state channels (1 = one scale unit off).</p>")
        horizons = [str(h) for h in labelled[0][1]["horizons"]]
        parts.append("<table><tr><th class='l'>series</th>" + "".join(f"<th>h = {h}</th>" for h in horizons) + "</tr>")
        for label, table in labelled:
            cells = "".join(f"<td>{_fmt(table['by_horizon'].get(h, {}).get('normalized_rms'))}</td>" for h in horizons)
            parts.append(f"<tr><td class='l'>{html.escape(label)}</td>{cells}</tr>")
        parts.append("</table>")
        main = labelled[0][1]
        last = main["by_horizon"][horizons[-1]]["rms"]
        top = sorted(last, key=lambda c: -(last[c] if last[c] is not None and math.isfinite(last[c]) else -1))[:8]
        parts.append(f"<table><tr><th class='l'>channel ({html.escape(labelled[0][0])})</th>"
                     + "".join(f"<th>RMS h = {h}</th>" for h in horizons)
                     + "".join(f"<th>no-change h = {h}</th>" for h in horizons) + "</tr>")
        for c in top:
            cells = "".join(f"<td>{_fmt(main['by_horizon'][h]['rms'][c])}</td>" for h in horizons)
            cells += "".join(f"<td>{_fmt(main['by_horizon'][h]['no_change_rms'][c])}</td>" for h in horizons)
            parts.append(f"<tr><td class='l'>{html.escape(c)}</td>{cells}</tr>")
        parts.append("</table>" + _img(png_path.read_bytes(), "prediction error"))

    # Lockstep drift.
    if folder is not None:
        png, series = _drift_png(folder, manifest, event_list)
        record["lockstep"] = {"folder": str(folder), "primary": manifest.get("primary"),
                              "secondary": manifest.get("secondary"), "resync": manifest.get("resync"),
                              "error_by_horizon": manifest.get("error_by_horizon", {}), "episodes": series,
                              "knob_updates": manifest.get("knob_updates", [])}
        parts.append(f"<h2>Drift over time</h2><p>{_fmt(manifest.get('primary'))} (primary) vs "
                     f"{_fmt(manifest.get('secondary'))}, re-sync <code>{_fmt(manifest.get('resync'))}</code>; grey "
                     "lines: re-syncs; red/green dashed: alarm raised/cleared; purple: knob update.</p>")
        parts.append(_img(png, "drift over time"))
        parts.append("<table><tr><th class='l'>episode</th><th>status</th><th>periods</th><th>re-syncs</th>"
                     "<th>mean error</th><th>max error</th><th>final error</th></tr>")
        for ep in manifest.get("episodes", []):
            parts.append(f"<tr><td class='l'>{_fmt(ep['id'])}</td><td>{_fmt(ep['status'])}</td><td>{ep['steps']}</td>"
                         f"<td>{ep['resyncs']}</td><td>{_fmt(ep['mean_error'])}</td><td>{_fmt(ep['max_error'])}</td>"
                         f"<td>{_fmt(ep['final_error'])}</td></tr>")
        parts.append("</table>")
        by_h = manifest.get("error_by_horizon", {})
        if by_h:
            shown = list(by_h.items())[:30]
            parts.append("<h3>Error by periods since the last sync</h3><table><tr><th>periods</th>"
                         + "".join(f"<th>{h}</th>" for h, _ in shown) + "</tr><tr><td>mean error</td>"
                         + "".join(f"<td>{_fmt(v)}</td>" for _, v in shown) + "</tr></table>")

    # Alarms and re-alignments.
    if event_list:
        listed = [e for e in event_list if e.get("event") in TABLE_EVENTS]
        record["events"] = listed
        record["windows"] = [{"t": e["t"], "episode": e.get("episode"), "value": e.get("value"),
                              "alarm": e.get("alarm")} for e in event_list if e.get("event") == "window"]
        parts.append("<h2>Alarms and re-alignments</h2>")
        if not listed:
            parts.append("<p>No alarm was raised.</p>")
        else:
            parts.append("<table><tr><th>t [s]</th><th class='l'>episode</th><th class='l'>event</th>"
                         "<th class='l'>evidence</th></tr>")
            for e in listed:
                evidence = {k: v for k, v in e.items() if k not in ("seq", "t", "episode", "event")}
                parts.append(f"<tr><td>{_fmt(e['t'])}</td><td class='l'>{_fmt(e.get('episode'))}</td>"
                             f"<td class='l'>{_fmt(e['event'])}</td><td class='l'><code>"
                             f"{html.escape(json.dumps(evidence, sort_keys=True)[:600])}</code></td></tr>")
            parts.append("</table>")
    parts.append("</body></html>")
    write_json(out / "report.json", json_safe(record))
    path = out / "report.html"
    write_text(path, "\n".join(parts))
    return path

