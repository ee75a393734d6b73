"""The alignment objective: pure functions from a reference and a candidate's traces to numbers.

Terms per training scenario and channel, each dimensionless so channels and scenarios add up:

* ``dtw``: DTW (dtaidistance, ``dtw / sqrt(n)``) on the common time grid, divided by the channel's scale;
* ``event``: difference of threshold-crossing times (the pole-fall event) divided by the scenario's
  duration; a series that never crosses counts as crossing at the end of its log;
* ``endpoint``: difference of the last common values divided by the channel's scale;
* ``rmse``: optional (weight 0 by default), like ``dtw`` without warping.

The channel's scale is the largest peak-to-peak range of the *reference* over the objective's scenarios.
It is fixed before fitting, so a candidate cannot shrink its error by growing its own range (the
divergence report's pooled scale would let it). Each term goes through a pseudo-Huber function
(quadratic near 0, linear beyond ``robust_delta``) so one structurally mismatched channel cannot dominate.
Per scenario, a difference in when the run ended (a failure threshold stopped one twin earlier) is
another event term. A candidate that blows up scores ``unstable_penalty × (1 + unfinished fraction)``,
larger than any finite mismatch and lower the later it blows up, so optimisers move toward stability.

`residuals` gives least squares a fixed-length vector instead: trajectory differences on the reference's
own time stamps (the candidate interpolated, held after its last sample), crossing-time differences, the
end-time difference and a stability residual per scenario.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dualtwin.align.simulate import ScenarioTrace
from dualtwin.align.weights import TERMS, ObjectiveWeights
from dualtwin.divergence.comparison import resolve_thresholds
from dualtwin.divergence.metrics import (
    FloatArray,
    Threshold,
    crossing_time,
    dtw_distance,
    finite_prefix,
    resample_common,
    time_stamps_problem,
)
from dualtwin.divergence.metrics import rmse as rmse_of
from dualtwin.divergence.runs import Series
from dualtwin.errors import DualtwinError

#: Objective value when the numbers themselves are not finite.
NONFINITE_VALUE = 1e3


@dataclass(frozen=True, eq=False)
class ObjectiveSpec:
    """Everything needed to score candidates against a reference (built once, before fitting)."""

    reference: Mapping[str, ScenarioTrace]
    scenarios: tuple[str, ...]
    channels: tuple[str, ...]
    scales: Mapping[str, float]
    thresholds: Mapping[str, Threshold]
    weights: ObjectiveWeights
    skipped: tuple[str, ...] = ()

    @functools.cached_property
    def prepared(self) -> dict[tuple[str, str], PreparedSeries]:
        """Each scenario's and channel's reference series, cut to its finite prefix once (a fit scores
        hundreds of candidates against the same reference)."""
        out: dict[tuple[str, str], PreparedSeries] = {}
        for sid in self.scenarios:
            for name in self.channels:
                series = self.reference[sid].series.get(name)
                if series is not None:
                    out[sid, name] = PreparedSeries.of(series)
        return out


@dataclass(frozen=True, eq=False)
class PreparedSeries:
    """A reference series' finite prefix, and whether its time stamps would pass `resample_common`'s checks."""

    t: FloatArray
    y: FloatArray
    valid_time: bool

    @classmethod
    def of(cls, series: Series) -> PreparedSeries:
        t, y = finite_prefix(series.t, series.y)
        return cls(t, y, time_stamps_problem(t) is None)


@dataclass(frozen=True)
class ObjectiveValue:
    """A candidate's objective: total, per scenario and per (weighted, robust) term."""

    total: float
    per_scenario: Mapping[str, float] = field(default_factory=dict)
    per_term: Mapping[str, float] = field(default_factory=dict)
    unstable: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {"total": self.total, "per_scenario": dict(self.per_scenario), "per_term": dict(self.per_term),
                "unstable": list(self.unstable)}


