"""Why two runs diverge: ranked findings in plain words, each with its evidence, and knob sensitivities.

`analyze_runs` compares two recorded runs of one suite (A is the reference) with
`dualtwin.divergence.compare_runs` and looks for the usual causes:

=========================  ==========================================================================  =====
finding                    detected when (per channel, over scenarios)                                 tier
=========================  ==========================================================================  =====
``one_sided_instability``  exactly one twin blew up in a scenario                                      0
``sign_inversion``         correlation <= -0.8 and regression slope <= -0.1 (B is a negated A)        0
``lag``                    shifting B by one consistent lag (>= 1 sample) halves the RMSE              1
``scale_mismatch``         B ~ s·A + c with one consistent s outside [1/1.15, 1.15] halves the RMSE   1
``input_growth``           scenario scores rise with a scenario input's magnitude (Spearman >= 0.8)    1
``event_time``             threshold crossings (the pole fall) differ by >= 1.5 samples, or one only   2
``endpoint``               the final values differ by >= 10 % of the channel's range                   2
=========================  ==========================================================================  =====

Every test looks only at scenarios in which the channel moves: its range there must be at least 5 % of
its largest range over the suite, and above the channel's resolution. A pole resting on its stop (1.0 rad
in one twin, 1.0013 rad in the other) carries no sign, lag or gain, only noise. Endpoint differences are
likewise measured against the channel's largest range, as the alignment objective does.

Physical significance gates every finding (issue 15.5): a difference at or below the channel's
resolution (declared by the binding, else 1 mm for m, 1 mrad for rad) or within the reproducibility
floor (when either run is an ensemble) raises no sign, lag, scale or endpoint finding, and an event-time
difference within the members' own spread of crossing times raises none either. A 13 µm cart wobble has
no direction worth reporting, and a chaotic bounce that each twin cannot reproduce itself is no defect.

A lag or a gain must be consistent to count: the same value (within 1.5 samples or 15 %) must explain at
least half of the scenarios in which the channel diverges. A real control delay or command gain acts
alike in every driven scenario. A dynamics difference (a more damped pole falls later) only looks like a
shift or a gain here and there, and is left to the event-time and endpoint findings.

Findings are ranked by tier, then by the share of the divergence in the scenario × channel pairs they
cover, where pairs weigh by their significance (RMSE ÷ the larger of resolution and floor, see
`dualtwin.divergence.RunComparison.contributions`), not by a score divided by the channel's own range.
Structural mismatches come first because no parameter fit can repair them. Symptoms
come last: a late pole fall has many possible causes.

With a robot and a twin for B, each knob is also perturbed from nominal in both directions (``step`` of
its range, in parallel) and the suite is re-simulated. The change in the alignment objective
(`dualtwin.align.objective`, A as the reference) is the knob's sensitivity. Findings then name the most
sensitive knob for their term and say which way to move it.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import ConfigDict, Field

from dualtwin.align.knobs import KnobSpec, select_knobs
from dualtwin.align.objective import ObjectiveValue, build_spec, evaluate
from dualtwin.align.propose import ProposalOutcome, try_proposals
from dualtwin.align.simulate import Evaluator, ExecutorKind, SimJob, check_executor, load_traces
from dualtwin.divergence.comparison import Contribution, RunComparison, ScenarioComparison, compare_runs
from dualtwin.divergence.metrics import ChannelDivergence, median
from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel, StrictModel
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.loader import load_suite
from dualtwin.suite.schema import Suite
from dualtwin.suite.signals import Constant, Impulse, Ramp, Sine, Step, Table
from dualtwin.twins import make_twin

FindingKind = Literal["one_sided_instability", "sign_inversion", "lag", "scale_mismatch", "input_growth",
                      "event_time", "endpoint"]
ANALYSIS_SCHEMA = "dualtwin.analysis/1"
TIERS: dict[str, int] = {"one_sided_instability": 0, "sign_inversion": 0, "lag": 1, "scale_mismatch": 1,
                         "input_growth": 1, "event_time": 2, "endpoint": 2}
#: A lag or gain explains a channel when correcting for it cuts the RMSE by this factor.
EXPLAINS_FACTOR = 0.5
#: A channel diverges in a scenario when its RMSE is at least this fraction of its largest range.
DIVERGING_MIN = 0.01
#: A channel moves in a scenario when its range there is at least this fraction of its largest range.
MOVING_MIN = 0.05
LAG_AGREE_SAMPLES = 1.5
SCALE_MIN_RATIO = 1.15
ENDPOINT_MIN_FRACTION = 0.1
EVENT_MIN_SAMPLES = 1.5
GROWTH_MIN_SPEARMAN = 0.8
GROWTH_MIN_SCORE_RISE = 0.02
# Knobs worth trying first for each finding, before any sensitivity is known.
SUGGESTED: dict[str, tuple[str, ...]] = {
    "one_sided_instability": ("geom.*.solref_timeconst", "body.*.mass", "body.*.inertia_scale"),
    "sign_inversion": ("motor.*.gain",),
    "lag": ("control.delay_periods", "sensor.*.delay"),
    "scale_mismatch": ("motor.*.gain", "motor.*.max_velocity", "motor.*.max_torque"),
    "input_growth": ("geom.*.friction", "motor.*.max_torque", "motor.*.max_velocity"),
    "event_time": ("joint.*.damping", "joint.*.friction", "body.*.mass"),
    "endpoint": ("geom.*.friction", "joint.*.friction", "joint.*.damping"),
}
# Structural findings get no sensitivity-based suggestion: no amount of damping fixes a flipped sign.
_STRUCTURAL = frozenset({"one_sided_instability", "sign_inversion"})
# The objective term whose sensitivity matters for each finding (None: the total).
_TERM_FOR: dict[str, str | None] = {"event_time": "event", "endpoint": "endpoint", "lag": "dtw",
                                    "scale_mismatch": "dtw"}


class AnalysisConfig(FrozenModel):
    """Inputs and settings of one analysis (saved in ``analysis.json``)."""

    run_a: str
    run_b: str
    robot: str | None = None
    twin_b: str | None = None
    knobs: list[str] = Field(default_factory=list)
    step: float = Field(default=0.05, gt=0, le=0.5, description="perturbation, as a fraction of each knob's range")
    executor: ExecutorKind = "process"
    workers: int = Field(default=2, ge=1)
    thresholds: dict[str, float] | None = None


class Finding(StrictModel):
    """One explanation of the divergence, in plain words, with its evidence."""

    # Measured, not configured: a share can be non-finite when a run is unstable.
    model_config = ConfigDict(allow_inf_nan=True)
    kind: FindingKind
    message: str
    channel: str | None = None
    scenarios: list[str] = Field(default_factory=list)
    share: float = Field(description="share of the summary divergence score in the pairs this finding covers")
    tier: int
    knobs: list[str] = Field(default_factory=list, description="knobs to try, most promising first")
    evidence: dict[str, Any] = Field(default_factory=dict)


class KnobSensitivity(StrictModel):
    """How the divergence objective changes when one knob moves away from nominal."""

    # Measured, not configured: a perturbed run that goes unstable gives a non-finite change.
    model_config = ConfigDict(allow_inf_nan=True)
    knob: str
    unit: str = ""
    nominal: float
    tried: dict[str, float] = Field(description="direction ('up'/'down') -> knob value simulated")
    change: dict[str, float] = Field(description="direction -> objective change (negative: closer to A)")
    sensitivity: float = Field(description="largest |objective change| per unit of the knob's normalised range")
    per_term: dict[str, float] = Field(default_factory=dict, description="term -> change in the better direction")
    per_scenario: dict[str, float] = Field(default_factory=dict)
    best_direction: Literal["increase", "decrease", "none"] = "none"
    unstable: list[str] = Field(default_factory=list)


@dataclass
class Analysis:
    """The result of `analyze_runs`."""

    config: AnalysisConfig
    comparison: RunComparison
    findings: list[Finding]
    sensitivity: list[KnobSensitivity] = field(default_factory=list)
    objective: ObjectiveValue | None = None
    notes: list[str] = field(default_factory=list)
    #: Outcomes of proposals (e.g. an LLM's), each re-simulated; empty unless a proposer was given.
    proposals: list[ProposalOutcome] = field(default_factory=list)
    #: The LLM narrative (`dualtwin.align.narrate.Narrative.to_dict`), labelled as LLM output; None without --llm.
    narrative: dict[str, Any] | None = None

    @property
    def dominant(self) -> list[Contribution]:
        """Scenario × channel pairs that dominate the summary score, largest first."""
        return self.comparison.contributions()

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": ANALYSIS_SCHEMA,
            "config": self.config.model_dump(mode="json"),
            "summary_score": self.comparison.summary_score,
            "dominant": [{"scenario": c.scenario_id, "channel": c.channel, "contribution": c.contribution,
                          "share": c.share} for c in self.dominant[:10]],
            "findings": [f.model_dump(mode="json") for f in self.findings],
            "sensitivity": [s.model_dump(mode="json") for s in self.sensitivity],
            "objective": None if self.objective is None else self.objective.to_dict(),
            "notes": list(self.notes),
            "left_out": {k: dict(v) for k, v in self.comparison.left_out.items()},
            "floors": floor_table(self.comparison),
            "proposals": [p.to_dict() for p in self.proposals],
            **({"llm_narrative": self.narrative} if self.narrative is not None else {}),
            "comparison": self.comparison.to_dict(),
        }


#: A proposer: reads the analysis, suggests knob settings (see `dualtwin.align.propose`).
ProposeFn = Callable[[Analysis], Sequence[Mapping[str, float]]]


def floor_table(comparison: RunComparison) -> list[dict[str, Any]]:
    """Every scenario × channel judged against a reproducibility floor, most significant first.

    Significance (not the floor ratio) orders them: in a predictable scenario the members agree to within
    numerical noise, so any ratio there is huge and says nothing; the verdict reads it against the resolution.
    """
    rows = [{"scenario": sc.id, "channel": name, "ratio": f.ratio, "floor_dtw": f.floor_dtw,
             "dtw": sc.channels[name].dtw, "significance": sc.channels[name].significance,
             "horizon_s": f.horizon_s, "verdict": f.verdict}
            for sc in comparison.scenarios for name, f in sc.floors.items() if name in sc.channels]
    return sorted(rows, key=lambda r: (-(r["significance"] or 0.0), r["scenario"], r["channel"]))


def left_out_notes(comparison: RunComparison) -> list[str]:
    """One note per scenario or channel that only one run has (a recording logs fewer channels)."""
    return [f"left out {what[:-1]} {name}: {why}" for what, names in comparison.left_out.items()
            for name, why in names.items()]


# ------------------------------------------------------------------ pure detectors
def _pairs(comparison: RunComparison) -> list[tuple[ScenarioComparison, str, ChannelDivergence]]:
    return [(sc, name, ch) for sc in comparison.scenarios for name, ch in sc.channels.items()]


def channel_ranges(comparison: RunComparison) -> dict[str, float]:
    """Largest pooled range of each channel over the compared scenarios."""
    out: dict[str, float] = {}
    for _, name, ch in _pairs(comparison):
        out[name] = max(out.get(name, 0.0), ch.scale)
    return out


def _moving(comparison: RunComparison, name: str) -> list[tuple[ScenarioComparison, ChannelDivergence]]:
    """Pairs of ``name`` in scenarios where the channel moves (see the module docstring)."""
    full = channel_ranges(comparison).get(name, 0.0)
    return [(sc, ch) for sc, n, ch in _pairs(comparison)
            if n == name and ch.scale >= MOVING_MIN * full and ch.scale > (ch.resolution or 0.0)]


def significant(ch: ChannelDivergence) -> bool:
    """The pair's difference exceeds its resolution and floor (always true without a resolution)."""
    return ch.significance is None or ch.significance > 1.0


