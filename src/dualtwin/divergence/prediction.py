"""Short-horizon prediction error: the chaos-insensitive measure of model mismatch.

Open-loop comparisons of two twins over seconds mostly measure how chaotic the task is: a falling pole
amplifies a micro-radian difference into a different fall. Here the secondary twin is put into the
reference's state at many start points along recorded trajectories (multiple shooting), driven with the
recorded commands for ``h`` control periods, and compared with where the reference went. Errors at
``h = 1, 5, 25`` periods show how fast the models drift apart, and for identical models they are zero.

The same rollouts give the residual vector of the ``prediction`` alignment objective
(:mod:`dualtwin.align.prediction`): scaled per channel (:mod:`dualtwin.divergence.channels`), one block per
(trajectory, start, horizon), ``√(1/count)``-weighted so that its squared norm is the mean squared
normalised prediction error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import json_safe, package_versions, sha256_file, write_json, write_text
from dualtwin.divergence.channels import channel_scales
from dualtwin.divergence.trajectories import (
    Command,
    Trajectory,
    record_trajectories,
    replay,
    save_trajectories,
)
from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.loader import load_suite
from dualtwin.suite.runner import check_against_binding
from dualtwin.twins import make_twin
from dualtwin.twins.base import SyncError, Twin

DEFAULT_HORIZONS = (1, 5, 25)
#: Residual, in scale units, of every channel of a rollout that blew up or could not be synchronised.
UNSTABLE_RESIDUAL = 3.0


@dataclass(frozen=True)
class PredictionSettings:
    """Which rollouts to run: horizons in control periods, a start every ``stride`` periods."""

    horizons: tuple[int, ...] = DEFAULT_HORIZONS
    stride: int = 5
    scales: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.horizons or min(self.horizons) < 1:
            raise DualtwinError(f"horizons must be positive control-period counts, got {list(self.horizons)}")
        if self.stride < 1:
            raise DualtwinError(f"stride must be at least 1, got {self.stride}")

    def to_dict(self) -> dict[str, Any]:
        return {"horizons": list(self.horizons), "stride": self.stride, "scales": dict(self.scales)}


def rollout_plan(trajectories: Sequence[Trajectory], settings: PredictionSettings) -> list[tuple[int, int, list[int]]]:
    """(trajectory index, start index, horizons reachable from it) for every start (starts 0, stride, ...)."""
    plan = []
    for t, traj in enumerate(trajectories):
        n = len(traj)
        for start in range(0, max(n - 1, 0), settings.stride):
            reachable = [h for h in sorted(settings.horizons) if start + h <= n - 1]
            if reachable:
                plan.append((t, start, reachable))
    return plan


@dataclass
class PredictionSamples:
    """Prediction errors of every rollout: ``errors[h]`` is (rollouts reaching h) × channels, in physical units."""

    channels: list[str]
    horizons: list[int]
    errors: dict[int, np.ndarray]
    baseline: dict[int, np.ndarray]
    failed: dict[int, np.ndarray]
    steps: int = 0
    unstable: list[str] = field(default_factory=list)

    def residuals(self, scales: Mapping[str, float]) -> np.ndarray:
        """Scaled residuals, fixed length for one reference, ``‖r‖² =`` mean squared normalised error."""
        columns = [i for i, c in enumerate(self.channels) if math.isfinite(scales[c])]
        scale = np.array([scales[self.channels[i]] for i in columns])
        parts = []
        total = sum(self.errors[h].shape[0] for h in self.horizons) * len(columns)
        weight = 1.0 / math.sqrt(max(total, 1))
        for h in self.horizons:
            block = self.errors[h][:, columns] / scale
            block[self.failed[h]] = UNSTABLE_RESIDUAL
            parts.append(block.ravel() * weight)
        out = np.concatenate(parts) if parts else np.zeros(0)
        return np.where(np.isfinite(out), out, UNSTABLE_RESIDUAL * weight)

    def table(self, scales: Mapping[str, float]) -> dict[str, Any]:
        """RMS error per horizon and channel (physical units), normalised RMS, and the no-change baseline."""
        rows = {}
        for h in self.horizons:
            ok = ~self.failed[h]
            err, base = self.errors[h][ok], self.baseline[h][ok]
            rms = np.sqrt(np.mean(err ** 2, axis=0)) if len(err) else np.full(len(self.channels), math.nan)
            base_rms = np.sqrt(np.mean(base ** 2, axis=0)) if len(base) else np.full(len(self.channels), math.nan)
            finite = [i for i, c in enumerate(self.channels) if math.isfinite(scales[c])]
            scaled = err[:, finite] / np.array([scales[self.channels[i]] for i in finite]) if len(err) else err
            rows[str(h)] = {
                "rollouts": int(self.errors[h].shape[0]), "failed": int(self.failed[h].sum()),
                "normalized_rms": float(np.sqrt(np.mean(scaled ** 2))) if scaled.size else math.nan,
                "rms": {c: float(v) for c, v in zip(self.channels, rms, strict=True)},
                "no_change_rms": {c: float(v) for c, v in zip(self.channels, base_rms, strict=True)},
            }
        return {"horizons": list(self.horizons), "channels": list(self.channels), "by_horizon": rows,
                "unstable": list(self.unstable), "simulated_periods": self.steps}


def predict(twin: Twin, trajectories: Sequence[Trajectory], settings: PredictionSettings,
            seed: int = 0) -> PredictionSamples:
    """Synchronise ``twin`` to each start state, replay the recorded commands, collect errors per horizon.

    The twin is reset before every rollout (controller state such as PID integrals starts clean), then
    ``set_state`` puts it into the recorded state. A start the twin refuses (:class:`SyncError`) or a rollout
    that blows up counts as failed for the horizons it did not reach.
    """
    if not trajectories:
        raise DualtwinError("no reference trajectories to predict")
    plan = rollout_plan(trajectories, settings)
    if not plan:
        raise DualtwinError(f"the reference trajectories are too short for horizon {min(settings.horizons)}")
    probe = trajectories[0].state(0)
    channels = probe.diff_channels()
    horizons = sorted(settings.horizons)
    errors: dict[int, list[np.ndarray]] = {h: [] for h in horizons}
    baseline: dict[int, list[np.ndarray]] = {h: [] for h in horizons}
    failed: dict[int, list[bool]] = {h: [] for h in horizons}
    steps = 0
    unstable: list[str] = []
    for t, start, reachable in plan:
        traj = trajectories[t]
        origin = traj.state(start)
        ok = True
        try:
            twin.reset(seed)
            twin.set_state(origin)
        except SyncError as exc:
            ok = False
            unstable.append(f"{traj.id}@{start}: {exc}")
        previous: dict[str, Command] | None = None
        done = 0
        for h in reachable:
            while ok and done < h:
                active = traj.active(start + done + 1)
                replay(twin, active, previous)
                previous = active
                try:
                    twin.step()
                except SimulationUnstable as exc:
                    ok = False
                    unstable.append(f"{traj.id}@{start}+{done + 1}: {exc}")
                    break
                done += 1
                steps += 1
            target = traj.state(start + h)
            if ok:
                diff = target.difference(twin.get_state())
                errors[h].append(np.array([diff[c] for c in channels]))
            else:
                errors[h].append(np.full(len(channels), math.nan))
            no_change = target.difference(origin)
            baseline[h].append(np.array([-no_change[c] for c in channels]))
            failed[h].append(not ok)
    return PredictionSamples(
        channels, horizons,
        {h: np.array(errors[h]).reshape(len(errors[h]), len(channels)) for h in horizons},
        {h: np.array(baseline[h]).reshape(len(baseline[h]), len(channels)) for h in horizons},
        {h: np.array(failed[h], dtype=bool) for h in horizons}, steps, unstable)


@dataclass
class PredictionResult:
    """What :func:`prediction_error` measured and wrote."""

    out_dir: Path
    table: dict[str, Any]
    files: dict[str, str]

    def normalized_rms(self) -> dict[int, float]:
        return {int(h): float(v["normalized_rms"]) for h, v in self.table["by_horizon"].items()}


def plot_prediction(series: Sequence[tuple[str, Mapping[str, Any]]], path: Path,
                    channels: Sequence[str] | None = None) -> Path:
    """PNG: normalised RMS error against horizon (log-log) for each labelled table, and per-channel RMS of the
    first one for its largest channels (or ``channels``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from dualtwin.artifacts import write_bytes
    from dualtwin.divergence.channels import channel_unit
    from dualtwin.reporting import literal_legend, plot_unit_groups
    from dualtwin.reporting import png_bytes as _png_bytes

    if not series:
        raise ValueError("nothing to plot")
    main = series[0][1]
    hs = [int(h) for h in main["by_horizon"]]
    last = main["by_horizon"][str(hs[-1])]["rms"]
    chosen = list(channels) if channels else sorted(last, key=lambda c: -abs(last[c]) if math.isfinite(last[c]) else 0)[:6]
    # One axes per unit: metres, radians and their rates never share an axis.
    units = list(dict.fromkeys(channel_unit(c) for c in chosen))
    fig = Figure(figsize=(4.0 * (1 + max(1, len(units))), 3.8), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(1, 1 + max(1, len(units)))
    left = fig.add_subplot(grid[0, 0])
    for label, tab in series:
        hs_ = [int(h) for h in tab["by_horizon"]]
        values = [tab["by_horizon"][str(h)]["normalized_rms"] for h in hs_]
        left.plot(hs_, np.maximum(values, 1e-16), marker="o", label=label)
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("horizon [control periods]")
    left.set_ylabel("normalised RMS prediction error [1 = one scale unit]")
    left.grid(True, which="both", alpha=0.3)
    literal_legend(left.legend(fontsize=8))
    right = fig.add_subfigure(grid[0, 1:])
    plot_unit_groups(right, {c: (hs, [max(main["by_horizon"][str(h)]["rms"][c], 1e-16) for h in hs]) for c in chosen},
                     channel_unit, quantity="RMS error", xlabel="horizon [control periods]", log=True)
    right.suptitle(series[0][0], fontsize=9, parse_math=False)
    write_bytes(path, _png_bytes(fig))
    return path


def table_tsv(table: Mapping[str, Any]) -> str:
    """One row per channel, RMS at each horizon, then the normalised RMS row."""
    hs = [str(h) for h in table["horizons"]]
    lines = ["\t".join(["channel", *(f"rms_h{h}" for h in hs), *(f"no_change_h{h}" for h in hs)])]
    for c in table["channels"]:
        rms = [repr(table["by_horizon"][h]["rms"][c]) for h in hs]
        base = [repr(table["by_horizon"][h]["no_change_rms"][c]) for h in hs]
        lines.append("\t".join([c, *rms, *base]))
    lines.append("\t".join(["normalized", *(repr(table["by_horizon"][h]["normalized_rms"]) for h in hs),
                            *("" for _ in hs)]))
    return "\n".join(lines) + "\n"


def prediction_error(primary: str | Twin, secondary: str | Twin, robot: str | RobotBinding, *, suite: Path,
                     out_dir: Path, horizons: Sequence[int] = DEFAULT_HORIZONS, stride: int = 5, seed: int = 0,
                     scales: Mapping[str, float] | None = None, scenarios: Sequence[str] | None = None,
                     primary_knobs: Mapping[str, float] | None = None,
                     secondary_knobs: Mapping[str, float] | None = None) -> PredictionResult:
    """Record the suite on the primary twin, then measure the secondary's k-step prediction error from it.

    Writes ``OUT/prediction.json`` (table, settings, provenance), ``OUT/prediction.tsv``,
    ``OUT/prediction.png`` and ``OUT/trajectories.npz`` (the primary's recording, reusable as an alignment
    reference).
    """
    binding = resolve_robot(robot) if isinstance(robot, str) else robot
    suite_path = Path(suite)
    suite_obj = load_suite(suite_path)
    check_against_binding(suite_obj, suite_path, binding)
    period = suite_obj.global_settings.control_period_s
    settings = PredictionSettings(tuple(int(h) for h in horizons), int(stride), dict(scales or {}))
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()):
        raise DualtwinError(f"{out}: output folder is not empty; choose another folder")
    a = make_twin(primary, binding, period) if isinstance(primary, str) else primary
    b = make_twin(secondary, binding, period) if isinstance(secondary, str) else secondary
    owned = [t for t, given in ((a, primary), (b, secondary)) if isinstance(given, str)]
    try:
        a.set_knobs(dict(primary_knobs or {}))
        b.set_knobs(dict(secondary_knobs or {}))
        trajectories = record_trajectories(a, binding, suite_obj, scenarios, seed)
        samples = predict(b, trajectories, settings, seed)
    finally:
        for t in owned:
            t.close()
    scale_map = channel_scales(samples.channels, settings.scales)
    table = samples.table(scale_map)
    table["scales"] = scale_map
    files = {"json": "prediction.json", "tsv": "prediction.tsv", "png": "prediction.png",
             "trajectories": "trajectories.npz"}
    save_trajectories(out / files["trajectories"], trajectories,
                      {"twin": a.name, "robot": binding.name, "knobs": dict(primary_knobs or {}), "seed": seed})
    write_text(out / files["tsv"], table_tsv(table))
    plot_prediction([(f"{b.name} from {a.name}", table)], out / files["png"])
    record = {
        "schema": "dualtwin.prediction/1", "primary": a.name, "secondary": b.name, "robot": binding.name,
        "seed": seed, "settings": settings.to_dict(), "control_period_s": period,
        "knobs": {"primary": dict(primary_knobs or {}), "secondary": dict(secondary_knobs or {})},
        "inputs": {"suite": {"path": str(suite_path), "sha256": sha256_file(suite_path)},
                   "binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)}},
        "versions": package_versions(), "table": json_safe(table), "files": files,
    }
    write_json(out / files["json"], record)
    return PredictionResult(out, table, files)

