"""Divergence metrics between two time series of one channel (pure functions, no I/O).

Every function takes numpy arrays and returns numbers or frozen dataclasses, so the same code scores a
suite run, an alignment objective or a unit test. Conventions used throughout:

* **Common time base.** Series are compared on the overlap of their time spans, sampled at the time
  stamps of the finer series (ties: series A). The other series is linearly interpolated onto them, so
  when both share a grid no value is changed.
* **DTW.** ``dtw`` is dtaidistance's value: the square root of the summed squared differences along the
  optimal warping path. ``dtw_rms`` normalises it by the number ``n`` of common samples,
  ``dtw / sqrt(n)``. That keeps the channel's unit, does not grow with the log length, and satisfies
  ``dtw_rms <= rmse`` (the diagonal path is one of the candidates), so the two read on the same scale.
* **Lag.** ``lag_s > 0`` means B lags A: ``y_b(t) ~ y_a(t - lag_s)``.
* **Crossings.** The first time ``|y| >= threshold`` (or a signed crossing, see `Threshold`), linearly
  interpolated between samples, on each series' own samples.
* **Score.** A weighted mean of dimensionless terms in ``[0, 1]`` (0 = identical), see `ScoreWeights`.
* **Resolution.** The smallest difference in a channel that means anything physically (a binding declares it
  per channel, else `default_resolution` by unit: 1 mm for m, 1 mrad for rad). A difference at or below it
  never raises a sign inversion and never ranks (``significance <= 1``).
* **Reproducibility floor.** The divergence of a twin against itself when its initial conditions move by a
  tiny amount (an ensemble, see `dualtwin.divergence.floor`). ``floor_ratio`` = divergence between the twins ÷ the larger
  floor: near 1 is as close as the physics allows.
* **Significance.** ``rmse / max(resolution, rmse floor)`` (the floor: the worst member's RMSE, see
  `dualtwin.divergence.floor`): how many times larger than anything the channel can resolve or reproduce
  the difference is. Divergences are ranked by it, not by the score (whose
  amplitude terms are divided by the channel's own range, so a channel that barely moves would dominate).
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from dtaidistance import dtw as _dtw

from dualtwin.artifacts import json_safe

FloatArray = npt.NDArray[np.float64]

#: Default max lag searched by the cross-correlation, in seconds.
DEFAULT_MAX_LAG_S = 1.0
#: Sign inversion needs a correlation at or below this value ...
SIGN_INVERSION_MAX_CORRELATION = -0.8
#: ... and a regression slope of B on A at or below this value.
SIGN_INVERSION_MAX_SLOPE = -0.1

#: Resolution by unit when the binding declares none (documented in the README's divergence section).
DEFAULT_RESOLUTION_BY_UNIT: dict[str, float] = {
    "m": 1e-3, "mm": 1.0, "rad": 1e-3, "deg": 0.05, "m/s": 1e-2, "rad/s": 1e-2, "deg/s": 0.5,
    "s": 1e-3, "N": 1e-2, "N*m": 1e-3, "N·m": 1e-3,
}
#: Resolution of a channel whose unit is unknown or unlisted, in its own unit.
FALLBACK_RESOLUTION = 1e-3
#: A floor ratio at or below this reads "as close as the physics allows".
FLOOR_RATIO_CLOSE = 1.5
#: ... and at or below this "near the floor".
FLOOR_RATIO_NEAR = 3.0

# Relative tolerance below which a series counts as constant or two grids count as equal.
_REL_EPS = 1e-12
_GRID_RTOL = 1e-9


@dataclass(frozen=True)
class Threshold:
    """A crossing threshold.

    Attributes:
        value: Threshold in the channel's unit; must be positive for ``mode="abs"``.
        mode: ``"abs"``: first time ``|y| >= value``; ``"rising"``: first time ``y >= value``;
            ``"falling"``: first time ``y <= value``.
    """

    value: float
    mode: Literal["abs", "rising", "falling"] = "abs"

    def __post_init__(self) -> None:
        if self.mode not in ("abs", "rising", "falling"):
            raise ValueError(f"unknown threshold mode {self.mode!r}; use 'abs', 'rising' or 'falling'")
        if not math.isfinite(self.value):
            raise ValueError(f"threshold must be finite, got {self.value!r}")
        if self.mode == "abs" and self.value <= 0:
            raise ValueError(f"an 'abs' threshold must be positive, got {self.value!r}")

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "mode": self.mode}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Threshold:
        return cls(value=float(data["value"]), mode=data.get("mode", "abs"))


@dataclass(frozen=True)
class ScoreWeights:
    """Weights of the summary score terms. Each term is dimensionless and lies in ``[0, 1]``.

    Amplitude terms are divided by the pooled peak-to-peak range of both series on the common grid, or by
    the channel's resolution where that is larger (``scale``), so channels with different units can be
    averaged and a difference nobody can resolve scores near 0.

    Attributes:
        rmse: Weight of ``rmse / scale``.
        dtw: Weight of ``dtw_rms / scale`` (shape mismatch that survives time warping).
        max_abs: Weight of ``max_abs_error / scale``.
        final: Weight of ``|final_diff| / scale``.
        correlation: Weight of ``(1 - correlation) / 2``.
        crossing: Weight of ``|crossing_diff_s| / duration``; 1 when only one series crosses.
    """

    rmse: float = 0.3
    dtw: float = 0.3
    max_abs: float = 0.1
    final: float = 0.1
    correlation: float = 0.1
    crossing: float = 0.1

    def __post_init__(self) -> None:
        values = self.to_dict()
        if any(not math.isfinite(v) or v < 0 for v in values.values()) or sum(values.values()) <= 0:
            raise ValueError(f"score weights must be finite, non-negative and not all zero: {values}")

    def to_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, float]) -> ScoreWeights:
        return cls(**{k: float(v) for k, v in data.items()})


DEFAULT_WEIGHTS = ScoreWeights()


@dataclass(frozen=True, eq=False)
class CommonSeries:
    """Two series on one time base (see `resample_common`)."""

    t: FloatArray
    a: FloatArray
    b: FloatArray

    @property
    def n(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Median sample spacing in seconds."""
        return median(np.diff(self.t))