def _share_of(comparison: RunComparison, pairs: Sequence[tuple[str, str | None]]) -> float:
    wanted = set(pairs)
    scenario_level = {sid for sid, ch in pairs if ch is None}
    total = sum(c.share for c in comparison.contributions()
                if (c.scenario_id, c.channel) in wanted or c.scenario_id in scenario_level)
    return float(min(1.0, total))


def _aligned(sc: ScenarioComparison, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Both series of a pair on A's samples over the overlap (None if not comparable)."""
    sa, sb = sc.series_a.get(name), sc.series_b.get(name)
    if sa is None or sb is None or sa.t.size < 4 or sb.t.size < 4:
        return None
    end = min(sa.t[-1], sb.t[-1])
    keep = sa.t <= end + 1e-9
    if keep.sum() < 4:
        return None
    return sa.y[keep], np.interp(sa.t[keep], sb.t, sb.y)


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2))) if a.size else 0.0


def lag_explains(a: np.ndarray, b: np.ndarray, lag_samples: int) -> tuple[float, float]:
    """RMSE of B against A before and after undoing ``lag_samples`` (B lags A when positive)."""
    before = _rmse(a, b)
    k = int(lag_samples)
    if k == 0 or abs(k) >= a.size - 2:
        return before, before
    after = _rmse(a[:-k], b[k:]) if k > 0 else _rmse(a[-k:], b[:k])
    return before, after


