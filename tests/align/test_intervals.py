"""Honest intervals (issue 24): autocorrelated residuals widen them, a non-quadratic criterion is profiled, an
unseen knob gets its bounds, and a two-valley fit finds the deeper valley. Closed-form problems, no simulator."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest

from dualtwin.align import AlignConfig, CachedProblem, Evaluation, fit_lsq
from dualtwin.align.core import residual_norm
from dualtwin.align.intervals import effective_samples, estimate_intervals
from dualtwin.align.knobs import KnobSpec, unit_from_values, values_from_unit
from dualtwin.align.objective import ResidualBlock

T = np.linspace(0.0, 1.0, 400)


def ar1(rho: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = np.zeros(n)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + rng.normal(0.0, 0.01)
    return e


class Line(CachedProblem):
    """``y = a t + b + noise``, the residuals one time series (so the layout makes them one block)."""

    def __init__(self, specs: Sequence[KnobSpec], y: np.ndarray, blocks: bool = True, model: str = "line") -> None:
        super().__init__(specs, budget=10_000)
        self.y, self.blocks, self.model = y, blocks, model

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        out = []
        for v in values:
            a = v["a"] ** 3 if self.model == "cubic" else v["a"]
            r = a * T + v.get("b", 0.0) - self.y
            out.append(Evaluation(float(r @ r), None, r))
        return out

    def residual_blocks(self) -> list[ResidualBlock]:
        return [ResidualBlock("s", "y", 0, T.size, "series")]


SPECS = [KnobSpec("a", 1.0, 0.0, 4.0), KnobSpec("b", 0.0, -2.0, 2.0)]


def ols_u(problem: Line) -> list[float]:
    x = np.stack([T, np.ones_like(T)], axis=1)
    coef, *_ = np.linalg.lstsq(x, problem.y, rcond=None)
    return unit_from_values(problem.specs, {"a": float(coef[0]), "b": float(coef[1])})


def test_effective_samples_follow_the_autocorrelation() -> None:
    block = [ResidualBlock("s", "y", 0, 4000, "series")]
    white, red = ar1(0.0, 4000, 1), ar1(0.9, 4000, 1)
    assert effective_samples(white, block) == pytest.approx(4000, rel=0.1)
    # AR(1) with rho 0.9: n (1 - rho) / (1 + rho) = 210.
    assert effective_samples(red, block) == pytest.approx(4000 * 0.1 / 1.9, rel=0.25)
    # Without a layout the residuals count as independent (the textbook interval).
    assert effective_samples(red, None) == 4000


def test_autocorrelated_residuals_widen_the_interval_and_say_so() -> None:
    y = 2.5 * T - 0.7 + ar1(0.95, T.size, 3)
    red, iid = Line(SPECS, y, blocks=True), Line(SPECS, y)
    u = ols_u(red)
    honest = estimate_intervals(red, u, 0.03, profile=False)
    # The same data judged as independent samples (the interval alignment used to report).
    iid.residual_blocks = None  # type: ignore[assignment,method-assign]
    textbook = estimate_intervals(iid, u, 0.03, profile=False)
    assert honest.methods["a"] == "jacobian (n_eff)" and textbook.methods["a"] == "jacobian (iid)"
    ratio = (honest.half_widths["a"] or 0) / (textbook.half_widths["a"] or 1)
    assert ratio > 3.0, ratio  # sqrt((1 + 0.95) / (1 - 0.95)) = 6.2, less the sample autocorrelation's bias
    assert honest.noise["effective_samples"] < 0.2 * T.size
    lo, hi = honest.intervals["a"] or (0.0, 0.0)
    assert lo < 2.5 < hi


def test_a_cubic_criterion_is_profiled_and_an_unseen_knob_gets_its_bounds() -> None:
    specs = [KnobSpec("a", 1.0, 0.0, 2.0), KnobSpec("c", 0.5, 0.0, 1.0)]
    # a enters as a³ and the truth is a = 0.25, where the cube is flat: the criterion is far from quadratic.
    y = 0.25 ** 3 * T + np.random.default_rng(5).normal(0.0, 0.1, T.size)
    problem = Line(specs, y, model="cubic")
    best = min(problem.run([[x, 0.5] for x in np.linspace(0, 1, 2001)]), key=residual_norm)
    unc = estimate_intervals(problem, best.u, 0.03)
    assert unc.methods["a"].startswith("profile"), unc.methods
    lo, hi = unc.intervals["a"] or (0.0, 0.0)
    fitted = values_from_unit(specs, best.u)["a"]
    assert lo < 0.25 < hi and (fitted - lo) > 1.3 * (hi - fitted)  # asymmetric, wider toward the flat side
    assert unc.intervals["c"] == (0.0, 1.0) and unc.half_widths["c"] is None
    assert unc.methods["c"].startswith("unpinned")


class TwoValleys(CachedProblem):
    """r(a) = [a² - 1, 0.3 (a - 1)]: a shallow valley at a = -1 and the true minimum at a = 1."""

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        out = []
        for v in values:
            a = v["a"]
            r = np.array([a * a - 1.0, 0.3 * (a - 1.0)])
            out.append(Evaluation(float(r @ r), None, r))
        return out


@pytest.mark.parametrize("search", ["off", "multistart"])
def test_basin_search_finds_the_deeper_valley(tmp_path: Path, search: str) -> None:
    specs = [KnobSpec("a", -1.4, -2.0, 2.0)]
    problem = TwoValleys(specs, budget=200)
    x0 = unit_from_values(specs, {})
    problem.calibrate(problem.run([x0])[0])
    config = AlignConfig(reference="v", target="v", robot="v", knobs=["a"], optimizer="lsq", budget=200,
                         global_search=search)  # type: ignore[arg-type]
    outcome = fit_lsq(problem, config, tmp_path, x0, 1.0, False, None)
    a = values_from_unit(specs, outcome.u)["a"]
    if search == "off":
        assert a == pytest.approx(-1.0, abs=0.05)  # the control: polishing the start stays in its valley
    else:
        assert a == pytest.approx(1.0, abs=1e-3), outcome.stop_reason
        assert outcome.stop_reason.startswith("basin search: 8 points screened")


class Bouncy(Line):
    """The line plus a bounce: a stretch of samples whose value jumps as ``a`` crosses each multiple of 1.3e-3 (a
    contact that happens or not), so the criterion is rough far below any finite-difference step."""

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        out = []
        for v, e in zip(values, super().evaluate_knobs(values), strict=True):
            r = e.residual.copy()
            phase = (v["a"] / 1.3e-3) % 1.0
            r[200:230] += 0.1 * (phase - 0.5)
            out.append(Evaluation(float(r @ r), None, r))
        return out


def test_a_rough_criterion_is_profiled_to_what_its_bumps_allow_and_labelled() -> None:
    y = 2.5 * T - 0.7 + np.random.default_rng(7).normal(0.0, 0.01, T.size)
    problem = Bouncy(SPECS, y)
    # The fit ends on a bump's low side near the smooth minimum (as a search in a rough valley does).
    grid = [[x, u_b] for x in np.linspace(0.6, 0.65, 801) for u_b in (ols_u(problem)[1],)]
    best = min(problem.run(grid), key=residual_norm)
    # A fresh problem: the search's grid would widen the interval by itself (every simulated point the data
    # cannot reject is inside it); here the profile alone is tested.
    unc = estimate_intervals(Bouncy(SPECS, y), best.u, 0.03)
    assert unc.noise["jitter"] > unc.noise["threshold"]
    # (the checks' own points count too: the corrected points of b's profile can widen a's)
    assert unc.methods["a"].startswith("profile (rough criterion"), unc.methods
    lo, hi = unc.intervals["a"] or (0.0, 0.0)
    assert lo < 2.5 < hi and hi - lo > 4e-3  # wider than the bumps' spacing: the data cannot resolve below it
    # Control: the same data without the bounce keep a quadratic interval that is not labelled rough.
    smooth = estimate_intervals(Line(SPECS, y), ols_u(problem), 0.03)
    assert smooth.noise["jitter"] < smooth.noise["threshold"] and "rough" not in smooth.methods["a"]


@pytest.mark.parametrize("scan", [(0.1, 0.4, 0.9), (0.05, 0.2, 0.45, 0.8), (0.25, 0.5, 0.75, 1.0, 1.5)])
def test_a_profile_crossing_between_scanned_points_is_exact_for_a_quadratic_rise(scan: tuple[float, ...]) -> None:
    # A quadratic criterion rises as (k / k_true)² · threshold: the interval ends at k_true on both sides,
    # wherever the scan's points fall. Interpolating the rise linearly between the points around k_true ends
    # short of it (too narrow an interval); interpolating its square root is exact.
    from dualtwin.align.intervals import _crossing, _hull

    threshold, k_true = 2.0, 0.3
    curve = {sign * k: threshold * (k / k_true) ** 2 for k in scan for sign in (-1.0, 1.0)}
    curve[0.0] = 0.0
    for sign in (-1.0, 1.0):
        for end, reached in (_crossing(curve, sign, threshold), _hull(curve, sign, threshold)):
            assert reached and end == pytest.approx(sign * k_true, abs=1e-12)
    # The control: what linear interpolation of the rise gives on this scan is short of k_true.
    below = max(k for k in scan if k < k_true)
    above = min(k for k in scan if k > k_true)
    v0, v1 = curve[below], curve[above]
    linear = below + (threshold - v0) / (v1 - v0) * (above - below)
    assert linear < k_true - 0.01


class CurvedValley(CachedProblem):
    """``y = a t + noise`` and a second knob tied to the first through a curve, ``b³ = a`` (weight 1000): the
    valley of the criterion is curved, so a profile of ``a`` must re-fit ``b`` off the straight line of the
    covariance. Minimising over ``b`` leaves ``|a t - y|²``: the exact profile interval is known."""

    def __init__(self, specs: Sequence[KnobSpec], y: np.ndarray) -> None:
        super().__init__(specs, budget=100_000)
        self.y = y

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        out = []
        for v in values:
            r = np.concatenate([v["a"] * T - self.y, [1000.0 * (v["b"] ** 3 - v["a"])]])
            out.append(Evaluation(float(r @ r), None, r))
        return out

    def residual_blocks(self) -> list[ResidualBlock]:
        return [ResidualBlock("s", "y", 0, T.size, "series"), ResidualBlock("s", "tie", T.size, T.size + 1, "scalar")]


def curved_valley() -> tuple[list[KnobSpec], CurvedValley, float]:
    """The knobs, the problem (noise 2.0, seed 11) and the least-squares ``a``."""
    specs = [KnobSpec("a", 1.0, 0.0, 4.0), KnobSpec("b", 1.0, 0.5, 3.0)]
    y = T + np.random.default_rng(11).normal(0.0, 2.0, T.size)
    return specs, CurvedValley(specs, y), float(T @ y / (T @ T))


def test_a_profile_in_a_curved_valley_re_fits_the_other_knob_until_it_settles() -> None:
    specs, problem, a_hat = curved_valley()
    unc = estimate_intervals(problem, unit_from_values(specs, {"a": a_hat, "b": a_hat ** (1 / 3)}), 0.03)
    assert unc.methods["a"] == "profile"  # the straight line's rise is far from quadratic: the scan ran
    half = math.sqrt(unc.noise["threshold"] / float(T @ T))  # where |a t - y|² rises by the threshold
    lo, hi = unc.intervals["a"] or (0.0, 0.0)
    # Two fixed corrections per point (before) stopped above the valley floor: [0.871, 1.502] for the exact
    # [0.855, 1.511], too narrow on both sides.
    assert lo == pytest.approx(a_hat - half, abs=1e-3) and hi == pytest.approx(a_hat + half, abs=1e-3)


def test_a_profile_point_below_the_fit_is_handed_back_as_a_better_point() -> None:
    specs, problem, a_hat = curved_valley()
    at_minimum = estimate_intervals(problem, unit_from_values(specs, {"a": a_hat, "b": a_hat ** (1 / 3)}), 0.03)
    assert at_minimum.better is None  # the control: nothing below the minimum
    short = {"a": a_hat + 0.3, "b": (a_hat + 0.3) ** (1 / 3)}  # a fit that stopped on the valley's slope
    unc = estimate_intervals(problem, unit_from_values(specs, short), 0.03)
    assert unc.better is not None
    stopped = problem.run([unit_from_values(specs, short)])[0]
    assert unc.better["criterion"] < residual_norm(stopped) - unc.noise["jitter"]
    moved = values_from_unit(specs, unc.better["u"])["a"]
    assert abs(moved - a_hat) < 0.5 * abs(short["a"] - a_hat)


class Needle(Line):
    """``y = a t + b``, except in a needle around ``a = 3.2`` (width 1e-4) where the model behaves as ``a = depth``:
    a second minimum no scan of ``a`` lands in, as the bounces of a rough criterion leave one."""

    def __init__(self, specs: Sequence[KnobSpec], y: np.ndarray, depth: float) -> None:
        super().__init__(specs, y)
        self.depth = depth

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        return super().evaluate_knobs([{**v, "a": self.depth} if abs(v["a"] - 3.2) < 1e-4 else v for v in values])


def test_an_interval_holds_every_simulated_point_the_data_cannot_reject() -> None:
    y = 2.5 * T - 0.7 + np.random.default_rng(5).normal(0.0, 0.01, T.size)
    u = ols_u(Line(SPECS, y))
    needle_u = list(u)
    needle_u[0] = unit_from_values(SPECS, {"a": 3.2, "b": 0.0})[0]
    # Control: the needle never simulated; the interval is the quadratic one around 2.5, far from 3.2.
    unseen = Needle(SPECS, y, depth=2.5)
    plain = estimate_intervals(unseen, u, 0.03)
    assert plain.methods["a"] == "jacobian (n_eff)" and (plain.intervals["a"] or (0, 9))[1] < 2.6
    # The fit's search simulated the needle, where the criterion is the minimum's: the data cannot reject a = 3.2.
    seen = Needle(SPECS, y, depth=2.5)
    seen.run([needle_u])
    unc = estimate_intervals(seen, u, 0.03)
    lo, hi = unc.intervals["a"] or (0.0, 0.0)
    assert lo == pytest.approx((plain.intervals["a"] or (0, 0))[0]) and hi == pytest.approx(3.2, abs=1e-6)
    assert unc.methods["a"] == "jacobian (n_eff, widened to 1 simulated point)"
    assert unc.half_widths["a"] == pytest.approx(hi - values_from_unit(SPECS, u)["a"])
    assert unc.intervals["b"] == plain.intervals["b"]  # the needle's b is the fit's: nothing to widen
    # Control: a needle whose criterion rises above the threshold is a value the data reject; no widening.
    shallow = Needle(SPECS, y, depth=2.6)
    shallow.run([needle_u])
    rejected = estimate_intervals(shallow, u, 0.03)
    assert rejected.intervals["a"] == plain.intervals["a"] and "widened" not in rejected.methods["a"]
