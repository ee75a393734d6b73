"""Intervals that mean what they say: noise from the residuals with the effective number of independent samples,
and a profile where the objective is not quadratic.

The textbook least-squares interval ``t·√(s²(JᵀJ)⁻¹)`` assumes independent residuals. A trajectory's residuals
are a time series: neighbouring samples of a systematic error are nearly equal, so 500 samples may carry the
information of five. Intervals taken from them as if independent are far too narrow (the recorded-runs bench
once reported a damping of 0.0100 ± 0.00007 where the truth was 0.03). Here:

1. **Noise and effective samples.** The noise variance is ``s² = SSR / (n - p)``. Each channel's residual
   series in each scenario (:func:`dualtwin.align.objective.residual_layout`) is one block; its lag-1
   autocorrelation ρ gives ``n_eff = n (1 - ρ) / (1 + ρ)`` independent samples (AR(1), ρ clipped to
   [0, 0.999]); scalar residuals count once each. The covariance ``s²(JᵀJ)⁻¹`` is inflated by ``n / Σ n_eff``
   and the Student-t quantile uses ``Σ n_eff - p`` degrees of freedom. Method label: ``jacobian (n_eff)``;
   a problem without a residual layout keeps the i.i.d. interval (``jacobian (iid)``).
2. **Profile where curvature is not quadratic.** Along each knob's profile direction (the covariance column:
   the knob moves, the others follow as their correlation says, which is the exact profile path when the
   objective is quadratic; each scanned point then gets Gauss-Newton corrections of the other knobs until they gain less
   than :data:`PROFILE_SETTLED` of the threshold, at most :data:`PROFILE_CORRECTIONS`, as a profile re-fits them) the criterion must rise by ``t²·s²·n/n_eff`` at the quadratic half-width. The points
   ±1 half-width away are simulated (one batch); if the rise there is off by more than the factor
   :data:`QUADRATIC_TOLERANCE` on either side, the direction is scanned (one more batch) and the interval ends
   where the rise crosses the threshold: method ``profile``. A side that never crosses it within the bounds
   ends at the bound (``profile (open to the bound)``).
3. **A rough criterion.** Contacts and impacts make the criterion rough: a change of a knob far below the
   finite-difference step can move it by more than the noise threshold (a bounce happens or not). Then both
   the Jacobian (which sees slopes of the roughness) and a first-crossing profile claim a precision the data
   never gave: the recorded-runs bench once reported a damping interval of width 1e-5 around 0.0142 while the
   truth, 0.03, scored the same to within the roughness. Before any interval is trusted, each knob is moved
   by 1 and 2 × :data:`ROUGH_PROBE` of the step either way and a parabola fitted to the five values; the
   largest miss is the criterion's **jitter** (a smooth criterion is a parabola there to within its next
   Taylor term). Where it exceeds the noise threshold, a
   rise below the jitter cannot reject a value: every knob is profiled out to its bounds with the threshold
   raised by the jitter, the interval is the hull of every scanned value whose rise stays below it (not the
   first crossing, which a bump gives), and the method says ``profile (rough criterion)``.
4. **Proportionate to the fit.** The checks above take 6 to 190 simulations per knob (the central Jacobian 2,
   the roughness probes 4, the quadratic check 2, a scan of 18 to 20 points, each corrected up to 8
   times: 18 to 180), not counted in the fit's budget. A fit
   with a tiny budget would spend most of its time here: ``AlignConfig.intervals="auto"`` (the default)
   computes them only when the budget is at least :data:`SIMULATIONS_PER_KNOB` per continuous knob plus one
   (:func:`intervals_skipped`); below that, and with ``intervals="off"``, no interval is computed and every
   knob's method says so and how to get one (``not computed: ...``) in the terminal, the report and
   ``align_record.json``: a missing interval is never shown as a width. ``intervals="profile"`` always
   computes them.
5. **A better point.** A profile point whose criterion is below the fit's by more than the jitter shows that
   the fit had not reached the minimum; it is returned (``Uncertainty.better``) and the caller moves the fit there
   and computes the intervals again (:func:`dualtwin.align.run.run_align`, least squares).
6. **Every simulated point counts.** A profile is a minimisation, and a stalled one overstates the rise. Every
   point simulated so far (the fit's search, the checks above; :meth:`.core.CachedProblem.simulated`) whose
   criterion rises less than the threshold (plus the jitter, on a rough criterion) is a setting the data cannot
   reject: each interval is widened to hold its values, and the method says ``widened to N simulated points``.
7. **Nothing pinned.** A knob along a direction the Jacobian does not see (no effect, or a combination
   of knobs the suite cannot separate) gets its bounds as the interval, no half-width, method ``unpinned``.

The correlation matrix is taken from the pseudo-inverse of ``JᵀJ`` so that exactly interchangeable knobs show
``|r| = 1`` rather than nothing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from dualtwin.align.core import (
    Problem,
    Uncertainty,
    fd_jacobian,
    integer_half_width,
    interval_estimate,
    residual_norm,
    t_quantile,
)
from dualtwin.align.identifiability import correlated_pairs
from dualtwin.align.knobs import KnobSpec
from dualtwin.align.objective import ResidualBlock

#: The criterion's rise at the quadratic half-width may be off by this factor (either way) before the
#: interval is taken from a profile scan instead.
QUADRATIC_TOLERANCE = 1.2
#: Quadratic half-widths (unit coordinates) below this are not profiled.
PROFILE_RESOLUTION = 1e-6
#: Gauss-Newton corrections of the other knobs at each profile point, at most. A profile re-fits the others; in
#: the curved valleys of a trajectory fit (a kick, a logging delay and a damping trading off) a fixed two left
#: the profile above the valley floor and the intervals too narrow (the CartPole coverage study's kick: 16 of
#: 20). A point stops being corrected once a correction gains less than PROFILE_SETTLED of the noise threshold.
PROFILE_CORRECTIONS = 8
PROFILE_SETTLED = 0.01
#: A profile point this fraction (or the criterion's jitter, if larger) below the fit's residual norm means the
#: fit had not reached the minimum (:attr:`.core.Uncertainty.better`): as R's ``profile`` says of an ``nls`` fit,
#: "profiling has found a better solution, so original fit had not converged".
BETTER_MARGIN = 1e-6
#: Profile scan, in quadratic half-widths from the fit.
SCAN = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0)
#: Roughness probes: each knob moved by this fraction of the finite-difference step, both ways.
ROUGH_PROBE = 0.125
#: A parabola's miss below this fraction of the probed values' spread is a smooth criterion's next Taylor term.
ROUGH_FRACTION = 0.1
#: A rough criterion's profile: this many points per side, spaced geometrically out to the bound.
ROUGH_SCAN = 10
#: ``intervals="auto"`` computes intervals when the fit's budget is at least this many simulations per continuous
#: knob, plus one: the fewest the checks take (a central Jacobian, 2 per knob; the roughness probes, 4 per knob).
SIMULATIONS_PER_KNOB = 6


def intervals_skipped(choice: str, budget: int, knobs: int) -> str | None:
    """Why the intervals are not computed (the method every knob shows), or None when they are.

    ``choice`` is ``AlignConfig.intervals``; ``knobs`` the number of continuous knobs."""
    if choice == "off":
        return "not computed (intervals off): use --intervals profile"
    needed = SIMULATIONS_PER_KNOB * knobs + 1
    if choice == "auto" and knobs and budget < needed:
        return (f"not computed: budget too small ({budget} < {needed}, {SIMULATIONS_PER_KNOB} per knob + 1), "
                "use --intervals profile")
    return None


def not_computed(specs: Sequence[KnobSpec], why: str) -> Uncertainty:
    """No interval for any knob: no half-width, no interval, the method says ``why``."""
    return Uncertainty({s.name: None for s in specs}, None, [], {s.name: None for s in specs},
                       {s.name: why for s in specs})


def effective_samples(r: np.ndarray, blocks: Sequence[ResidualBlock] | None) -> float:
    """Σ n_eff over the residual blocks (AR(1) from each series' lag-1 autocorrelation; the rest count once).

    Channels of one scenario can repeat one another (a joint's angle logged twice, time-stamp jitter shared by
    a row's columns): within a scenario, the series of equal length count as the participation ratio
    ``(Σλ)² / Σλ²`` of their correlation matrix's eigenvalues, not as one channel each.
    """
    if blocks is None:
        return float(r.size)
    covered = 0
    total = 0.0
    by_scenario: dict[tuple[str, int], list[np.ndarray]] = {}
    for b in blocks:
        if b.kind != "series" or b.stop - b.start < 3:
            continue
        x = r[b.start:b.stop]
        covered += x.size
        by_scenario.setdefault((b.scenario, x.size), []).append(x)
    for series in by_scenario.values():
        n_eff = []
        for x in series:
            energy = float(x @ x)
            rho = float(x[:-1] @ x[1:]) / energy if energy > 0 else 0.0
            rho = min(0.999, max(0.0, rho))
            n_eff.append(max(1.0, x.size * (1.0 - rho) / (1.0 + rho)))
        share = 1.0
        if len(series) > 1:
            stack = np.stack(series, axis=1)
            norms = np.linalg.norm(stack, axis=0)
            live = norms > 0
            if live.sum() > 1:
                unit = stack[:, live] / norms[live]
                eig = np.linalg.eigvalsh(unit.T @ unit)
                share = float(eig.sum() ** 2 / (eig @ eig)) / len(series)
        total += share * sum(n_eff)
    return total + float(r.size - covered)


def estimate_intervals(problem: Problem, u: Sequence[float], step: float, profile: bool = True) -> Uncertainty:
    """95 % intervals at the fit ``u`` (see the module docstring); one batch for the Jacobian, one or two per
    profile check."""
    specs = problem.specs
    layout = getattr(problem, "residual_blocks", None)
    blocks: list[ResidualBlock] | None = layout() if callable(layout) else None
    cont = [i for i, s in enumerate(specs) if not s.integer]
    half: dict[str, float | None] = {s.name: None for s in specs}
    intervals: dict[str, tuple[float, float] | None] = {}
    methods: dict[str, str] = {}
    for i, spec in enumerate(specs):
        if spec.integer:
            hw = integer_half_width(problem, u, i)
            value = spec.from_unit(u[i])
            half[spec.name] = hw
            intervals[spec.name] = (max(spec.lower, value - hw), min(spec.upper, value + hw))
            methods[spec.name] = "integer sweep"
    if not cont:
        return Uncertainty(half, None, [], intervals, methods)
    jac, r0 = fd_jacobian(problem, u, step, cont, central=True)
    n, p = r0.size, len(cont)
    n_eff = effective_samples(r0, blocks)
    inflation = max(1.0, n / max(n_eff, 1.0)) if blocks is not None else 1.0
    dof = max(int(round(n_eff)) - p, 1) if blocks is not None else max(n - p, 1)
    base = interval_estimate(jac, r0, [specs[i] for i in cont], [u[i] for i in cont])
    ssr0 = float(r0 @ r0)
    s2 = ssr0 / max(n - p, 1)
    t = t_quantile(dof)
    label = "jacobian (n_eff)" if blocks is not None else "jacobian (iid)"
    # Covariance in unit coordinates from the pseudo-inverse (null directions dropped).
    jtj = jac.T @ jac
    eig, vec = np.linalg.eigh(jtj)
    keep = eig > max(float(eig.max(initial=0.0)), 1e-300) * 1e-12
    pinv = (vec[:, keep] / eig[keep]) @ vec[:, keep].T
    cov = s2 * inflation * pinv
    threshold = t * t * s2 * inflation
    # How rough is the criterion at a fraction of the step? A miss larger than the threshold means rises below
    # it say nothing: every knob is then profiled to its bounds against the threshold plus the jitter.
    jitter = criterion_jitter(problem, u, cont, step) if profile else 0.0
    rough_criterion = jitter > threshold
    names = [specs[i].name for i in cont]
    scans: list[tuple[int, int, float, np.ndarray]] = []
    for col, i in enumerate(cont):
        spec = specs[i]
        if base.half_widths.get(spec.name) is None or cov[col, col] <= 0:
            intervals[spec.name] = (spec.lower, spec.upper)
            methods[spec.name] = "unpinned (the data pin nothing: the bounds)"
            continue
        sd = math.sqrt(cov[col, col])
        direction = np.zeros(len(u))
        direction[cont] = cov[:, col] * t / sd  # moves knob i by its quadratic half-width (unit coordinates)
        value = spec.from_unit(u[i])
        hw = t * sd * spec.dvalue_du(value)
        half[spec.name] = hw
        intervals[spec.name] = (max(spec.lower, value - hw), min(spec.upper, value + hw))
        methods[spec.name] = label
        # Below ~1e-6 of the range a simulation's rise is rounding, not curvature: an exact fit keeps the
        # quadratic interval.
        if profile and (rough_criterion or t * sd > PROFILE_RESOLUTION):
            scans.append((col, i, sd, direction))
    seen: list[Any] = []  # every profile point simulated: a lower one than the fit shows it had not converged
    if scans and rough_criterion:
        rough = [(s, 0.0, 0.0) for s in scans]
    elif scans:
        probes = [_along(u, d, k) for _, _, _, d in scans for k in (-1.0, 1.0)]
        probed = problem.run(probes)
        seen += probed
        rises = [residual_norm(pt) - ssr0 for pt in probed]
        rough = [(s, rises[2 * j], rises[2 * j + 1]) for j, s in enumerate(scans)
                 if not all(1 / QUADRATIC_TOLERANCE ** 2 <= rise / threshold <= QUADRATIC_TOLERANCE ** 2
                            for rise in rises[2 * j:2 * j + 2])]
    else:
        rough = []
    if rough:
        if rough_criterion:
            # Out to the box on each side, denser near the fit: a rough criterion's rise is not read off a
            # multiple of a half-width that the Jacobian of the roughness gave.
            scales = [[s * _reach(u, d, s) * (j / ROUGH_SCAN) ** 2 for s in (-1.0, 1.0)
                       for j in range(1, ROUGH_SCAN + 1)] for (_, _, _, d), _, _ in rough]
        else:
            # Multiples of the quadratic half-width, shrunk on a side where the box ends sooner, so the scan
            # stays inside it (a half-width larger than the box would put every point on its corner).
            scales = [[s * k * _room(u, d, s) for s in (-1.0, 1.0) for k in SCAN] for (_, _, _, d), _, _ in rough]
        points = [_along(u, d, k) for ((_, _, _, d), _, _), ks in zip(rough, scales, strict=True) for k in ks]
        ks = scales[0]  # every knob's scan has as many points
        current = problem.run(points)
        best = [residual_norm(pt) for pt in current]
        # Gauss-Newton corrections of the other knobs at every scan point (the fit's Jacobian, one batch
        # each): a profile re-fits the others, and a curved valley leaves any straight line. A point is
        # corrected again until a correction lowers its criterion by less than PROFILE_SETTLED of the noise
        # threshold (then the crossing cannot move by more than that), at most PROFILE_CORRECTIONS times.
        active = list(range(len(current)))
        for _ in range(PROFILE_CORRECTIONS):
            corrected = []
            for idx in active:
                col = rough[idx // len(ks)][0][0]
                others = [c for c in range(p) if c != col]
                q = list(current[idx].u)
                if others:
                    delta, *_ = np.linalg.lstsq(jac[:, others], -current[idx].residual, rcond=1e-10)
                    for c, dv in zip(others, delta, strict=True):
                        q[cont[c]] = min(1.0, max(0.0, q[cont[c]] + float(dv)))
                corrected.append(q)
            still = []
            for idx, new in zip(active, problem.run(corrected), strict=True):
                gain = best[idx] - residual_norm(new)
                if gain > 0:
                    current[idx], best[idx] = new, best[idx] - gain
                if gain > PROFILE_SETTLED * threshold:
                    still.append(idx)
            active = still
            if not active:
                break
        seen += current
        values = [v - ssr0 for v in best]
        for j, ((_, i, _, d), _, _) in enumerate(rough):
            curve = dict(zip(scales[j], values[j * len(ks):(j + 1) * len(ks)], strict=True))
            curve[0.0] = 0.0
            spec = specs[i]
            ends, open_side = [], False
            for sign in (-1.0, 1.0):
                k_end, reached = (_hull(curve, sign, threshold + jitter) if rough_criterion
                                  else _crossing(curve, sign, threshold))
                point = _along(u, d, k_end)
                open_side |= not reached
                ends.append(spec.lower if not reached and sign < 0 else spec.upper if not reached
                            else spec.from_unit(point[i]))
            value = spec.from_unit(u[i])
            lo, hi = min(ends), max(ends)
            intervals[spec.name] = (lo, hi)
            half[spec.name] = None if open_side else max(hi - value, value - lo)
            notes = ["rough criterion"] if rough_criterion else []
            notes += ["open to the bound"] if open_side else []
            methods[spec.name] = f"profile ({', '.join(notes)})" if notes else "profile"
    # Every point simulated so far (the fit's search, the checks above) bounds the profile from above: a point
    # whose rise stays below the threshold is a setting the data cannot reject, so each of its knob values is
    # inside that knob's interval. On a rough criterion the corrections of a scanned point can stall above a
    # valley floor that the fit's own search had already visited (the CartPole coverage study's misses were
    # almost all such fits, within their truth's basin).
    simulated = getattr(problem, "simulated", None)
    if callable(simulated):
        _widen_to_simulated(specs, u, simulated(), ssr0, threshold + jitter if rough_criterion else threshold,
                            intervals, half, methods)
    corr = _correlation(pinv)
    noise = {"s2": s2, "samples": float(n), "effective_samples": n_eff, "inflation": inflation, "dof": float(dof),
             "threshold": threshold, "jitter": jitter}
    lowest = min(seen, key=residual_norm, default=None)
    better = None
    if lowest is not None and residual_norm(lowest) < ssr0 - max(jitter, BETTER_MARGIN * ssr0):
        better = {"u": [float(x) for x in lowest.u], "criterion": residual_norm(lowest)}
    return Uncertainty(half, base.condition, base.warnings, intervals, methods,
                       {"knobs": names, "matrix": corr.tolist()}, correlated_pairs(names, corr), noise, better)


def _widen_to_simulated(specs: Sequence[KnobSpec], u: Sequence[float], points: Sequence[Any], ssr0: float,
                        limit: float, intervals: dict[str, tuple[float, float] | None],
                        half: dict[str, float | None], methods: dict[str, str]) -> None:
    """Extend each continuous knob's interval to the values of every simulated point whose criterion rises less
    than ``limit`` above the fit's (``ssr0``), and say so in its method. Unpinned knobs keep their bounds."""
    inside = [pt for pt in points if residual_norm(pt) - ssr0 < limit]
    for i, spec in enumerate(specs):
        bounds = intervals.get(spec.name)
        method = methods.get(spec.name, "")
        if spec.integer or bounds is None or method.startswith("unpinned"):
            continue
        lo, hi = bounds
        values = [spec.from_unit(pt.u[i]) for pt in inside]
        wider = [v for v in values if v < lo or v > hi]
        if not wider:
            continue
        lo, hi = min(lo, *values), max(hi, *values)
        intervals[spec.name] = (lo, hi)
        value = spec.from_unit(u[i])
        if half.get(spec.name) is not None:
            half[spec.name] = max(hi - value, value - lo)
        note = f"widened to {len(wider)} simulated point{'s' if len(wider) > 1 else ''}"
        methods[spec.name] = (f"{method[:-1]}, {note})" if method.endswith(")") else f"{method} ({note})")


def criterion_jitter(problem: Problem, u: Sequence[float], cont: Sequence[int], step: float) -> float:
    """The criterion's bumps: each knob moved by 1 and 2 × :data:`ROUGH_PROBE` of ``step`` either way (inward
    only at a bound; one batch), a parabola fitted to the five values, and the largest miss of a parabola over
    every knob. A smooth criterion is a parabola at that distance to within its next Taylor term; one that
    contacts make rough is not. Misses below :data:`ROUGH_FRACTION` of the values' spread are not counted."""
    ks_of: list[list[float]] = []
    probes = []
    for i in cont:
        delta = ROUGH_PROBE * step
        ks = [-2.0, -1.0, 1.0, 2.0]
        if u[i] - 2 * delta < 0.0:
            ks = [1.0, 2.0, 3.0, 4.0]
        elif u[i] + 2 * delta > 1.0:
            ks = [-4.0, -3.0, -2.0, -1.0]
        ks_of.append(ks)
        for k in ks:
            q = list(u)
            q[i] = min(1.0, max(0.0, u[i] + k * delta))
            probes.append(q)
    if not probes:
        return 0.0
    values = [residual_norm(pt) for pt in problem.run([list(u), *probes])]
    f0, rest = values[0], values[1:]
    jitter = 0.0
    for j, ks in enumerate(ks_of):
        x = np.array([0.0, *ks])
        f = np.array([f0, *rest[4 * j:4 * j + 4]])
        coef = np.polyfit(x, f, 2)
        miss = float(np.max(np.abs(np.polyval(coef, x) - f)))
        if miss > ROUGH_FRACTION * float(np.ptp(f)):
            jitter = max(jitter, miss)
    return jitter


def _box_limit(u: Sequence[float], direction: np.ndarray, sign: float) -> float:
    """How many ``direction`` steps from ``u`` along ``sign`` stay inside the unit box (inf: no bound ahead)."""
    limit = math.inf
    for x, dx in zip(u, direction, strict=True):
        step = sign * float(dx)
        if step > 1e-15:
            limit = min(limit, (1.0 - x) / step)
        elif step < -1e-15:
            limit = min(limit, x / -step)
    return limit


def _reach(u: Sequence[float], direction: np.ndarray, sign: float) -> float:
    """How many ``direction`` steps from ``u`` along ``sign`` stay inside the unit box (0 at a bound)."""
    limit = _box_limit(u, direction, sign)
    return 0.0 if not math.isfinite(limit) else limit


def _hull(curve: dict[float, float], sign: float, threshold: float) -> tuple[float, bool]:
    """The outermost scanned point on one side whose rise stays below ``threshold``, extended to where the next
    point out crosses it; ``reached`` is False when even the last scanned point stays below.
    A rough criterion's bump then cannot end an interval that a lower point further out would have extended.
    Between the two points the crossing is interpolated on the rise's square root (:func:`_root_fraction`)."""
    ks = sorted((k for k in curve if k * sign >= 0), key=abs)
    inside = [k for k in ks if curve[k] < threshold]
    last = inside[-1] if inside else 0.0
    beyond = [k for k in ks if abs(k) > abs(last)]
    if not beyond:
        return ks[-1], False
    nxt = beyond[0]
    return last + _root_fraction(curve.get(last, 0.0), curve[nxt], threshold) * (nxt - last), True


def _root_fraction(v0: float, v1: float, threshold: float) -> float:
    """Where between two scanned points (0 and 1) the rise reaches ``threshold``, interpolating the square root
    of the rise: near a minimum the rise grows as the square of the distance, so its root is linear in the knob
    and the crossing is exact for a quadratic criterion (the profile-t idea). Interpolating the rise itself
    puts the crossing short of the truth, more so the coarser the scan: a bias toward too narrow intervals."""
    r0, r1, rt = math.sqrt(max(v0, 0.0)), math.sqrt(max(v1, 0.0)), math.sqrt(max(threshold, 0.0))
    return min(1.0, max(0.0, (rt - r0) / (r1 - r0))) if r1 > r0 else 1.0


def _room(u: Sequence[float], direction: np.ndarray, sign: float) -> float:
    """The factor (at most 1) that makes the scan's last point along ``sign · direction`` land inside the box."""
    return min(1.0, _box_limit(u, direction, sign) / SCAN[-1])


def _along(u: Sequence[float], direction: np.ndarray, k: float) -> list[float]:
    return [min(1.0, max(0.0, float(x))) for x in np.asarray(u) + k * direction]


def _crossing(curve: dict[float, float], sign: float, threshold: float) -> tuple[float, bool]:
    """Where the criterion's rise first crosses ``threshold`` going out on one side (interpolated on the rise's
    square root in between, :func:`_root_fraction`)."""
    ks = sorted((k for k in curve if k * sign >= 0), key=abs)
    prev_k, prev_v = 0.0, 0.0
    for k in ks[1:]:
        v = curve[k]
        if v >= threshold:
            return prev_k + _root_fraction(prev_v, v, threshold) * (k - prev_k), True
        prev_k, prev_v = k, max(prev_v, v)
    return ks[-1], False


def _correlation(pinv: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.clip(np.diag(pinv), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = pinv / np.outer(d, d)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return np.clip(corr, -1.0, 1.0)


def interval_record(unc: Uncertainty, name: str) -> dict[str, Any]:
    """One knob's interval and method for the record and the report."""
    bounds = unc.intervals.get(name)
    return {"interval_95": list(bounds) if bounds is not None else None, "method": unc.methods.get(name)}
