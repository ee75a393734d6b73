"""Compare two loaded suite runs scenario by scenario: channel divergences, floors, tolerances, ranking.

The runs come from :func:`dualtwin.divergence.runs.load_run`; the numbers from
:mod:`dualtwin.divergence.metrics` and :mod:`dualtwin.divergence.floor`.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import json_safe
from dualtwin.divergence.floor import ChannelFloor, FloorJudgement, ensemble_floor, judge_against_floor
from dualtwin.divergence.metrics import (
    DEFAULT_MAX_LAG_S,
    DEFAULT_WEIGHTS,
    ChannelDivergence,
    ScoreWeights,
    Threshold,
    compare_channel,
    default_resolution,
    finite_prefix,
    significance,
)
from dualtwin.divergence.runs import Run, Series, load_run
from dualtwin.errors import DualtwinError

#: Crossing threshold applied to every channel whose name ends in ``_angle_rad``: the paper's pole-fall event.
DEFAULT_ANGLE_THRESHOLD_RAD = 0.99

# Metrics a manifest tolerance may bound, compared by absolute value.
TOLERANCE_METRICS = (
    "mse",
    "rmse",
    "dtw",
    "dtw_rms",
    "max_abs_error",
    "final_diff",
    "lag_s",
    "crossing_diff_s",
    "score",
)


@dataclass(frozen=True)
class ToleranceViolation:
    """A metric above its manifest tolerance (``limit``); ``value`` None means only one twin crossed."""

    channel: str
    metric: str
    value: float | None
    limit: float

    def to_dict(self) -> dict[str, Any]:
        return {"channel": self.channel, "metric": self.metric, "value": self.value, "limit": self.limit}


@dataclass(frozen=True)
class ScenarioComparison:
    """One scenario compared between twin A and twin B.

    Attributes:
        id: Scenario id (matched between the runs).
        index: Position in the suite.
        name: Scenario name.
        status_a: Status in run A (``completed``, ``failed`` or ``unstable``).
        status_b: Status in run B.
        failure_a: Run A's failure record, if any.
        failure_b: Run B's failure record, if any.
        channels: Metrics per channel; channels that could not be compared are absent.
        score: Mean channel score, 1.0 when exactly one twin is unstable, None when nothing was comparable.
        note: Why channels are missing or the score was overridden.
        tolerance_violations: Metrics above the manifest tolerances.
        series_a: Run A's raw series (for plots; not serialised).
        series_b: Run B's raw series.
    """

    id: str
    index: int
    name: str
    status_a: str
    status_b: str
    failure_a: Mapping[str, Any] | None
    failure_b: Mapping[str, Any] | None
    channels: Mapping[str, ChannelDivergence]
    score: float | None
    note: str | None = None
    tolerance_violations: tuple[ToleranceViolation, ...] = ()
    #: Per channel, the divergence judged against the sides' reproducibility floors (ensembles only).
    floors: Mapping[str, FloorJudgement] = field(default_factory=dict)
    series_a: Mapping[str, Series] = field(default_factory=dict, repr=False, compare=False)
    series_b: Mapping[str, Series] = field(default_factory=dict, repr=False, compare=False)

    @property
    def unstable(self) -> bool:
        """True if either twin blew up."""
        return "unstable" in (self.status_a, self.status_b)

    @property
    def unstable_one_sided(self) -> bool:
        """True if exactly one twin blew up (the scenario then scores 1.0)."""
        return (self.status_a == "unstable") != (self.status_b == "unstable")

    @property
    def within_tolerance(self) -> bool:
        return not self.tolerance_violations

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "index": self.index,
            "name": self.name,
            "status_a": self.status_a,
            "status_b": self.status_b,
            "failure_a": None if self.failure_a is None else dict(self.failure_a),
            "failure_b": None if self.failure_b is None else dict(self.failure_b),
            "score": self.score,
            "note": self.note,
            "channels": {name: ch.to_dict() for name, ch in self.channels.items()},
            "tolerance_violations": [v.to_dict() for v in self.tolerance_violations],
            "floors": {name: f.to_dict() for name, f in self.floors.items()},
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScenarioComparison:
        """Inverse of `to_dict` (without the raw series)."""
        return cls(
            id=data["id"],
            index=int(data["index"]),
            name=data["name"],
            status_a=data["status_a"],
            status_b=data["status_b"],
            failure_a=data.get("failure_a"),
            failure_b=data.get("failure_b"),
            channels={k: ChannelDivergence.from_dict(v) for k, v in data["channels"].items()},
            score=data.get("score"),
            note=data.get("note"),
            tolerance_violations=tuple(ToleranceViolation(**v) for v in data.get("tolerance_violations", [])),
            floors={k: FloorJudgement.from_dict(v) for k, v in (data.get("floors") or {}).items()},
        )


@dataclass(frozen=True)
class Contribution:
    """How much one scenario × channel adds to the summary score (``share`` of it, 0..1)."""

    scenario_id: str
    channel: str | None
    contribution: float
    share: float


@dataclass(frozen=True)
class RunComparison:
    """Two runs of one suite compared scenario by scenario.

    Attributes:
        run_a: Path of run A.
        run_b: Path of run B.
        twin_a: Twin of run A (e.g. ``mujoco``).
        twin_b: Twin of run B.
        robot: Robot name (identical in both runs).
        suite_name: Suite name of run A.
        scenarios: Per-scenario results in suite order.
        units: Unit per channel.
        settings: The resolved comparison settings (thresholds, weights, max lag, definitions).
        summary_score: Mean scenario score over scenarios with a score, None if none has one.
        left_out: What only one run has and was therefore not compared: ``{"scenarios": {id: why},
            "channels": {name: why}}`` (a recording usually logs fewer channels than a twin).
    """

    run_a: str
    run_b: str
    twin_a: str
    twin_b: str
    robot: str
    suite_name: str
    scenarios: tuple[ScenarioComparison, ...]
    units: Mapping[str, str]
    settings: Mapping[str, Any]
    summary_score: float | None
    left_out: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    #: Notes on the runs' data that explain differences without physics (a recording whose scenario starts
    #: where the previous one ended), each naming its run: see `state_notes`.
    data_notes: tuple[str, ...] = ()

    @property
    def channel_names(self) -> list[str]:
        return list(self.units)

    @property
    def within_tolerance(self) -> bool:
        return all(s.within_tolerance for s in self.scenarios)

    def judgement_lines(self) -> list[str]:
        """Plain-word lines: what was left out and why, and each channel judged against its floor."""
        lines = [f"left out {what[:-1]} {name}: {why}" for what, names in self.left_out.items()
                 for name, why in names.items()]
        lines.extend(self.data_notes)
        for sc in self.scenarios:
            lines.extend(f"{sc.id} / {name}: {judged.verdict}" for name, judged in sc.floors.items())
        return lines

    def contributions(self) -> list[Contribution]:
        """Scenario × channel pairs ranked by physical significance, largest first.

        ``contribution`` is the pair's significance (``rmse / max(resolution, rmse floor)``, see
        `dualtwin.divergence.metrics`) and ``share`` its part of the sum over ranked pairs. Pairs at or below
        their resolution or floor (significance <= 1) never rank. A scenario in which exactly one twin blew
        up is one entry with ``channel=None`` that counts as much as every other ranked pair together.

        Comparisons without significances (loaded from older JSON) rank by the score as before: shares of
        the summary score, summing to it.
        """
        pairs = [(sc, name, ch) for sc in self.scenarios for name, ch in sc.channels.items()]
        if pairs and all(ch.significance is not None for _, _, ch in pairs):
            ranked = [(sc.id, name, float(ch.significance or 0.0)) for sc, name, ch in pairs
                      if not sc.unstable_one_sided and (ch.significance or 0.0) > 1.0]
            rest = sum(v for *_, v in ranked)
            blown = [sc.id for sc in self.scenarios if sc.unstable_one_sided]
            entries = [(sid, None, rest or 1.0) for sid in blown] + ranked
            total = sum(v for *_, v in entries)
            return sorted((Contribution(sid, name, v, v / total) for sid, name, v in entries),
                          key=lambda c: (-c.contribution, c.scenario_id, c.channel or ""))
        scored = [s for s in self.scenarios if s.score is not None]
        if not scored or not self.summary_score:
            return []
        out: list[Contribution] = []
        for sc in scored:
            assert sc.score is not None
            per_scenario = sc.score / len(scored)
            if sc.unstable_one_sided or not sc.channels:
                out.append(Contribution(sc.id, None, per_scenario, per_scenario / self.summary_score))
                continue
            for name, ch in sc.channels.items():
                c = ch.score / len(sc.channels) / len(scored)
                out.append(Contribution(sc.id, name, c, c / self.summary_score))
        return sorted(out, key=lambda c: c.contribution, reverse=True)

    def to_dict(self) -> dict[str, Any]:
        return {
            "run_a": self.run_a,
            "run_b": self.run_b,
            "twin_a": self.twin_a,
            "twin_b": self.twin_b,
            "robot": self.robot,
            "suite_name": self.suite_name,
            "summary_score": self.summary_score,
            "units": dict(self.units),
            "settings": json_safe(self.settings),
            "scenarios": [s.to_dict() for s in self.scenarios],
            "left_out": {k: dict(v) for k, v in self.left_out.items()},
            "data_notes": list(self.data_notes),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunComparison:
        """Inverse of `to_dict` (without raw series), e.g. to reload ``metrics.json``."""
        return cls(
            run_a=data["run_a"],
            run_b=data["run_b"],
            twin_a=data["twin_a"],
            twin_b=data["twin_b"],
            robot=data["robot"],
            suite_name=data["suite_name"],
            scenarios=tuple(ScenarioComparison.from_dict(s) for s in data["scenarios"]),
            units=dict(data["units"]),
            settings=data["settings"],
            summary_score=data.get("summary_score"),
            left_out=data.get("left_out") or {},
            data_notes=tuple(data.get("data_notes") or ()),
        )



def resolve_thresholds(
    channels: list[str], thresholds: Mapping[str, float | Threshold | None] | None
) -> dict[str, Threshold]:
    """Per-channel crossing thresholds: ``*_angle_rad`` defaults to 0.99 rad, overridden by ``thresholds``.

    A value of None in ``thresholds`` switches a default off.

    Raises:
        ValueError: If ``thresholds`` names a channel that is not compared.
    """
    overrides = dict(thresholds or {})
    unknown = sorted(set(overrides) - set(channels))
    if unknown:
        raise DualtwinError(f"thresholds given for unknown channels {unknown}; channels are {sorted(channels)}")
    out: dict[str, Threshold] = {}
    for name in channels:
        value: float | Threshold | None
        if name in overrides:
            value = overrides[name]
        else:
            value = DEFAULT_ANGLE_THRESHOLD_RAD if name.endswith("_angle_rad") else None
        if value is not None:
            out[name] = value if isinstance(value, Threshold) else Threshold(float(value))
    return out


def left_out(what: str, a: list[str], b: list[str], label_a: str, label_b: str) -> dict[str, str]:
    """Names only one side has, each with why it is left out of the comparison."""
    out = {name: f"only in A ({label_a}): B has no such {what}" for name in a if name not in b}
    out.update({name: f"only in B ({label_b}): A has no such {what}" for name in b if name not in a})
    return out


def shared_names(what: str, a: list[str], b: list[str], label_a: str, label_b: str) -> list[str]:
    """The names both sides have, in A's order.

    Raises:
        ValueError: One line naming both sides' names when nothing is shared.
    """
    shared = [name for name in a if name in b]
    if not shared:
        raise DualtwinError(f"runs are not comparable: no {what} in common: A ({label_a}) has {a}; "
                         f"B ({label_b}) has {b}")
    return shared


def _side_floor(members: list[dict[str, Series]], name: str, resolution: float,
                threshold: Threshold | None, dtw_window: int | None) -> ChannelFloor | None:
    series = [(m[name].t, m[name].y) for m in members if name in m]
    if len(series) < 2 or len(series) != len(members):
        return None
    try:
        return ensemble_floor(series, resolution=resolution, threshold=threshold, dtw_window=dtw_window)
    except ValueError:
        return None  # a member that blew up at once leaves nothing to measure a floor on


def _floors(a: Run, b: Run, scenario_id: str, channels: Mapping[str, ChannelDivergence],
            resolution: Mapping[str, float], thresholds: Mapping[str, Threshold],
            dtw_window: int | None) -> dict[str, FloorJudgement]:
    """Each compared channel judged against the floors of whichever sides are ensembles."""
    members_a, members_b = a.members(scenario_id), b.members(scenario_id)
    if not members_a and not members_b:
        return {}
    out: dict[str, FloorJudgement] = {}
    for name, ch in channels.items():
        fa = _side_floor(members_a, name, resolution[name], thresholds.get(name), dtw_window) if members_a else None
        fb = _side_floor(members_b, name, resolution[name], thresholds.get(name), dtw_window) if members_b else None
        if fa is not None or fb is not None:
            out[name] = judge_against_floor(ch, fa, fb)
    return out


def _check_tolerances(
    scenario_id: str,
    tolerances: Mapping[str, Mapping[str, float]],
    channels: Mapping[str, ChannelDivergence],
    channel_names: list[str],
) -> tuple[ToleranceViolation, ...]:
    violations: list[ToleranceViolation] = []
    for channel, limits in tolerances.items():
        if channel not in channel_names:
            raise DualtwinError(f"tolerances for scenario {scenario_id!r} name unknown channel {channel!r}")
        unknown = sorted(set(limits) - set(TOLERANCE_METRICS))
        if unknown:
            raise DualtwinError(
                f"tolerances for {scenario_id!r}/{channel!r} use unknown metrics {unknown}; "
                f"allowed: {list(TOLERANCE_METRICS)}"
            )
        ch = channels.get(channel)
        if ch is None:
            continue  # not comparable (unstable); the scenario status already says so
        for metric, limit in limits.items():
            value = getattr(ch, metric)
            if metric == "crossing_diff_s" and value is None:
                if (ch.crossing_a_s is None) != (ch.crossing_b_s is None):
                    violations.append(ToleranceViolation(channel, metric, None, float(limit)))
                continue
            if abs(float(value)) > float(limit):
                violations.append(ToleranceViolation(channel, metric, float(value), float(limit)))
    return tuple(violations)


def state_notes(a: Run, b: Run, shared_ids: Collection[str]) -> tuple[str, ...]:
    """The runs' notes on how their scenarios start (state carried over in a recording), naming the run: a
    difference they explain is not the physics' (friction, damping) to answer for."""
    return tuple(f"run {side} ({run.path.name}): {note}; an offset that follows from this start is not friction or damping"
                 for side, run in (("A", a), ("B", b)) for entry in run.scenarios
                 if entry.id in shared_ids for note in entry.state_notes)


