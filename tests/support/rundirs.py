"""Fabricate suite run directories following the runner's contract (manifest + TSV logs)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

CHANNELS: dict[str, dict[str, str]] = {
    "pole_angle_rad": {"source": "ground_truth", "unit": "rad"},
    "cart_pos_m": {"source": "ground_truth", "unit": "m"},
    "wheel_vel_rad_s": {"source": "onboard", "unit": "rad/s"},
}

# scenario id -> channel -> (t, y); status per scenario id (default "completed").
ScenarioData = Mapping[str, Mapping[str, tuple[np.ndarray, np.ndarray]]]


def write_tsv(path: Path, names: list[str], t: np.ndarray, columns: list[np.ndarray]) -> None:
    lines = ["\t".join(["time_s", *names])]
    for i in range(len(t)):
        lines.append("\t".join(repr(float(v)) for v in [t[i], *(c[i] for c in columns)]))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def fabricate_run(
    root: Path,
    data: ScenarioData,
    *,
    twin: str = "mujoco",
    channels: Mapping[str, Mapping[str, str]] | None = None,
    statuses: Mapping[str, str] | None = None,
    tolerances: Mapping[str, Any] | None = None,
    skip_logs: tuple[str, ...] = (),
) -> Path:
    """Write ``root/manifest.json`` and one onboard/ground-truth TSV pair per scenario.

    Channels listed in ``channels`` but absent from a scenario's data are left out of its logs; scenario
    ids in ``skip_logs`` get no log files at all (an unstable run that crashed early).
    """
    channels = dict(CHANNELS if channels is None else channels)
    statuses = dict(statuses or {})
    root.mkdir(parents=True, exist_ok=True)
    entries = []
    for index, (sid, series) in enumerate(data.items()):
        entry: dict[str, Any] = {
            "id": sid,
            "index": index,
            "name": sid.split("_", 1)[-1],
            "status": statuses.get(sid, "completed"),
            "failure": None,
        }
        for source in ("onboard", "ground_truth"):
            rel = f"scenarios/{sid}/{source}.tsv"
            entry[source] = rel
            names = [n for n, spec in channels.items() if spec["source"] == source and n in series]
            if sid in skip_logs or not names:
                continue
            t = series[names[0]][0]
            write_tsv(root / rel, names, t, [series[n][1] for n in names])
        entries.append(entry)
    manifest = {
        "twin": twin,
        "robot": "cartpole",
        "suite_name": "unit",
        "control_period_s": 0.032,
        "seed": 0,
        "scenarios": entries,
        "channels": channels,
        "tolerances": dict(tolerances or {}),
    }
    (root / "manifest.json").write_text(json.dumps(manifest, indent=2), encoding="utf-8")
    return root


def cartpole_like(
    t: np.ndarray, *, delay: float = 0.0, gain: float = 1.0
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Three channels resembling a falling pole: angle grows like cosh, cart drifts, wheels oscillate."""
    ts = t - delay
    return {
        "pole_angle_rad": (t, gain * 0.05 * np.cosh(1.5 * ts)),
        "cart_pos_m": (t, 0.2 * np.sin(0.8 * ts) + 0.01 * ts),
        "wheel_vel_rad_s": (t, 3.0 * np.cos(2.0 * ts)),
    }


def fabricate_ensemble(root: Path, members: list[dict[str, np.ndarray]], twin: str,
                       t: np.ndarray) -> Path:
    """A one-scenario run folder (``00_fall``) with ensemble members laid out as
    `dualtwin.suite.ensemble` writes them; member 0 is the main log."""
    root.mkdir(parents=True)
    channels = {"pole_angle_rad": {"source": "ground_truth", "unit": "rad"},
                "cart_pos_m": {"source": "ground_truth", "unit": "m"}}
    names = list(channels)
    write_tsv(root / "scenarios/00_fall/ground_truth.tsv", names, t, [members[0][n] for n in names])
    record = {"id": "00_fall", "index": 0, "name": "fall", "status": "completed",
              "ground_truth": "scenarios/00_fall/ground_truth.tsv", "members": []}
    for k, m in enumerate(members[1:], start=1):
        rel = f"scenarios/00_fall/members/{k}/ground_truth.tsv"
        write_tsv(root / rel, names, t, [m[n] for n in names])
        record["members"].append({"member": k, "status": "completed", "ground_truth": rel})
    manifest = {"twin": twin, "robot": "cartpole", "suite_name": "unit", "scenarios": [record],
                "channels": channels}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root
