"""``best_lag`` tests every lagged slice for a constant series from running extremes of the whole series
(one pass per series) instead of one ``np.ptp`` per slice: its results must be the per-slice search's, bit for
bit, since the lag and correlation reach the run comparisons and the files written from them.

The reference below is the per-slice search written out with the public ``pearson``; the series are random,
with flat stretches at either end (where the constant test decides), a constant series, NaN, infinities,
values at the constant test's tolerance, and lengths down to none.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.divergence import best_lag, pearson
from dualtwin.divergence.metrics import LagResult


def per_slice_best_lag(x: np.ndarray, y: np.ndarray, dt: float, max_lag_s: float) -> LagResult:
    """The lag search with ``pearson`` called on every lagged slice (its definition)."""
    n = x.size
    k_max = max(0, min(int(math.floor(max_lag_s / dt + 1e-9)), (n - 2) // 2))
    lags = np.arange(-k_max, k_max + 1)
    corr = [pearson(x[: n - k], y[k:]) if k >= 0 else pearson(x[-k:], y[: n + k]) for k in lags]
    score = np.array([abs(c) if c is not None else -1.0 for c in corr])
    if np.all(score < 0):
        return LagResult(lag_s=0.0, correlation=None)
    ties = np.flatnonzero(score >= float(np.max(score)) - 1e-9)
    i = int(ties[np.argmin(np.abs(lags[ties]))])
    offset = 0.0
    if 0 < i < lags.size - 1 and score[i - 1] >= 0 and score[i + 1] >= 0:
        lo, mid, hi = score[i - 1], score[i], score[i + 1]
        denom = lo - 2.0 * mid + hi
        if denom < 0:
            offset = float(np.clip(0.5 * (lo - hi) / denom, -0.5, 0.5))
    return LagResult(lag_s=(float(lags[i]) + offset) * dt, correlation=corr[i])


def series_pairs() -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(25)
    pairs: list[tuple[np.ndarray, np.ndarray]] = []
    for n in (0, 1, 2, 3, 4, 5, 7, 40, 125):
        pairs.append((rng.normal(size=n), rng.normal(size=n)))
    for _ in range(40):
        n = int(rng.integers(6, 160))
        x, y = rng.normal(size=n), np.cumsum(rng.normal(size=n))
        for v in (x, y):  # flat stretches at the ends: the slices that reach into them only are constant
            head, tail = int(rng.integers(0, n)), int(rng.integers(0, n))
            v[:head] = v[0]
            if tail:
                v[-tail:] = v[-1]
        pairs.append((x, y))
    n = 60
    ramp = np.linspace(0.0, 1.0, n)
    flat = np.full(n, 3.0)
    pairs += [(flat, ramp), (ramp, flat), (flat, flat), (ramp, -ramp)]
    # Spreads at the constant test's tolerance (1e-12 of the larger of 1 and the largest magnitude).
    step = np.where(np.arange(n) < n // 2, 0.0, 1e-12)
    pairs += [(step, ramp), (ramp, 1e3 + step * 1e3), (ramp, 1e3 + step * 0.99e3)]
    with_nan, with_inf, two_inf = ramp.copy(), ramp.copy(), ramp.copy()
    with_nan[7] = math.nan
    with_inf[-5] = math.inf
    two_inf[[3, 50]] = math.inf
    pairs += [(with_nan, ramp), (ramp, with_inf), (two_inf, ramp), (np.full(n, math.inf), ramp)]
    return pairs


@pytest.mark.parametrize("max_lag_s", [0.0, 0.1, 0.5, 10.0])
def test_best_lag_equals_the_per_slice_search(max_lag_s: float) -> None:
    dt = 0.016
    with np.errstate(invalid="ignore"):
        for x, y in series_pairs():
            got, want = best_lag(x, y, dt, max_lag_s=max_lag_s), per_slice_best_lag(x, y, dt, max_lag_s)
            assert repr(got) == repr(want), (x.size, max_lag_s)


def test_the_cases_reach_both_verdicts_at_lags_other_than_zero() -> None:
    """Control: the flat stretches make some lagged slices constant and leave others varying, so a test on
    the wrong end of a series (prefix for suffix) would change a verdict the comparison above sees."""
    seen = set()
    for x, y in series_pairs():
        n = x.size
        for k in range(1, (n - 2) // 2 + 1):
            seen.add((pearson(x[: n - k], y[k:]) is None, pearson(x[k:], y[: n - k]) is None))
    assert {(True, False), (False, True), (False, False)} <= seen


def test_median_is_numpys_bit_for_bit() -> None:
    """``metrics.median`` stands in for np.median (whose NaN check imports numpy.ma): the same value, bit for
    bit, on random series of every length parity, with ties, infinities and NaN (control: the mean of the two
    middle values, not either one, is what an even length must give)."""
    from dualtwin.divergence.metrics import median

    rng = np.random.default_rng(7)
    cases: list[np.ndarray] = [np.array([2.0]), np.array([1.0, 4.0]), np.array([0.1, 0.2, 0.7, 1e308, 1e308])]
    for n in range(1, 60):
        cases.append(rng.normal(size=n) * 10.0 ** rng.integers(-8, 8))
        cases.append(rng.integers(0, 3, size=n).astype(float) * 0.032)  # ties
    inf, nan = np.array([1.0, math.inf, -math.inf, 2.0, math.inf]), np.array([0.5, math.nan, 1.5])
    cases += [inf, nan, np.array([math.nan])]
    for values in cases:
        with np.errstate(invalid="ignore"):
            want = float(np.median(values))
        assert repr(median(values)) == repr(want), values
        assert repr(median(list(values))) == repr(want)
    assert median([1.0, 4.0]) == 2.5