def mean_trace(members: Sequence[ScenarioTrace]) -> ScenarioTrace:
    """The ensemble mean of one scenario's members (member 0 first), on member 0's time stamps.

    At each time stamp the mean is over the members whose finite log reaches it, so a member that a failure
    threshold stopped early drops out rather than being extrapolated. The mean has member 0's status and
    duration: whether the unperturbed run failed or blew up is what the event and stability terms judge.
    A pole landing on a hard stop is chaotic (a 1 µrad change moves the bounces); the mean keeps what the
    members share and averages out what no engine can reproduce.
    """
    if not members:
        raise DualtwinError("an ensemble mean needs at least one member")
    first = members[0]
    if len(members) == 1 or first.status == "unstable":
        return first
    series: dict[str, Series] = {}
    for name, base in first.series.items():
        t, _ = finite_prefix(base.t, base.y)
        stack = np.full((len(members), t.size), np.nan)
        for i, member in enumerate(members):
            s = member.series.get(name)
            if s is None:
                continue
            tm, ym = finite_prefix(s.t, s.y)
            if tm.size:
                inside = (t >= tm[0] - 1e-9) & (t <= tm[-1] + 1e-9)
                stack[i, inside] = np.interp(t[inside], tm, ym)
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(stack, axis=0) if t.size else np.zeros(0)
        series[name] = Series(t.copy(), mean)
    return ScenarioTrace(first.id, first.status, first.duration_s, series)


def pseudo_huber(x: float, delta: float) -> float:
    """``δ(√(1 + (x/δ)²) - 1)``: ``x²/2δ`` near 0, ``|x| - δ`` for large ``|x|``."""
    return delta * (math.sqrt(1.0 + (x / delta) ** 2) - 1.0)


def channel_scales(reference: Mapping[str, ScenarioTrace], scenarios: Sequence[str],
                   channels: Sequence[str]) -> dict[str, float]:
    """Largest reference peak-to-peak range per channel over ``scenarios`` (1.0 for a flat channel)."""
    out: dict[str, float] = {}
    for name in channels:
        ranges = []
        for sid in scenarios:
            series = reference[sid].series.get(name)
            if series is not None:
                _, y = finite_prefix(series.t, series.y)
                if y.size:
                    ranges.append(float(np.ptp(y)))
        scale = max(ranges, default=0.0)
        out[name] = scale if scale > 1e-12 else 1.0
    return out


def build_spec(
    reference: Mapping[str, ScenarioTrace],
    scenarios: Sequence[str],
    channels: Sequence[str] | None = None,
    *,
    thresholds: Mapping[str, float | Threshold | None] | None = None,
    weights: ObjectiveWeights | None = None,
) -> ObjectiveSpec:
    """Fix the scenarios, channels, scales and thresholds of an objective.

    Scenarios where the reference itself blew up are skipped (listed in ``skipped``): there is nothing
    trustworthy to match.

    Raises:
        DualtwinError: Unknown scenarios or channels, or nothing left to fit.
    """
    missing = [s for s in scenarios if s not in reference]
    if missing:
        raise DualtwinError(f"the reference has no scenarios {missing} (it has {sorted(reference)})")
    usable = [s for s in scenarios if reference[s].status != "unstable"]
    skipped = tuple(s for s in scenarios if s not in usable)
    if not usable:
        raise DualtwinError(f"no scenario to fit: the reference is unstable in all of {list(scenarios)}")
    common = [c for c in reference[usable[0]].series if all(c in reference[s].series for s in usable)]
    if channels is None:
        chosen = common
    else:
        unknown = [c for c in channels if c not in common]
        if unknown:
            raise DualtwinError(f"channels {unknown} are not logged in every scenario; available: {common}")
        chosen = list(channels)
    if not chosen:
        raise DualtwinError("no channel is logged in every scenario of the reference")
    try:
        resolved = resolve_thresholds(chosen, thresholds)
    except ValueError as exc:
        raise DualtwinError(str(exc)) from None
    return ObjectiveSpec(
        reference=reference,
        scenarios=tuple(usable),
        channels=tuple(chosen),
        scales=channel_scales(reference, usable, chosen),
        thresholds=resolved,
        weights=weights or ObjectiveWeights(),
        skipped=skipped,
    )


def _crossing_or_end(t: FloatArray, y: FloatArray, threshold: Threshold) -> tuple[float | None, float]:
    crossing = crossing_time(t, y, threshold) if t.size else None
    end = float(t[-1]) if t.size else 0.0
    return crossing, crossing if crossing is not None else end