_UNIT_SUFFIXES = ("_rad_s", "_m_s", "_rad", "_deg", "_m", "_s", "_n", "_nm")


def _label(channel: str) -> str:
    """``onboard/pole_angle_rad`` -> ``on-board pole angle``."""
    name = channel.removeprefix("onboard/")
    for suffix in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            name = name[: -len(suffix)]
            break
    return ("on-board " if channel.startswith("onboard/") else "") + name.replace("_", " ")


def _diverging(comparison: RunComparison, name: str) -> list[tuple[ScenarioComparison, ChannelDivergence]]:
    full = channel_ranges(comparison).get(name, 0.0)
    return [(sc, ch) for sc, ch in _moving(comparison, name)
            if ch.rmse >= DIVERGING_MIN * full and significant(ch)]


def _consistent(hits: list[Any], value: Callable[[Any], float], tolerance: float,
                diverging: int) -> list[Any]:
    """Hits whose value lies within ``tolerance`` of their median, if they cover half the diverging scenarios."""
    if not hits:
        return []
    center = median([value(h) for h in hits])
    agree = [h for h in hits if abs(value(h) - center) <= tolerance]
    return agree if len(agree) >= max(1, math.ceil(0.5 * diverging)) else []


def _count(n: int, total: int) -> str:
    return f"{n} of {total} scenario{'s' if total != 1 else ''}"