def median(values: npt.ArrayLike) -> float:
    """``float(np.median(values))`` for a 1-D series, bit for bit: the middle value, or the mean of the two middle
    ones as ``np.mean`` takes it, ``(a + b) / 2``; NaN when a value is NaN (signed zeros aside: -0.0 and 0.0 tie).

    Not np.median itself: it looks for NaN through ``numpy.ma``, whose import was about 10 ms of a small
    alignment (``dualtwin align --budget 4``, issue 25) that uses no masked array."""
    v = np.sort(np.asarray(values, dtype=np.float64).ravel())  # NaN sorts last
    n = v.size
    if n == 0 or math.isnan(v[-1]):
        return math.nan
    mid = n // 2
    return float(v[mid]) if n % 2 else float((v[mid - 1] + v[mid]) / 2)


@dataclass(frozen=True)
class DtwResult:
    """DTW between two equal-length series.

    Attributes:
        distance: dtaidistance's value, ``sqrt(sum of squared diffs along the warping path)``.
        rms: ``distance / sqrt(n)``, in the channel's unit (see the module docstring).
        n: Number of samples in each series.
    """

    distance: float
    rms: float
    n: int


@dataclass(frozen=True)
class LagResult:
    """Best lag from the cross-correlation.

    Attributes:
        lag_s: Lag in seconds; positive means B lags A. Refined below one sample by a parabola fit.
        correlation: Pearson correlation at the best whole-sample lag (signed), None if undefined.
    """

    lag_s: float
    correlation: float | None


@dataclass(frozen=True)
class Regression:
    """Least-squares fit ``y_b ~ slope * y_a + intercept``; None fields when ``y_a`` is constant."""

    slope: float | None
    intercept: float | None


