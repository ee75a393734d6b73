"""Which scenarios the twins cannot share: each scenario's divergence after the fit against the target twin's
reproducibility floor, and the scenarios a user excluded from the objective.

A pole that lands on a hard stop is chaotic: a shift of its start by 10 µrad moves every bounce after the
first impact (see :mod:`dualtwin.divergence.floor`). No knob setting makes a second engine agree with the
reference more closely than the target agrees with itself under such a shift, and a scenario dominated by
bounces pulls every knob toward whatever averages them best. After every fit, the target is simulated at the
fitted values twice more, with every position initial condition shifted by ±:data:`FLOOR_EPS` at fresh
starts; per scenario and channel, the DTW between the reference and the fitted target is divided by the mean
DTW between the target's shifted members and its unshifted run (its floor), and the first time the members
spread beyond the channel's resolution is the scenario's **horizon**. A scenario more than
:data:`FLOOR_LIMIT` × its floor is *named* in the terminal, the report and ``align_record.json``, with the
ratio and the horizon; it is never dropped without the user's consent. A scenario above the limit only by
differences within its channels' resolution is named apart (:func:`within_resolution`): no log can show them.
Excluding a scenario is the user's call: ``AlignConfig.exclude`` (``--exclude SCENARIO``) leaves it out of the
objective (neither fitted nor held out) and the record says so, with the measurement that motivated it.

Only the target's floor is measured (a recorded reference has no members); an ensemble reference's own floor
is judged by ``dualtwin compare``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from dualtwin.align.simulate import Evaluator, SimJob, Traces
from dualtwin.divergence.floor import channel_resolutions
from dualtwin.divergence.metrics import dtw_distance, finite_prefix, predictability_horizon, resample_common
from dualtwin.robots.binding import RobotBinding

#: Shift of every position initial condition (in its unit) for the target's floor members.
FLOOR_EPS = 1e-5
#: A scenario is named when its divergence after the fit exceeds this multiple of the target's floor.
FLOOR_LIMIT = 1.5


@dataclass(frozen=True)
class ScenarioFloor:
    """One scenario's and channel's divergence after the fit against the target's reproducibility floor."""

    scenario: str
    channel: str
    dtw: float
    floor_dtw: float
    ratio: float | None
    horizon_s: float | None
    dtw_rms: float
    resolution: float

    @property
    def beyond(self) -> bool:
        """More than :data:`FLOOR_LIMIT` × the floor, and above the channel's resolution (a floor of exactly 0,
        a predictable scenario, is judged against the resolution alone)."""
        if self.dtw_rms <= self.resolution:
            return False
        return self.ratio is None or self.ratio > FLOOR_LIMIT

    @property
    def within_resolution(self) -> bool:
        """More than :data:`FLOOR_LIMIT` × a nonzero floor, but no farther from the reference than the channel's
        resolution: beyond the floor by a difference no log of the channel can show (not :attr:`beyond`)."""
        return self.dtw_rms <= self.resolution and self.ratio is not None and self.ratio > FLOOR_LIMIT

    def why(self) -> str:
        where = (f"the target's members shifted by ±{FLOOR_EPS:g} stop agreeing at t = {self.horizon_s:.3g} s"
                 if self.horizon_s is not None else "the target's shifted members agree within the resolution")
        ratio = f"{self.ratio:.3g}× the target's reproducibility floor" if self.ratio is not None else \
            f"{self.dtw_rms / self.resolution:.3g}× the channel's resolution (no floor)"
        if self.within_resolution:
            where = (f"its RMS difference {self.dtw_rms:.3g} is within the channel's resolution {self.resolution:.3g}, "
                     "so no log of it can show the difference")
        return f"{self.channel} DTW {self.dtw:.4g} after the fit = {ratio}; {where}"

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "beyond": self.beyond, "within_resolution": self.within_resolution}