def detect_instability(comparison: RunComparison) -> list[Finding]:
    found = [sc for sc in comparison.scenarios if sc.unstable_one_sided]
    if not found:
        return []
    sides = {sc.id: ("A" if sc.status_a == "unstable" else "B") for sc in found}
    times = {sc.id: (sc.failure_a if sides[sc.id] == "A" else sc.failure_b or {}) for sc in found}
    blown = sorted(set(sides.values()))
    when = ", ".join(f"{sid} at t = {(times[sid] or {}).get('time_s', float('nan')):.3g} s" for sid in sides)
    message = (f"twin {'/'.join(blown)} is numerically unstable in {_count(len(found), len(comparison.scenarios))} "
               f"({when}) while the other twin is not: check contact softness, masses and the time step")
    return [Finding(kind="one_sided_instability", message=message, scenarios=list(sides),
                    share=_share_of(comparison, [(sid, None) for sid in sides]), tier=TIERS["one_sided_instability"],
                    evidence={"unstable_side": sides, "failure": {k: dict(v or {}) for k, v in times.items()}})]


def detect_sign_inversion(comparison: RunComparison) -> list[Finding]:
    out: list[Finding] = []
    total = len(comparison.scenarios)
    for name in comparison.channel_names:
        hits = [(sc, ch) for sc, ch in _moving(comparison, name) if ch.sign_inverted and significant(ch)]
        if not hits:
            continue
        message = (f"{_label(name)} has the opposite sign in {_count(len(hits), total)} "
                   f"({', '.join(sc.id for sc, _ in hits)}): actuator axis or sign mismatch "
                   "(a motor's direction, a joint axis or a sensor's sign)")
        out.append(Finding(kind="sign_inversion", message=message, channel=name, scenarios=[sc.id for sc, _ in hits],
                           share=_share_of(comparison, [(sc.id, name) for sc, _ in hits]),
                           tier=TIERS["sign_inversion"],
                           evidence={sc.id: {"correlation": ch.correlation, "slope": ch.slope} for sc, ch in hits}))
    return out


def detect_lag(comparison: RunComparison) -> list[Finding]:
    out: list[Finding] = []
    total = len(comparison.scenarios)
    for name in comparison.channel_names:
        hits: list[tuple[ScenarioComparison, ChannelDivergence, float, float]] = []
        diverging = _diverging(comparison, name)
        for sc, ch in diverging:
            if ch.sign_inverted or ch.dt_s <= 0:
                continue
            samples = int(round(ch.lag_s / ch.dt_s))
            pair = _aligned(sc, name)
            if samples == 0 or pair is None:
                continue
            before, after = lag_explains(pair[0], pair[1], samples)
            if before > 0 and after <= EXPLAINS_FACTOR * before:
                hits.append((sc, ch, before, after))
        dt0 = median([ch.dt_s for _, ch in diverging]) if diverging else 0.0
        hits = _consistent(hits, lambda h: h[1].lag_s, LAG_AGREE_SAMPLES * dt0, len(diverging))
        if not hits:
            continue
        lags = [ch.lag_s for _, ch, _, _ in hits]
        lag = median(lags)
        dt = median([ch.dt_s for _, ch, _, _ in hits])
        who, other = ("B", "A") if lag > 0 else ("A", "B")
        message = (f"{_label(name)} in {who} lags {other} by {abs(lag):.3g} s (≈{abs(lag) / dt:.1f} control periods) "
                   f"in {_count(len(hits), total)}; undoing the lag cuts the error by "
                   f"{100 * (1 - np.mean([a / b for _, _, b, a in hits])):.0f} %: control or sensor delay")
        out.append(Finding(kind="lag", message=message, channel=name, scenarios=[sc.id for sc, *_ in hits],
                           share=_share_of(comparison, [(sc.id, name) for sc, *_ in hits]), tier=TIERS["lag"],
                           evidence={"lag_s": lag, "lag_periods": lag / dt, "lagging": who,
                                     "per_scenario": {sc.id: {"lag_s": ch.lag_s, "rmse": b, "rmse_lag_removed": a}
                                                      for sc, ch, b, a in hits}}))
    return out


def detect_scale_mismatch(comparison: RunComparison) -> list[Finding]:
    out: list[Finding] = []
    total = len(comparison.scenarios)
    for name in comparison.channel_names:
        hits: list[tuple[ScenarioComparison, ChannelDivergence, float, float]] = []
        diverging = _diverging(comparison, name)
        for sc, ch in diverging:
            if ch.slope is None or ch.intercept is None or ch.slope <= 0:
                continue
            if max(ch.slope, 1 / ch.slope) < SCALE_MIN_RATIO:
                continue
            pair = _aligned(sc, name)
            if pair is None:
                continue
            a, b = pair
            before = _rmse(a, b)
            after = _rmse(ch.slope * a + ch.intercept, b)
            if before > 0 and after <= EXPLAINS_FACTOR * before:
                hits.append((sc, ch, before, after))
        hits = _consistent(hits, lambda h: math.log(h[1].slope or 1.0), math.log(SCALE_MIN_RATIO), len(diverging))
        if not hits:
            continue
        slope = median([ch.slope or 1.0 for _, ch, _, _ in hits])
        message = (f"{_label(name)} in B is {slope:.3g}× A's in {_count(len(hits), total)}: command gain or "
                   "scale mismatch (motor gain, velocity or torque limit, wheel radius)")
        out.append(Finding(kind="scale_mismatch", message=message, channel=name, scenarios=[sc.id for sc, *_ in hits],
                           share=_share_of(comparison, [(sc.id, name) for sc, *_ in hits]),
                           tier=TIERS["scale_mismatch"],
                           evidence={"slope": slope, "per_scenario": {sc.id: {"slope": ch.slope, "rmse": b,
                                                                              "rmse_after_gain": a}
                                                                      for sc, ch, b, a in hits}}))
    return out