@dataclass(frozen=True)
class ChannelDivergence:
    """All metrics of one channel between twin A and twin B.

    Differences are signed ``B - A``. Amplitude metrics use the common grid (``n`` samples over
    ``[t_start_s, t_end_s]``); crossing times use each series' own samples.
    """

    channel: str
    n: int
    t_start_s: float
    t_end_s: float
    dt_s: float
    mse: float
    rmse: float
    dtw: float
    dtw_rms: float
    max_abs_error: float
    max_abs_error_time_s: float
    final_diff: float
    correlation: float | None
    lag_s: float
    lag_correlation: float | None
    slope: float | None
    intercept: float | None
    sign_inverted: bool
    threshold: Threshold | None
    crossing_a_s: float | None
    crossing_b_s: float | None
    crossing_diff_s: float | None
    scale: float
    score: float
    score_terms: Mapping[str, float] = field(default_factory=dict)
    #: Smallest meaningful difference in the channel's unit (see the module docstring).
    resolution: float | None = None
    #: ``rmse / max(resolution, rmse floor)``; ranks divergences, <= 1 never ranks.
    significance: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict; non-finite floats become None."""
        out = asdict(self)
        out["threshold"] = None if self.threshold is None else self.threshold.to_dict()
        out["score_terms"] = dict(self.score_terms)
        return json_safe(out)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ChannelDivergence:
        """Inverse of `to_dict`."""
        kwargs = dict(data)
        if kwargs.get("threshold") is not None:
            kwargs["threshold"] = Threshold.from_dict(kwargs["threshold"])
        kwargs["score_terms"] = dict(kwargs.get("score_terms", {}))
        return cls(**kwargs)



def _as_series(t: npt.ArrayLike, y: npt.ArrayLike, name: str) -> tuple[FloatArray, FloatArray]:
    t_arr = np.asarray(t, dtype=np.float64)
    y_arr = np.asarray(y, dtype=np.float64)
    if t_arr.ndim != 1 or y_arr.ndim != 1 or t_arr.shape != y_arr.shape:
        raise ValueError(
            f"series {name}: t and y must be 1-D and equally long, got {t_arr.shape} and {y_arr.shape}"
        )
    return t_arr, y_arr


def finite_prefix(t: npt.ArrayLike, y: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Drop everything from the first non-finite time or value on.

    A twin that blows up logs NaN or inf from then on; the samples before it are still comparable.
    """
    t_arr, y_arr = _as_series(t, y, "")
    finite = np.isfinite(t_arr) & np.isfinite(y_arr)
    end = t_arr.size if finite.all() else int(np.argmin(finite))  # (the first False)
    return t_arr[:end], y_arr[:end]


def time_stamps_problem(t: FloatArray, name: str = "") -> str | None:
    """Why ``t`` cannot be a series' time stamps for `resample_common` (fewer than 2, not finite, not strictly
    increasing), or None when it can."""
    if t.size < 2:
        return f"series {name} needs at least 2 samples, got {t.size}"
    if not np.all(np.isfinite(t)):
        return f"series {name} has non-finite time stamps"
    if np.any(np.diff(t) <= 0):
        return f"series {name}: time must be strictly increasing"
    return None


def _check_time(t: FloatArray, name: str) -> None:
    problem = time_stamps_problem(t, name)
    if problem is not None:
        raise ValueError(problem)


def resample_common(
    t_a: npt.ArrayLike, y_a: npt.ArrayLike, t_b: npt.ArrayLike, y_b: npt.ArrayLike
) -> CommonSeries:
    """Put two series on one time base over the overlap of their spans.

    The grid is the finer series' own time stamps inside the overlap (ties go to A), and the other series
    is linearly interpolated onto it. Identical grids pass through untouched.

    Raises:
        ValueError: If a series is malformed or the overlap holds fewer than 2 samples.
    """
    ta, ya = _as_series(t_a, y_a, "A")
    tb, yb = _as_series(t_b, y_b, "B")
    _check_time(ta, "A")
    _check_time(tb, "B")
    # np.allclose with rtol 0, without its general machinery (the times are finite, checked above): the
    # objective calls this for every channel of every candidate
    if ta.shape == tb.shape and float(np.max(np.abs(ta - tb))) <= _GRID_RTOL * max(1.0, abs(ta[-1])):
        return CommonSeries(t=ta.copy(), a=ya.copy(), b=yb.copy())

    t0, t1 = max(ta[0], tb[0]), min(ta[-1], tb[-1])
    base = ta if median(np.diff(ta)) <= median(np.diff(tb)) else tb
    # Grid points a rounding error outside the overlap still belong to it (e.g. 0.032 * k sums).
    tol = _GRID_RTOL * max(1.0, abs(t0), abs(t1))
    t = base[(base >= t0 - tol) & (base <= t1 + tol)]
    if t.size < 2:
        raise ValueError(f"series overlap [{t0:g}, {t1:g}] s holds {t.size} sample(s); at least 2 are needed")
    return CommonSeries(t=t.copy(), a=np.interp(t, ta, ya), b=np.interp(t, tb, yb))