def compare_runs(
    run_a: Path,
    run_b: Path,
    thresholds: Mapping[str, float | Threshold | None] | None = None,
    *,
    max_lag_s: float = DEFAULT_MAX_LAG_S,
    dtw_window: int | None = None,
    weights: ScoreWeights = DEFAULT_WEIGHTS,
    resolutions: Mapping[str, float] | None = None,
) -> RunComparison:
    """Compare two runs of the same suite, scenario by scenario and channel by channel.

    Scenarios are matched by id and channels by name. A scenario that is ``unstable`` in a twin may have
    a short log or none: its channels are compared over what overlaps, the rest is noted. When exactly
    one twin is unstable the scenario scores 1.0 (the maximum), since one twin blowing up is the largest
    divergence there is. Tolerances come from run A's manifest, completed by run B's.

    Args:
        run_a: Run directory of twin A (the reference).
        run_b: Run directory of twin B.
        thresholds: Crossing thresholds per channel, merged over the defaults (see `resolve_thresholds`).
        max_lag_s: Largest lag searched by the cross-correlation.
        dtw_window: Optional Sakoe-Chiba band half-width in samples.
        weights: Score weights.
        resolutions: Resolution per channel, over the manifests' (declared by the bindings) and the
            defaults by unit. A difference at or below it never ranks and is never called a sign inversion.

    When a run holds ensemble members (``suite run --ensemble``), each channel's divergence is also judged
    against the reproducibility floor (``floors``) and ranked against it (``significance``).

    Only the scenarios and channels both runs have are compared (a recording usually logs fewer channels
    than a twin, or covers fewer scenarios); what only one side has is listed in ``left_out`` with why.

    Raises:
        ValueError: If the robots or the units of a shared channel differ, if the runs share no scenario
            or no channel (the message lists each side's names), or a scenario that did not blow up lacks
            its logs.
    """
    a, b = load_run(Path(run_a)), load_run(Path(run_b))
    if a.robot != b.robot:
        raise DualtwinError(f"runs are not comparable: robots differ: A ({a.path}) is {a.robot!r}, "
                         f"B ({b.path}) is {b.robot!r}")
    if a.suite_name and b.suite_name and a.suite_name != b.suite_name:
        raise DualtwinError(f"runs are not comparable: suites differ: A ({a.path}) ran {a.suite_name!r}, "
                            f"B ({b.path}) ran {b.suite_name!r}")
    ids_a, ids_b = [s.id for s in a.scenarios], [s.id for s in b.scenarios]
    shared_ids = shared_names("scenario", ids_a, ids_b, str(a.path), str(b.path))
    channel_names = shared_names("channel", list(a.channels), list(b.channels), str(a.path), str(b.path))
    units_differ = sorted(
        f"{n}: {a.channels[n].unit!r} vs {b.channels[n].unit!r}"
        for n in channel_names
        if a.channels[n].unit != b.channels[n].unit
    )
    if units_differ:
        raise DualtwinError(f"runs are not comparable: channel units differ: {units_differ}")
    excluded = {"scenarios": left_out("scenario", ids_a, ids_b, str(a.path), str(b.path)),
                "channels": left_out("channel", list(a.channels), list(b.channels), str(a.path), str(b.path))}

    resolved = resolve_thresholds(channel_names, thresholds)
    unknown_res = sorted(set(resolutions or {}) - set(channel_names))
    if unknown_res:
        raise DualtwinError(f"resolutions given for channels not compared {unknown_res}; "
                            f"channels are {channel_names}")
    resolution = {n: float((resolutions or {}).get(n) or a.channels[n].resolution or b.channels[n].resolution
                           or default_resolution(a.channels[n].unit or b.channels[n].unit))
                  for n in channel_names}
    # Tolerances of a channel only one run logs have nothing to bound; a name neither run has stays an error.
    only_one_side = set(excluded["channels"])
    tolerances = {sid: {c: v for c, v in limits.items() if c not in only_one_side}
                  for sid, limits in {**b.tolerances, **a.tolerances}.items()}
    unknown_tol = sorted(set(tolerances) - set(ids_a) - set(ids_b))
    if unknown_tol:
        raise DualtwinError(f"tolerances name unknown scenarios {unknown_tol}")

    results: list[ScenarioComparison] = []
    for entry_a in (s for s in a.scenarios if s.id in shared_ids):
        entry_b = b.scenario(entry_a.id)
        series_a, series_b = a.series(entry_a.id), b.series(entry_a.id)
        for run, entry, series in ((a, entry_a, series_a), (b, entry_b, series_b)):
            missing = [c for c in channel_names if c not in series]
            if missing and entry.status != "unstable":
                raise DualtwinError(
                    f"{run.path}: scenario {entry.id!r} ({entry.status}) has no log data for channels {missing}"
                )
        channels: dict[str, ChannelDivergence] = {}
        skipped: list[str] = []
        for name in channel_names:
            sa, sb = series_a.get(name), series_b.get(name)
            if sa is None or sb is None:
                skipped.append(f"{name} (no log)")
                continue
            try:
                channels[name] = compare_channel(
                    sa.t,
                    sa.y,
                    sb.t,
                    sb.y,
                    channel=name,
                    threshold=resolved.get(name),
                    max_lag_s=max_lag_s,
                    dtw_window=dtw_window,
                    weights=weights,
                    resolution=resolution[name],
                )
            except ValueError as exc:
                # Only a scenario that ended early (an unstable twin, or a failure threshold crossed within the
                # first periods) may leave too little to compare; otherwise the data is broken.
                if not {entry_a.status, entry_b.status} & {"unstable", "failed"}:
                    raise DualtwinError(f"scenario {entry_a.id!r}, channel {name!r}: {exc}") from exc
                skipped.append(f"{name} ({exc})")

        notes: list[str] = []
        one_sided = (entry_a.status == "unstable") != (entry_b.status == "unstable")
        score: float | None = float(np.mean([c.score for c in channels.values()])) if channels else None
        if one_sided:
            side = "A" if entry_a.status == "unstable" else "B"
            notes.append(f"unstable in {side} only: scored 1.0")
            score = 1.0
        elif entry_a.status == "unstable":
            notes.append("unstable in both twins")
        if skipped:
            notes.append("not compared: " + ", ".join(skipped))
        notes.extend(f"{side}: {note}" for side, entry in (("A", entry_a), ("B", entry_b))
                     for note in entry.state_notes)

        floors = _floors(a, b, entry_a.id, channels, resolution, resolved, dtw_window)
        channels = {name: replace(ch, significance=significance(ch.rmse, resolution[name],
                                                                floors[name].floor_rmse_max if name in floors else None))
                    for name, ch in channels.items()}
        results.append(
            ScenarioComparison(
                id=entry_a.id,
                index=entry_a.index,
                name=entry_a.name,
                status_a=entry_a.status,
                status_b=entry_b.status,
                failure_a=entry_a.failure,
                failure_b=entry_b.failure,
                channels=channels,
                score=score,
                note="; ".join(notes) or None,
                tolerance_violations=_check_tolerances(
                    entry_a.id, tolerances.get(entry_a.id, {}), channels, channel_names
                ),
                floors=floors,
                series_a={k: Series(*finite_prefix(v.t, v.y)) for k, v in series_a.items()},
                series_b={k: Series(*finite_prefix(v.t, v.y)) for k, v in series_b.items()},
            )
        )

    scores = [s.score for s in results if s.score is not None]
    settings = {
        "thresholds": {k: v.to_dict() for k, v in resolved.items()},
        "weights": weights.to_dict(),
        "max_lag_s": max_lag_s,
        "dtw_window": dtw_window,
        "definitions": {
            "difference": "B - A",
            "dtw": "sqrt(sum of squared differences along the optimal warping path) (dtaidistance)",
            "dtw_rms": "dtw / sqrt(n), n = samples on the common grid",
            "lag_s": "positive: B lags A, y_b(t) ~ y_a(t - lag_s)",
            "crossing": "first time the threshold is reached, linearly interpolated",
            "score": "weighted mean of terms in [0, 1]; amplitude terms divided by the pooled range",
            "scenario_score": "mean channel score; 1.0 if exactly one twin is unstable",
            "summary_score": "mean scenario score over scenarios with a score",
            "resolution": "smallest meaningful difference per channel: the binding's, else 1 mm for m, 1 mrad "
                          "for rad (dualtwin.divergence.metrics.DEFAULT_RESOLUTION_BY_UNIT)",
            "floor": "a side's ensemble members against its unperturbed member 0, mean over members",
            "floor_ratio": "dtw between the sides / the larger dtw floor; near 1: as close as the physics allows",
            "horizon_s": "first time the members' spread exceeds the resolution: where prediction stops",
            "significance": "rmse / max(resolution, worst member rmse of either side); pairs rank by it, "
                            "<= 1 never ranks",
        },
        "resolutions": resolution,
    }
    return RunComparison(
        run_a=str(a.path),
        run_b=str(b.path),
        twin_a=a.twin,
        twin_b=b.twin,
        robot=a.robot,
        suite_name=a.suite_name,
        scenarios=tuple(results),
        units={name: a.channels[name].unit for name in channel_names},
        settings=settings,
        summary_score=float(np.mean(scores)) if scores else None,
        left_out={k: v for k, v in excluded.items() if v},
        data_notes=state_notes(a, b, shared_ids),
    )