def event_difference(ref: Series, cand: Series, threshold: Threshold) -> float:
    """Signed crossing-time difference (candidate - reference) in seconds; a missing crossing counts at the log end.

    Crossings are looked for from the later of the two first samples on: a candidate shifted onto the
    reference's clock (a nuisance time offset) starts earlier, and a series that starts beyond the threshold
    (a pole resting on its stop) would otherwise "cross" at its own first sample. A reference already past the
    threshold there has no crossing to time (0): a candidate shifted by a fraction of a period would otherwise
    "cross" wherever its first kept sample falls inside a bounce, a jump in the criterion at every period.
    """
    ta, ya = finite_prefix(ref.t, ref.y)
    tb, yb = finite_prefix(cand.t, cand.y)
    if ta.size and tb.size:
        start = max(float(ta[0]), float(tb[0])) - 1e-9
        keep_a, keep_b = ta >= start, tb >= start
        ta, ya, tb, yb = ta[keep_a], ya[keep_a], tb[keep_b], yb[keep_b]
        if ta.size and crossing_time(ta[:1], ya[:1], threshold) is not None:
            return 0.0
    ca, ca_eff = _crossing_or_end(ta, ya, threshold)
    cb, cb_eff = _crossing_or_end(tb, yb, threshold)
    if ca is None and cb is None:
        return 0.0
    return cb_eff - ca_eff


def channel_terms(ref: Series, cand: Series, scale: float, threshold: Threshold | None,
                  duration_s: float, wanted: Collection[str] = TERMS,
                  prepared: PreparedSeries | None = None) -> dict[str, float]:
    """Raw (unweighted) terms of one channel, those named in ``wanted`` (a term of weight 0 costs nothing:
    DTW was most of a score's time); 1.0 each when fewer than 2 candidate samples overlap. ``prepared``:
    ``ref`` already cut (:attr:`ObjectiveSpec.prepared`)."""
    if prepared is None:
        prepared = PreparedSeries.of(ref)
    ta, ya = prepared.t, prepared.y
    tb, yb = finite_prefix(cand.t, cand.y)
    event = (abs(event_difference(ref, cand, threshold)) / duration_s
             if threshold is not None and "event" in wanted else 0.0)
    if prepared.valid_time and tb.shape == ta.shape and np.array_equal(ta, tb):
        # the candidate logged on the reference's own time stamps (a twin run of the same suite): the common
        # grid is that grid, as resample_common would find, without its checks and copies
        a, b = ya, yb
    else:
        try:
            common = resample_common(ta, ya, tb, yb)
        except ValueError:
            failed = {"dtw": 1.0, "event": event if threshold is not None else 1.0, "endpoint": 1.0, "rmse": 1.0}
            return {k: v for k, v in failed.items() if k in wanted}
        a, b = common.a, common.b
    terms = {"event": event} if "event" in wanted else {}
    if "dtw" in wanted:
        terms["dtw"] = dtw_distance(a, b).rms / scale
    if "endpoint" in wanted:
        terms["endpoint"] = abs(float(b[-1] - a[-1])) / scale
    if "rmse" in wanted:
        terms["rmse"] = rmse_of(a, b) / scale
    return terms


def _duration(trace: ScenarioTrace) -> float:
    return trace.duration_s if trace.duration_s > 0 else max(trace.end_time_s, 1e-9)


def scenario_value(spec: ObjectiveSpec, sid: str, cand: ScenarioTrace) -> tuple[float, dict[str, float]]:
    """One scenario's score and its weighted robust terms (averaged over channels)."""
    w = spec.weights
    ref = spec.reference[sid]
    duration = _duration(ref)
    if cand.status == "unstable":
        unfinished = max(0.0, duration - cand.end_time_s) / duration
        return w.unstable_penalty * (1.0 + unfinished), {}
    weights = w.term_weights()
    wanted = {key for key, weight in weights.items() if weight}
    sums = dict.fromkeys(TERMS, 0.0)
    for name in spec.channels:
        ref_series = ref.series[name]
        cand_series = cand.series.get(name)
        if cand_series is None:
            raise DualtwinError(f"scenario {sid!r}: the candidate did not log channel {name!r}")
        terms = channel_terms(ref_series, cand_series, spec.scales[name], spec.thresholds.get(name), duration,
                              wanted, spec.prepared[sid, name])
        for key, value in terms.items():
            sums[key] += weights[key] * pseudo_huber(value, w.robust_delta)
    per_term = {k: v / len(spec.channels) for k, v in sums.items()}
    if "failed" in (ref.status, cand.status):
        # When a failure threshold stopped a twin, when it stopped is an event too.
        end_term = abs(cand.end_time_s - ref.end_time_s) / duration
        per_term["event"] += w.event * pseudo_huber(end_term, w.robust_delta)
    total = float(sum(per_term.values()))
    if not math.isfinite(total):
        return NONFINITE_VALUE, per_term
    return total, per_term