def mse(a: npt.ArrayLike, b: npt.ArrayLike) -> float:
    """Mean squared error of two equal-length arrays."""
    d = np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64)
    return float(np.mean(d * d))


def rmse(a: npt.ArrayLike, b: npt.ArrayLike) -> float:
    """Root mean squared error of two equal-length arrays."""
    return math.sqrt(mse(a, b))


def max_abs_error(t: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike) -> tuple[float, float]:
    """Largest ``|b - a|`` and the time at which it occurs (first occurrence)."""
    d = np.abs(np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64))
    i = int(np.argmax(d))
    return float(d[i]), float(np.asarray(t, dtype=np.float64)[i])


def dtw_distance(a: npt.ArrayLike, b: npt.ArrayLike, *, window: int | None = None) -> DtwResult:
    """DTW via dtaidistance's C implementation.

    Args:
        a: Series A on the common grid.
        b: Series B on the common grid, same length as ``a``.
        window: Optional Sakoe-Chiba band half-width in samples; None for unconstrained DTW.

    Returns:
        The raw distance and its ``/ sqrt(n)`` normalisation (see the module docstring).
    """
    # dtaidistance's C code takes writable buffers only: arrays from a read-only source (a Ray object store, a
    # memory map) are copied
    s1 = np.require(a, dtype=np.float64, requirements=("C", "W"))
    s2 = np.require(b, dtype=np.float64, requirements=("C", "W"))
    if s1.shape != s2.shape or s1.ndim != 1 or s1.size == 0:
        raise ValueError(f"dtw needs two non-empty 1-D series of equal length, got {s1.shape} and {s2.shape}")
    kwargs: dict[str, Any] = {} if window is None else {"window": int(window)}
    # dtaidistance's default pruning uses the Euclidean distance as an upper bound and returns inf when
    # the diagonal path is optimal and rounding puts DTW a hair above it (near-identical series).
    distance = float(_dtw.distance_fast(s1, s2, use_pruning=False, **kwargs))
    if not math.isfinite(distance):
        raise ValueError(f"dtw is not finite ({distance}); are the inputs finite?")
    return DtwResult(distance=distance, rms=distance / math.sqrt(s1.size), n=int(s1.size))


def _is_constant(x: FloatArray) -> bool:
    return bool(np.ptp(x) <= _REL_EPS * max(1.0, float(np.max(np.abs(x)))))


def pearson(a: npt.ArrayLike, b: npt.ArrayLike) -> float | None:
    """Pearson correlation, or None when either series is constant (undefined)."""
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.size < 2 or _is_constant(x) or _is_constant(y):
        return None
    return _pearson_varying(x, y)


def _pearson_varying(x: FloatArray, y: FloatArray) -> float:
    """`pearson` of two series already known to vary (the one place its arithmetic is written)."""
    xc, yc = x - x.mean(), y - y.mean()
    r = float(np.dot(xc, yc) / math.sqrt(float(np.dot(xc, xc)) * float(np.dot(yc, yc))))
    return min(1.0, max(-1.0, r))