def detect_event_time(comparison: RunComparison) -> list[Finding]:
    out: list[Finding] = []
    total = len(comparison.scenarios)
    for name in comparison.channel_names:
        timed: list[tuple[ScenarioComparison, ChannelDivergence]] = []
        one_sided: list[tuple[ScenarioComparison, ChannelDivergence]] = []
        for sc, n, ch in _pairs(comparison):
            if n != name or ch.threshold is None:
                continue
            if (ch.crossing_a_s is None) != (ch.crossing_b_s is None):
                one_sided.append((sc, ch))
            elif (ch.crossing_diff_s is not None and abs(ch.crossing_diff_s) >= EVENT_MIN_SAMPLES * ch.dt_s
                  and abs(ch.crossing_diff_s) > crossing_floor_s(sc, name)):
                timed.append((sc, ch))
        if not timed and not one_sided:
            continue
        parts = []
        if timed:
            diffs = [ch.crossing_diff_s or 0.0 for _, ch in timed]
            mean = float(np.mean(diffs))
            level = timed[0][1].threshold.value if timed[0][1].threshold else math.nan
            parts.append(f"crosses {level:g} {comparison.units.get(name, '')} ".replace("  ", " ") +
                         f"{abs(mean):.3g} s {'later' if mean > 0 else 'earlier'} in B on average in "
                         f"{_count(len(timed), total)}")
        if one_sided:
            parts.append(f"crosses in only one twin in {_count(len(one_sided), total)} "
                         f"({', '.join(sc.id for sc, _ in one_sided)})")
        hits = timed + one_sided
        evidence = {sc.id: {"crossing_a_s": ch.crossing_a_s, "crossing_b_s": ch.crossing_b_s,
                            "crossing_diff_s": ch.crossing_diff_s} for sc, ch in hits}
        out.append(Finding(kind="event_time", message=f"{_label(name)} " + "; ".join(parts), channel=name,
                           scenarios=[sc.id for sc, _ in hits],
                           share=_share_of(comparison, [(sc.id, name) for sc, _ in hits]), tier=TIERS["event_time"],
                           evidence=evidence))
    return out


def crossing_floor_s(sc: ScenarioComparison, name: str) -> float:
    """The larger spread of crossing times among either side's ensemble members (0 without an ensemble)."""
    judged = sc.floors.get(name)
    if judged is None:
        return 0.0
    spreads = [f.crossing_spread_s for f in (judged.floor_a, judged.floor_b)
               if f is not None and f.crossing_spread_s is not None]
    return max(spreads, default=0.0)


def detect_endpoint(comparison: RunComparison, units: Mapping[str, str] | None = None) -> list[Finding]:
    out: list[Finding] = []
    total = len(comparison.scenarios)
    units = units or comparison.units
    ranges = channel_ranges(comparison)
    for name in comparison.channel_names:
        hits = [(sc, ch) for sc, n, ch in _pairs(comparison)
                if n == name and abs(ch.final_diff) >= ENDPOINT_MIN_FRACTION * ranges.get(name, ch.scale)
                and abs(ch.final_diff) > (ch.resolution or 0.0) and significant(ch)]
        if not hits:
            continue
        worst_sc, worst = max(hits, key=lambda h: abs(h[1].final_diff))
        unit = f" {units.get(name, '')}".rstrip()
        message = (f"{_label(name)} ends apart in {_count(len(hits), total)}, most in {worst_sc.id} "
                   f"(B - A = {worst.final_diff:+.3g}{unit})")
        out.append(Finding(kind="endpoint", message=message, channel=name, scenarios=[sc.id for sc, _ in hits],
                           share=_share_of(comparison, [(sc.id, name) for sc, _ in hits]), tier=TIERS["endpoint"],
                           evidence={sc.id: {"final_diff": ch.final_diff,
                                             "fraction_of_range": abs(ch.final_diff) / ranges.get(name, ch.scale)}
                                     for sc, ch in hits}))
    return out