def evaluate(spec: ObjectiveSpec, candidate: Mapping[str, ScenarioTrace]) -> ObjectiveValue:
    """Mean scenario score of a candidate over the spec's scenarios."""
    per_scenario: dict[str, float] = {}
    per_term = dict.fromkeys(TERMS, 0.0)
    unstable: list[str] = []
    for sid in spec.scenarios:
        if sid not in candidate:
            raise DualtwinError(f"the candidate has no scenario {sid!r}")
        value, terms = scenario_value(spec, sid, candidate[sid])
        per_scenario[sid] = value
        if candidate[sid].status == "unstable":
            unstable.append(sid)
        for key, v in terms.items():
            per_term[key] += v / len(spec.scenarios)
    total = float(np.mean(list(per_scenario.values())))
    if not math.isfinite(total):
        total = NONFINITE_VALUE
    return ObjectiveValue(total, per_scenario, per_term, tuple(unstable))


def residual_size(spec: ObjectiveSpec) -> int:
    """Length of `residuals` for this spec."""
    n = 0
    for sid in spec.scenarios:
        ref = spec.reference[sid]
        for name in spec.channels:
            n += finite_prefix(ref.series[name].t, ref.series[name].y)[0].size
            n += 1 if name in spec.thresholds else 0
        n += 2  # end time, stability
    return n


@dataclass(frozen=True)
class ResidualBlock:
    """A stretch ``[start, stop)`` of the residual vector: one channel's samples in one scenario (``series``),
    or that scenario's scalar event, end-time and stability terms (``scalar``)."""

    scenario: str
    channel: str | None
    start: int
    stop: int
    kind: str


def residual_layout(spec: ObjectiveSpec) -> list[ResidualBlock]:
    """Where each scenario's and channel's residuals lie in `residuals` (same order), so interval estimates can
    treat a time series as one autocorrelated block and the identifiability check can look per scenario."""
    out: list[ResidualBlock] = []
    n = 0
    for sid in spec.scenarios:
        ref = spec.reference[sid]
        for name in spec.channels:
            size = finite_prefix(ref.series[name].t, ref.series[name].y)[0].size
            out.append(ResidualBlock(sid, name, n, n + size, "series"))
            n += size
            if name in spec.thresholds:
                out.append(ResidualBlock(sid, name, n, n + 1, "scalar"))
                n += 1
        out.append(ResidualBlock(sid, None, n, n + 2, "scalar"))
        n += 2
    return out


def residuals(spec: ObjectiveSpec, candidate: Mapping[str, ScenarioTrace]) -> FloatArray:
    """Fixed-length residual vector for least squares; its squared norm is comparable to a mean squared error."""
    w = spec.weights
    parts: list[FloatArray] = []
    per_scenario = 1.0 / math.sqrt(len(spec.scenarios))
    per_channel = 1.0 / math.sqrt(len(spec.channels))
    for sid in spec.scenarios:
        ref = spec.reference[sid]
        cand = candidate[sid]
        duration = _duration(ref)
        for name in spec.channels:
            reference = spec.prepared[sid, name]
            ta, ya = reference.t, reference.y
            cand_series = cand.series.get(name)
            if cand_series is None:
                raise DualtwinError(f"scenario {sid!r}: the candidate did not log channel {name!r}")
            tb, yb = finite_prefix(cand_series.t, cand_series.y)
            on_grid = np.interp(ta, tb, yb) if tb.size else np.full_like(ya, ya[0] if ya.size else 0.0)
            factor = math.sqrt(w.trajectory / max(ya.size, 1)) * per_channel * per_scenario
            parts.append((on_grid - ya) / spec.scales[name] * factor)
            threshold = spec.thresholds.get(name)
            if threshold is not None:
                diff = event_difference(ref.series[name], cand_series, threshold) / duration
                parts.append(np.array([diff * math.sqrt(w.event) * per_channel * per_scenario]))
        end_diff = (cand.end_time_s - ref.end_time_s) / duration if "failed" in (ref.status, cand.status) else 0.0
        unstable = 0.0
        if cand.status == "unstable":
            unstable = math.sqrt(w.unstable_penalty * (1.0 + max(0.0, duration - cand.end_time_s) / duration))
        parts.append(np.array([end_diff * math.sqrt(w.event) * per_scenario, unstable * per_scenario]))
    out = np.concatenate(parts) if parts else np.zeros(0)
    return np.where(np.isfinite(out), out, math.sqrt(NONFINITE_VALUE))
