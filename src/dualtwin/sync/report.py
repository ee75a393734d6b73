"""The synchronisation report: prediction-error curves, drift over time, alarms and re-alignments.

``write_sync_report(out, lockstep=..., prediction=..., events=...)`` writes ``report.json`` (every number
shown) and a self-contained ``report.html`` with embedded PNGs, built with :mod:`dualtwin.reporting`. Twins are
named by their twin names from the lockstep manifest; monitor evidence shows as tables, not JSON.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from dualtwin.artifacts import json_safe, write_json, write_text
from dualtwin.divergence.channels import channel_unit
from dualtwin.divergence.prediction import PredictionResult, plot_prediction
from dualtwin.divergence.runs import load_tsv
from dualtwin.errors import DualtwinError
from dualtwin.reporting import esc, evidence_html, html_table, img_html, page_head, plot_overlay, png_bytes
from dualtwin.suite.loader import read_json
from dualtwin.sync.lockstep import LockstepResult
from dualtwin.sync.monitor import read_events

REPORT_SCHEMA = "dualtwin.sync-report/1"
#: Monitor events listed in the alarms table.
TABLE_EVENTS = ("alarm_raised", "alarm_cleared", "realign_started", "knobs_updated", "realign_rejected",
                "realign_failed", "realign_skipped")


_img = img_html
_fmt = esc


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
    plot_overlay(ax, traces, ylabel="normalised state error [1 = one scale unit off]",
                 title=f"{manifest.get('secondary', 'secondary')} against {manifest.get('primary', 'primary')} "
                       "(primary): drift over time, episodes back to back")
    for when in resync_times[:400]:
        ax.axvline(when, color="0.8", linewidth=0.5, zorder=0)
    colors = {"alarm_raised": "red", "alarm_cleared": "green", "knobs_updated": "purple"}
    for event in events:
        if event.get("event") in colors:
            ax.axvline(float(event["t"]), color=colors[event["event"]], linestyle="--", linewidth=1.2)
    return png_bytes(fig), series


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
    parts = [page_head(title), f"<h1>{html.escape(title)}</h1>"]

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
        parts.append(html_table(["series", *(f"h = {h}" for h in horizons)],
                                [[label, *(table["by_horizon"].get(h, {}).get("normalized_rms") for h in horizons)]
                                 for label, table in labelled]))
        main = labelled[0][1]
        last = main["by_horizon"][horizons[-1]]["rms"]
        top = sorted(last, key=lambda c: -(last[c] if last[c] is not None and math.isfinite(last[c]) else -1))[:8]
        parts.append(html_table(
            [f"channel ({labelled[0][0]})", *(f"RMS h = {h}" for h in horizons),
             *(f"no-change h = {h}" for h in horizons)],
            [[f"{c} [{channel_unit(c)}]", *(main["by_horizon"][h]["rms"][c] for h in horizons),
              *(main["by_horizon"][h]["no_change_rms"][c] for h in horizons)] for c in top]))
        parts.append(_img(png_path.read_bytes(), "prediction error"))

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
        parts.append(html_table(
            ["episode", "status", "periods", "re-syncs", "mean error", "max error", "final error"],
            [[ep["id"], ep["status"], ep["steps"], ep["resyncs"], ep["mean_error"], ep["max_error"], ep["final_error"]]
             for ep in manifest.get("episodes", [])]))
        by_h = manifest.get("error_by_horizon", {})
        if by_h:
            shown = list(by_h.items())[:30]
            parts.append("<h3>Error by periods since the last sync</h3>")
            parts.append(html_table(["periods", *(str(h) for h, _ in shown)], [["mean error", *(v for _, v in shown)]]))

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
            parts.append(html_table(
                ["t [s]", "episode", "event", "evidence"],
                [[e["t"], e.get("episode"), str(e["event"]),
                  evidence_html({k: v for k, v in sorted(e.items()) if k not in ("seq", "t", "episode", "event")})]
                 for e in listed], left=(1, 2, 3), raw=(3,)))
    parts.append("</body></html>")
    write_json(out / "report.json", json_safe(record))
    path = out / "report.html"
    write_text(path, "\n".join(parts))
    return path