def _average_ranks(x: np.ndarray) -> np.ndarray:
    order = np.argsort(x, kind="mergesort")
    inverse = np.empty(x.size, dtype=np.intp)
    inverse[order] = np.arange(x.size)
    ordered = x[order]
    first = np.r_[True, ordered[1:] != ordered[:-1]]
    dense = first.cumsum()[inverse]
    count = np.r_[np.nonzero(first)[0], len(first)]
    return 0.5 * (count[dense] + count[dense - 1] + 1)


def spearman(x: Sequence[float], y: Sequence[float]) -> float:
    """Spearman's rank correlation as ``scipy.stats.spearmanr(x, y).statistic`` computes it (average ranks for
    ties, then ``np.corrcoef``), NaN for a constant or NaN input; without importing scipy.stats, which costs
    about a CPU-second on every ``dualtwin align``."""
    a = np.column_stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)])
    if np.isnan(a).any() or (a[:, 0] == a[0, 0]).all() or (a[:, 1] == a[0, 1]).all():
        return math.nan
    ranked = np.column_stack([_average_ranks(a[:, 0]), _average_ranks(a[:, 1])])
    return float(np.corrcoef(ranked, rowvar=False)[1, 0])


def input_magnitude(value: Any) -> float:
    """Magnitude of a scenario input: a number, or a signal's largest absolute level."""
    if isinstance(value, float | int):
        return abs(float(value))
    if isinstance(value, Constant):
        return abs(value.value)
    if isinstance(value, Step):
        return max(abs(value.before), abs(value.after))
    if isinstance(value, Impulse):
        return max(abs(value.value), abs(value.base))
    if isinstance(value, Ramp):
        return max(abs(value.start), abs(value.end))
    if isinstance(value, Sine):
        return abs(value.amplitude) + abs(value.offset)
    if isinstance(value, Table):
        return max(abs(v) for _, v in value.points)
    return float("nan")


def detect_input_growth(comparison: RunComparison, suite: Suite | None) -> list[Finding]:
    """Divergence that grows with a scenario input's magnitude (Spearman rank correlation over scenarios)."""
    if suite is None:
        return []
    ids = suite.scenario_ids()
    scores = {sc.id: sc.score for sc in comparison.scenarios if sc.score is not None and not sc.unstable}
    keys = sorted({k for s in suite.scenarios for k in s.inputs})
    out: list[Finding] = []
    for key in keys:
        points = [(input_magnitude(s.inputs.get(key, 0.0)), scores[sid])
                  for sid, s in zip(ids, suite.scenarios, strict=True) if sid in scores]
        points = [(m, v) for m, v in points if math.isfinite(m)]
        magnitudes = [m for m, _ in points]
        # Identical scores (twins that agree everywhere) have no rank correlation to speak of.
        if len(points) < 3 or len(set(magnitudes)) < 2 or len({v for _, v in points}) < 2:
            continue
        rho = spearman(magnitudes, [v for _, v in points])
        low = float(np.mean([v for m, v in points if m == min(magnitudes)]))
        high = float(np.mean([v for m, v in points if m == max(magnitudes)]))
        if not math.isfinite(rho) or rho < GROWTH_MIN_SPEARMAN or high - low < GROWTH_MIN_SCORE_RISE:
            continue
        top = [sid for sid, s in zip(ids, suite.scenarios, strict=True)
               if sid in scores and input_magnitude(s.inputs.get(key, 0.0)) == max(magnitudes)]
        message = (f"divergence grows with |{key}| (Spearman ρ = {rho:.2f} over {len(points)} scenarios; "
                   f"score {low:.3g} at |{key}| = {min(magnitudes):g} → {high:.3g} at {max(magnitudes):g})")
        out.append(Finding(kind="input_growth", message=message, scenarios=top,
                           share=_share_of(comparison, [(sid, None) for sid in top]), tier=TIERS["input_growth"],
                           evidence={"input": key, "spearman": rho,
                                     "points": [{"magnitude": m, "score": v} for m, v in points]}))
    return out


def detect_findings(comparison: RunComparison, suite: Suite | None = None) -> list[Finding]:
    """Every finding, ranked: tier first, then share of the divergence."""
    findings = [*detect_instability(comparison), *detect_sign_inversion(comparison), *detect_lag(comparison),
                *detect_scale_mismatch(comparison), *detect_input_growth(comparison, suite),
                *detect_event_time(comparison), *detect_endpoint(comparison)]
    return sorted(findings, key=lambda f: (f.tier, -f.share, f.kind, f.channel or ""))