def floor_members(binding: RobotBinding) -> list[dict[str, float]]:
    """The two shifted members: every position initial condition of the binding moved by ±:data:`FLOOR_EPS`."""
    keys = [k for k, ic in binding.spec.initial_conditions.items() if ic.quantity == "position"]
    return [{k: sign * FLOOR_EPS for k in keys} for sign in (1.0, -1.0)] if keys else []


def _dtw(ta: np.ndarray, ya: np.ndarray, tb: np.ndarray, yb: np.ndarray) -> tuple[float, float]:
    try:
        common = resample_common(ta, ya, tb, yb)
    except ValueError:
        return float("inf"), float("inf")
    d = dtw_distance(common.a, common.b)
    return float(d.distance), float(d.rms)


def check_floors(evaluator: Evaluator, job: SimJob, values: Mapping[str, float], reference: Mapping[str, Any],
                 scenarios: Sequence[str], channels: Sequence[str], binding: RobotBinding,
                 after: Traces | None = None) -> list[ScenarioFloor]:
    """Every scenario × channel of ``scenarios`` judged against the target's floor at ``values`` (two or three
    suite runs, not counted in the fit's budget)."""
    members = floor_members(binding)
    if not members:
        return []
    jobs = [job.with_knobs(values).with_offsets(m) for m in members]
    runs = evaluator.map(([] if after is not None else [job.with_knobs(values)]) + jobs)
    base = after if after is not None else runs[0]
    shifted = runs if after is not None else runs[1:]
    resolutions = channel_resolutions(binding)
    out: list[ScenarioFloor] = []
    for sid in scenarios:
        if sid not in base or sid not in reference:
            continue
        for name in channels:
            ref, cand = reference[sid].series.get(name), base[sid].series.get(name)
            if ref is None or cand is None:
                continue
            ta, ya = finite_prefix(ref.t, ref.y)
            t0, y0 = finite_prefix(cand.t, cand.y)
            dtw, rms = _dtw(ta, ya, t0, y0)
            floors = []
            stack = [y0]
            for run in shifted:
                tk, yk = finite_prefix(run[sid].series[name].t, run[sid].series[name].y)
                floors.append(_dtw(t0, y0, tk, yk)[0])
                stack.append(np.interp(t0, tk, yk) if tk.size else np.full_like(y0, np.nan))
            floor = float(np.mean(floors))
            resolution = resolutions.get(name, 0.0)
            horizon = predictability_horizon(t0, np.vstack(stack), resolution)[1] if t0.size else None
            ratio = dtw / floor if floor > 0 and np.isfinite(floor) else None
            out.append(ScenarioFloor(sid, name, dtw, floor, ratio, horizon, rms, resolution))
    return out


def beyond_floor(rows: Sequence[ScenarioFloor]) -> dict[str, str]:
    """Scenario -> why, for every scenario with a channel beyond the floor (the worst channel's numbers)."""
    return _worst(rows, lambda r: r.beyond)


def within_resolution(rows: Sequence[ScenarioFloor]) -> dict[str, str]:
    """Scenario -> why, for every scenario more than :data:`FLOOR_LIMIT` × its floor only by differences within
    its channels' resolution (none :attr:`~ScenarioFloor.beyond`): named too, so that every scenario above the
    limit is in the record, but not as one the twins cannot share."""
    beyond = beyond_floor(rows)
    return {sid: why for sid, why in _worst(rows, lambda r: r.within_resolution).items() if sid not in beyond}


def _worst(rows: Sequence[ScenarioFloor], test: Callable[[ScenarioFloor], bool]) -> dict[str, str]:
    out: dict[str, str] = {}
    for sid in dict.fromkeys(r.scenario for r in rows):
        bad = [r for r in rows if r.scenario == sid and test(r)]
        if bad:
            worst = max(bad, key=lambda r: r.ratio if r.ratio is not None else float("inf"))
            out[sid] = worst.why()
    return out