def _constant_ends(x: FloatArray) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """`_is_constant` of every prefix ``x[:m]`` and every suffix ``x[-m:]``, at index ``m - 1``, in one pass.

    The running maximum and minimum are the slices' own (max and min round nothing, and NaN propagates as
    in `np.ptp`), so each verdict is the one `_is_constant` gives the slice; `best_lag` asks it for about
    sixty slices of each series, where a call per slice cost more than the correlations."""
    def verdicts(v: FloatArray) -> npt.NDArray[np.bool_]:
        with np.errstate(invalid="ignore"):  # inf - inf: NaN, not constant, as np.ptp has it (silently here)
            spread = np.maximum.accumulate(v) - np.minimum.accumulate(v)
        return np.asarray(spread <= _REL_EPS * np.maximum(1.0, np.maximum.accumulate(np.abs(v))))
    return verdicts(x), verdicts(x[::-1])


def best_lag(
    a: npt.ArrayLike, b: npt.ArrayLike, dt: float, *, max_lag_s: float = DEFAULT_MAX_LAG_S
) -> LagResult:
    """Lag that maximises ``|Pearson correlation|`` between A and a shifted B.

    Each candidate lag is scored by the Pearson correlation of the overlapping parts only, so short
    overlaps are not penalised the way a raw cross-correlation sum would. Maximising the absolute value
    keeps a sign-inverted copy at lag 0 instead of half a period away. Lags are limited to
    ``max_lag_s`` and to half the series.

    Args:
        a: Series A on a uniform grid.
        b: Series B on the same grid.
        dt: Grid spacing in seconds.
        max_lag_s: Largest lag searched, in seconds.

    Returns:
        The lag in seconds (positive: B lags A) and the signed correlation there.
    """
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    n = x.size
    if dt <= 0 or not math.isfinite(dt):
        raise ValueError(f"dt must be positive, got {dt!r}")
    k_max = max(0, min(int(math.floor(max_lag_s / dt + 1e-9)), (n - 2) // 2))
    lags = np.arange(-k_max, k_max + 1)
    corr: list[float | None] = []
    # `pearson`'s test for a constant slice, made for every prefix and suffix of each series at once.
    ends = (_constant_ends(x), _constant_ends(y)) if y.shape == x.shape == (n,) and n - k_max >= 2 else None
    for k in lags:
        # y[i + k] pairs with x[i]: a positive k finds B's copy of A's feature k samples later.
        xs, ys = (x[: n - k], y[k:]) if k >= 0 else (x[-k:], y[: n + k])
        if ends is None:
            corr.append(pearson(xs, ys))
            continue
        (x_prefix, x_suffix), (y_prefix, y_suffix) = ends
        m = n - abs(int(k))  # the overlap's length, 2 or more
        flat = (x_prefix[m - 1] or y_suffix[m - 1]) if k >= 0 else (x_suffix[m - 1] or y_prefix[m - 1])
        corr.append(None if flat else _pearson_varying(xs, ys))
    score = np.array([abs(c) if c is not None else -1.0 for c in corr])
    if np.all(score < 0):
        return LagResult(lag_s=0.0, correlation=None)
    best = float(np.max(score))
    # Among equally good lags prefer the smallest shift (e.g. lag 0 for identical series).
    ties = np.flatnonzero(score >= best - 1e-9)
    i = int(ties[np.argmin(np.abs(lags[ties]))])
    offset = 0.0
    if 0 < i < lags.size - 1 and score[i - 1] >= 0 and score[i + 1] >= 0:
        lo, mid, hi = score[i - 1], score[i], score[i + 1]
        denom = lo - 2.0 * mid + hi
        if denom < 0:
            offset = float(np.clip(0.5 * (lo - hi) / denom, -0.5, 0.5))
    return LagResult(lag_s=(float(lags[i]) + offset) * dt, correlation=corr[i])


def regression(a: npt.ArrayLike, b: npt.ArrayLike) -> Regression:
    """Least-squares slope and intercept of B on A (``b ~ slope * a + intercept``)."""
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.size < 2 or _is_constant(x):
        return Regression(slope=None, intercept=None)
    xc = x - x.mean()
    slope = float(np.dot(xc, y - y.mean()) / np.dot(xc, xc))
    return Regression(slope=slope, intercept=float(y.mean() - slope * x.mean()))


def is_sign_inverted(
    correlation: float | None,
    slope: float | None,
    *,
    max_correlation: float = SIGN_INVERSION_MAX_CORRELATION,
    max_slope: float = SIGN_INVERSION_MAX_SLOPE,
) -> bool:
    """True when B looks like a negated copy of A: strongly negative correlation and a clearly negative slope."""
    return (
        correlation is not None
        and slope is not None
        and correlation <= max_correlation
        and slope <= max_slope
    )


def crossing_time(t: npt.ArrayLike, y: npt.ArrayLike, threshold: float | Threshold) -> float | None:
    """First time the series reaches the threshold, linearly interpolated between samples.

    Args:
        t: Time stamps, increasing.
        y: Values.
        threshold: A float means ``|y| >= threshold``; see `Threshold` for signed crossings.

    Returns:
        The crossing time, ``t[0]`` if the first sample is already past the threshold, or None if the
        series never reaches it.
    """
    thr = threshold if isinstance(threshold, Threshold) else Threshold(float(threshold))
    t_arr, y_arr = _as_series(t, y, "")
    if thr.mode == "abs":
        hit = np.abs(y_arr) >= thr.value
    elif thr.mode == "rising":
        hit = y_arr >= thr.value
    else:
        hit = y_arr <= thr.value
    idx = np.flatnonzero(hit)
    if idx.size == 0:
        return None
    i = int(idx[0])
    if i == 0:
        return float(t_arr[0])
    # For |y| the level is the threshold on the side the series arrives at (it may jump across zero).
    level = math.copysign(thr.value, y_arr[i]) if thr.mode == "abs" else thr.value
    y0, y1 = float(y_arr[i - 1]), float(y_arr[i])
    frac = (level - y0) / (y1 - y0) if y1 != y0 else 1.0
    frac = min(1.0, max(0.0, frac))
    return float(t_arr[i - 1] + frac * (t_arr[i] - t_arr[i - 1]))


def score_terms(
    *,
    scale: float,
    duration_s: float,
    rmse: float,
    dtw_rms: float,
    max_abs_error: float,
    final_diff: float,
    correlation: float | None,
    both_constant: bool,
    crossing_a_s: float | None,
    crossing_b_s: float | None,
) -> dict[str, float]:
    """Dimensionless score terms in ``[0, 1]`` (0 = identical); see `ScoreWeights`."""

    def unit(x: float) -> float:
        return min(1.0, max(0.0, x))

    if correlation is not None:
        corr_term = (1.0 - correlation) / 2.0
    else:
        # Two constants have no shape to disagree on; a constant against a moving signal shares none.
        corr_term = 0.0 if both_constant else 0.5
    if crossing_a_s is None and crossing_b_s is None:
        cross_term = 0.0
    elif crossing_a_s is None or crossing_b_s is None:
        cross_term = 1.0
    else:
        cross_term = abs(crossing_b_s - crossing_a_s) / duration_s if duration_s > 0 else 1.0
    return {
        "rmse": unit(rmse / scale),
        "dtw": unit(dtw_rms / scale),
        "max_abs": unit(max_abs_error / scale),
        "final": unit(abs(final_diff) / scale),
        "correlation": unit(corr_term),
        "crossing": unit(cross_term),
    }


def weighted_score(terms: Mapping[str, float], weights: ScoreWeights = DEFAULT_WEIGHTS) -> float:
    """Weighted mean of score terms: ``sum(w * term) / sum(w)``."""
    w = weights.to_dict()
    missing = set(w) - set(terms)
    if missing:
        raise ValueError(f"score terms missing: {sorted(missing)}")
    return float(sum(w[k] * terms[k] for k in w) / sum(w.values()))


#: Channel comparisons already computed in this process, by the bytes of their inputs and their settings (the
#: most recent :data:`_COMPARED_MAX`): an on-board channel that logs its ground-truth twin's values, or an
#: alignment's after run equal to its before run, is compared once. The metrics are a pure function of these.
_COMPARED: OrderedDict[bytes, ChannelDivergence] = OrderedDict()
_COMPARED_MAX = 4096


def _comparison_key(series: tuple[npt.ArrayLike, ...], settings: tuple[Any, ...]) -> bytes:
    digest = hashlib.blake2b(repr(settings).encode(), digest_size=20)
    for values in series:
        array = np.ascontiguousarray(values, dtype=np.float64)
        digest.update(repr(array.shape).encode())
        digest.update(array.tobytes())
    return digest.digest()


def compare_channel(
    t_a: npt.ArrayLike,
    y_a: npt.ArrayLike,
    t_b: npt.ArrayLike,
    y_b: npt.ArrayLike,
    *,
    channel: str = "",
    threshold: float | Threshold | None = None,
    max_lag_s: float = DEFAULT_MAX_LAG_S,
    dtw_window: int | None = None,
    weights: ScoreWeights = DEFAULT_WEIGHTS,
    resolution: float | None = None,
) -> ChannelDivergence:
    """Compute every divergence metric of one channel between twin A and twin B.

    Samples from the first non-finite value on are dropped (see `finite_prefix`). With a ``resolution``, a
    pair whose RMSE or either range is at or below it is never flagged as sign-inverted (a 13 µm cart
    wobble has no meaningful direction), ``significance`` is ``rmse / resolution``, and the score judges
    against it too: amplitude terms are divided by at least the resolution, and a series whose range is
    within the resolution counts as flat for the correlation term (two flat series share their shape; a
    flat one against a moving one shares none).

    Args:
        t_a: Time stamps of A in seconds.
        y_a: Values of A.
        t_b: Time stamps of B in seconds.
        y_b: Values of B.
        channel: Channel name, copied into the result.
        threshold: Crossing threshold; None skips crossing times.
        max_lag_s: Largest lag searched by the cross-correlation.
        dtw_window: Optional Sakoe-Chiba band half-width in samples of the common grid.
        weights: Score weights.
        resolution: Smallest meaningful difference in the channel's unit (None: no significance).

    Raises:
        ValueError: If either series is malformed or the overlap holds fewer than 2 finite samples.
    """
    if resolution is not None and not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be positive and finite, got {resolution!r}")
    key = _comparison_key((t_a, y_a, t_b, y_b), (threshold, max_lag_s, dtw_window, weights, resolution))
    known = _COMPARED.get(key)
    if known is None:
        known = _compare_channel(t_a, y_a, t_b, y_b, threshold, max_lag_s, dtw_window, weights, resolution)
        _COMPARED[key] = known
        if len(_COMPARED) > _COMPARED_MAX:
            _COMPARED.popitem(last=False)
    else:
        _COMPARED.move_to_end(key)
    return replace(known, channel=channel, score_terms=dict(known.score_terms))


def _compare_channel(t_a: npt.ArrayLike, y_a: npt.ArrayLike, t_b: npt.ArrayLike, y_b: npt.ArrayLike,
                     threshold: float | Threshold | None, max_lag_s: float, dtw_window: int | None,
                     weights: ScoreWeights, resolution: float | None) -> ChannelDivergence:
    """`compare_channel`, computed (with an empty channel name)."""
    ta, ya = finite_prefix(t_a, y_a)
    tb, yb = finite_prefix(t_b, y_b)
    common = resample_common(ta, ya, tb, yb)
    t, a, b = common.t, common.a, common.b
    thr = (
        None
        if threshold is None
        else threshold
        if isinstance(threshold, Threshold)
        else Threshold(float(threshold))
    )

    err = mse(a, b)
    dtw_res = dtw_distance(a, b, window=dtw_window)
    mae, mae_t = max_abs_error(t, a, b)
    final = float(b[-1] - a[-1])
    corr = pearson(a, b)
    lag = best_lag(a, b, common.dt, max_lag_s=max_lag_s)
    reg = regression(a, b)
    cross_a = crossing_time(ta, ya, thr) if thr is not None else None
    cross_b = crossing_time(tb, yb, thr) if thr is not None else None
    cross_diff = cross_b - cross_a if cross_a is not None and cross_b is not None else None

    ptp = float(max(a.max(), b.max()) - min(a.min(), b.min()))
    # A flat pair has nothing to normalise by; its differences are ~0 anyway.
    scale = ptp if ptp > _REL_EPS * max(1.0, float(np.max(np.abs(np.concatenate([a, b]))))) else 1.0
    if resolution is not None:
        # Judge the score against what the channel can resolve, as the ranking does: a pair whose whole
        # range is below the resolution has no amplitude or shape to disagree on (a 4.5e-8 m difference
        # is not 84 % of "maximal divergence", and two flat lines 60 µm/s apart have no meaningful r).
        scale = max(scale, resolution)
    flat_a = _is_constant(a) or not resolves(resolution, float(np.ptp(a)))
    flat_b = _is_constant(b) or not resolves(resolution, float(np.ptp(b)))
    terms = score_terms(
        scale=scale,
        duration_s=float(t[-1] - t[0]),
        rmse=math.sqrt(err),
        dtw_rms=dtw_res.rms,
        max_abs_error=mae,
        final_diff=final,
        correlation=None if flat_a or flat_b else corr,
        both_constant=flat_a and flat_b,
        crossing_a_s=cross_a,
        crossing_b_s=cross_b,
    )
    return ChannelDivergence(
        channel="",
        n=common.n,
        t_start_s=float(t[0]),
        t_end_s=float(t[-1]),
        dt_s=common.dt,
        mse=err,
        rmse=math.sqrt(err),
        dtw=dtw_res.distance,
        dtw_rms=dtw_res.rms,
        max_abs_error=mae,
        max_abs_error_time_s=mae_t,
        final_diff=final,
        correlation=corr,
        lag_s=lag.lag_s,
        lag_correlation=lag.correlation,
        slope=reg.slope,
        intercept=reg.intercept,
        sign_inverted=is_sign_inverted(corr, reg.slope) and resolves(resolution, math.sqrt(err),
                                                                     float(np.ptp(a)), float(np.ptp(b))),
        threshold=thr,
        crossing_a_s=cross_a,
        crossing_b_s=cross_b,
        crossing_diff_s=cross_diff,
        scale=scale,
        score=weighted_score(terms, weights),
        score_terms=terms,
        resolution=resolution,
        significance=None if resolution is None else significance(math.sqrt(err), resolution),
    )


# ------------------------------------------------------------------ resolution, floor, significance
def default_resolution(unit: str) -> float:
    """The resolution of a channel in ``unit`` when its binding declares none (see the module docstring)."""
    return DEFAULT_RESOLUTION_BY_UNIT.get(unit.strip(), FALLBACK_RESOLUTION)


def resolves(resolution: float | None, *amounts: float) -> bool:
    """True when every amount (a difference, a range) exceeds the resolution (always, without one)."""
    return resolution is None or all(x > resolution for x in amounts)


def significance(divergence: float, resolution: float, floor: float | None = None) -> float:
    """``divergence / max(resolution, floor)``: above 1 the difference is resolvable and reproducible."""
    return float(divergence / max(resolution, floor or 0.0))


def predictability_horizon(t: npt.ArrayLike, ys: npt.ArrayLike, resolution: float) -> tuple[float, float | None]:
    """Members' largest spread and the first time it exceeds ``resolution``.

    Args:
        t: Common time stamps, shape ``(n,)``.
        ys: Member values on ``t``, shape ``(members, n)``.
        resolution: The channel's resolution.

    Returns:
        ``(largest spread, first time spread > resolution or None)``.
    """
    t_arr = np.asarray(t, dtype=np.float64)
    y_arr = np.asarray(ys, dtype=np.float64)
    if y_arr.ndim != 2 or y_arr.shape[1] != t_arr.size or t_arr.size == 0:
        raise ValueError(f"members must have shape (members, {t_arr.size}), got {y_arr.shape}")
    spread = np.ptp(y_arr, axis=0)
    over = np.flatnonzero(spread > resolution)
    return float(spread.max()), (float(t_arr[over[0]]) if over.size else None)