def attach_knobs(findings: Sequence[Finding], sensitivity: Sequence[KnobSensitivity],
                 available: Sequence[str] | None) -> list[Finding]:
    """Name the knobs to try per finding: the most sensitive one for its term first, then the usual suspects."""
    out: list[Finding] = []
    for finding in findings:
        suggested = list(SUGGESTED[finding.kind])
        if available is not None:
            suggested = [p for p in suggested if fnmatch.filter(available, p)]
        knobs: list[str] = []
        message = finding.message
        relevant = [s for s in sensitivity if s.best_direction != "none" and finding.kind not in _STRUCTURAL]
        if relevant:
            term = _TERM_FOR.get(finding.kind)

            def weight(s: KnobSensitivity, term: str | None = term, scenarios: list[str] = finding.scenarios) -> float:
                if term is not None:
                    return abs(s.per_term.get(term, 0.0))
                picked = [abs(s.per_scenario.get(sid, 0.0)) for sid in scenarios]
                return max(picked) if picked else s.sensitivity

            best = max(relevant, key=weight)
            if weight(best) > 0:
                knobs.append(best.knob)
                message += (f"; the most sensitive knob is {best.knob} ({best.best_direction} it to move B "
                            "toward A)")
        knobs.extend(p for p in suggested if p not in knobs)
        out.append(finding.model_copy(update={"knobs": knobs, "message": message}))
    return out


# ------------------------------------------------------------------ sensitivity
def knob_sensitivity(reference_dir: Path, job: SimJob, specs: Sequence[KnobSpec], evaluator: Evaluator,
                     step: float = 0.05, thresholds: Mapping[str, float] | None = None
                     ) -> tuple[ObjectiveValue, list[KnobSensitivity]]:
    """Finite differences of the objective (reference = ``reference_dir``) with each knob moved up and down."""
    reference = load_traces(reference_dir)
    spec = build_spec(reference, [s for s in reference], thresholds=thresholds)
    plans: list[tuple[KnobSpec, str, float]] = []
    for ks in specs:
        u0 = ks.to_unit(ks.nominal)
        for direction, u in (("up", u0 + step), ("down", u0 - step)):
            if not 0.0 <= u <= 1.0:
                continue
            value = ks.from_unit(u)
            if ks.integer:
                value = ks.nominal + (1.0 if direction == "up" else -1.0)
                if not ks.lower <= value <= ks.upper:
                    continue
            if value != ks.nominal:
                plans.append((ks, direction, value))
    jobs = [job.with_knobs({})] + [job.with_knobs({ks.name: value}) for ks, _, value in plans]
    results = evaluator.map(jobs)
    base = evaluate(spec, results[0])
    out: list[KnobSensitivity] = []
    for ks in specs:
        mine = [(d, v, r) for (k, d, v), r in zip(plans, results[1:], strict=True) if k.name == ks.name]
        if not mine:
            continue
        tried: dict[str, float] = {}
        change: dict[str, float] = {}
        best: tuple[float, str, ObjectiveValue] | None = None
        sens = 0.0
        unstable: list[str] = []
        for direction, value, result in mine:
            value_obj = evaluate(spec, result)
            delta = value_obj.total - base.total
            tried[direction] = value
            change[direction] = delta
            du = abs(ks.to_unit(value) - ks.to_unit(ks.nominal)) or step
            sens = max(sens, abs(delta) / du)
            unstable.extend(value_obj.unstable)
            if best is None or delta < best[0]:
                best = (delta, direction, value_obj)
        assert best is not None
        delta, direction, better = best
        out.append(KnobSensitivity(
            knob=ks.name, unit=ks.unit, nominal=ks.nominal, tried=tried, change=change, sensitivity=sens,
            per_term={k: better.per_term.get(k, 0.0) - base.per_term.get(k, 0.0) for k in base.per_term},
            per_scenario={sid: better.per_scenario[sid] - base.per_scenario[sid] for sid in base.per_scenario},
            best_direction=("increase" if direction == "up" else "decrease") if delta < 0 else "none",
            unstable=sorted(set(unstable)),
        ))
    return base, sorted(out, key=lambda s: (-s.sensitivity, s.knob))


# ------------------------------------------------------------------ entry points
def _suite_of(run_a: Path, run_b: Path) -> tuple[Suite | None, Path | None]:
    for run in (run_b, run_a):
        path = run / "config" / "suite.json"
        if path.is_file():
            return load_suite(path), path
    return None, None


def analyze_runs(
    run_a: Path,
    run_b: Path,
    *,
    robot: str | RobotBinding | None = None,
    twin_b: str | None = None,
    knobs: Sequence[str] | None = None,
    executor: ExecutorKind | Evaluator | None = None,
    workers: int = 2,
    step: float = 0.05,
    thresholds: Mapping[str, float] | None = None,
    propose_fn: ProposeFn | None = None,
) -> Analysis:
    """Explain the divergence of run B from run A (the reference). Deterministic.

    Args:
        run_a: Reference run directory.
        run_b: Run directory of the twin to explain.
        robot: Robot name or binding; with ``twin_b`` it enables knob sensitivities.
        twin_b: Twin that produced run B (``mujoco``, ``webots``), re-simulated with knobs perturbed.
        knobs: Knob names or globs to perturb (default: every knob of ``twin_b``).
        executor: ``process`` (default), ``serial``, ``ray``, or an existing `Evaluator`.
        workers: Process-pool size, or the threads of the MuJoCo batch a MuJoCo ``twin_b`` runs as (see `Evaluator`).
        step: Perturbation as a fraction of each knob's normalised range.
        thresholds: Crossing thresholds per channel (default: 0.99 rad on ``*_angle_rad``).
        propose_fn: Optional proposer (an LLM, see `dualtwin.align.narrate`). It sees the finished
            analysis; with a robot and twin its proposals are re-simulated and kept only if they lower the
            objective, else none can be kept. Its narrative, if any, is attached, labelled as such.

    Raises:
        DualtwinError: Runs that are not comparable (the message lists what is missing on each side),
            unknown knobs, or a missing suite copy when sensitivities are asked for.
    """
    run_a, run_b = Path(run_a), Path(run_b)
    kind = executor if isinstance(executor, str) else "process"
    check_executor(kind)
    binding = resolve_robot(robot) if isinstance(robot, str) else robot
    config = AnalysisConfig(run_a=str(run_a), run_b=str(run_b), robot=None if binding is None else str(binding.path),
                            twin_b=twin_b, knobs=list(knobs or []), step=step, executor=kind, workers=workers,
                            thresholds=None if thresholds is None else dict(thresholds))
    try:
        comparison = compare_runs(run_a, run_b, thresholds)
    except ValueError as exc:
        raise DualtwinError(str(exc)) from None
    suite, suite_path = _suite_of(run_a, run_b)
    findings = detect_findings(comparison, suite)
    notes: list[str] = left_out_notes(comparison) + list(comparison.data_notes)
    sensitivity: list[KnobSensitivity] = []
    objective: ObjectiveValue | None = None
    available: list[str] | None = None
    if (binding is None) != (twin_b is None):
        raise DualtwinError("knob sensitivities need both a robot and the twin that produced run B")
    if binding is not None and twin_b is not None:
        if suite is None or suite_path is None:
            raise DualtwinError(f"{run_b}: no config/suite.json in either run; cannot re-simulate the suite")
        produced_by = load_run(run_b)
        if produced_by.kind != "recorded" and produced_by.twin != twin_b:
            # sensitivities of another twin than the one that made run B explain nothing about run B
            raise DualtwinError(f"{run_b} was run on the {produced_by.twin} twin, but sensitivities were asked of "
                                f"the {twin_b} twin (--target {twin_b}); re-simulate the twin that produced it: "
                                f"--target {produced_by.twin}")
        twin = make_twin(twin_b, binding, suite.global_settings.control_period_s)
        try:
            registry = twin.knobs()
        finally:
            twin.close()
        available = sorted(registry)
        specs = select_knobs(registry, list(knobs) if knobs else ["*"], where=f"twin {twin_b!r}")
        seed = load_run(run_b).seed or 0
        job = SimJob(str(binding.path), twin_b, str(suite_path), None, (), seed)
        own = executor if isinstance(executor, Evaluator) else Evaluator(kind, workers)
        try:
            objective, sensitivity = knob_sensitivity(run_a, job, specs, own, step, thresholds)
            recorded = evaluate(build_spec(load_traces(run_a), list(objective.per_scenario), thresholds=thresholds),
                                load_traces(run_b))
            if abs(recorded.total - objective.total) > 1e-6 * max(1.0, abs(recorded.total)):
                notes.append(f"twin {twin_b!r} at nominal does not reproduce run B (objective {objective.total:.4g} "
                             f"vs {recorded.total:.4g} recorded); sensitivities are relative to the nominal twin")
            analysis = _finish(config, comparison, findings, sensitivity, objective, notes, available)
            if propose_fn is not None:
                spec = build_spec(load_traces(run_a), list(objective.per_scenario), thresholds=thresholds)

                def simulate_objectives(values: Sequence[Mapping[str, float]]) -> list[float]:
                    return [evaluate(spec, r).total for r in own.map([job.with_knobs(v) for v in values])]

                analysis.proposals = try_proposals(propose_fn, analysis, specs, objective.total, simulate_objectives)
        finally:
            if own is not executor:
                own.close()
    else:
        analysis = _finish(config, comparison, findings, sensitivity, objective, notes, available)
        if propose_fn is not None:
            # Nothing can be re-simulated without the robot and twin, so no proposal can be kept.
            analysis.proposals = try_proposals(propose_fn, analysis, [], math.inf, lambda values: [])
            notes.append("proposals need --robot and --twin to be re-simulated; none was kept")
    narrative = getattr(propose_fn, "narrative", None)
    if narrative is not None:
        analysis.narrative = narrative.to_dict()
    return analysis


def _finish(config: AnalysisConfig, comparison: RunComparison, findings: list[Finding],
            sensitivity: list[KnobSensitivity], objective: ObjectiveValue | None, notes: list[str],
            available: list[str] | None) -> Analysis:
    findings = attach_knobs(findings, sensitivity, available)
    if not findings:
        notes.append("no finding: the runs agree within the detectors' thresholds")
    return Analysis(config, comparison, findings, sensitivity, objective, notes)
