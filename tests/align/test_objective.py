"""The objective and residuals: pure functions of a reference and a candidate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.align.objective import (
    ObjectiveWeights,
    build_spec,
    channel_terms,
    evaluate,
    event_difference,
    pseudo_huber,
    residual_size,
    residuals,
)
from dualtwin.align.simulate import ScenarioTrace
from dualtwin.divergence.metrics import Threshold, dtw_distance, finite_prefix, resample_common, rmse
from dualtwin.divergence.runs import Series
from dualtwin.errors import DualtwinError

T = (np.arange(1, 48) * 0.032).astype(np.float64)


def trace(sid: str, angle: np.ndarray, cart: np.ndarray, status: str = "completed") -> ScenarioTrace:
    n = angle.size
    return ScenarioTrace(sid, status, 1.5, {"pole_angle_rad": Series(T[:n], angle), "cart_pos_m": Series(T[:n], cart)})


def fall(delay: float = 0.0, gain: float = 1.0) -> np.ndarray:
    return np.clip(0.05 * np.exp(3.0 * (T - delay)), -1.0, 1.0) * gain


REF = {"a": trace("a", fall(), 0.2 * T), "b": trace("b", -fall(0.1), -0.1 * T)}


def test_identical_candidate_scores_zero() -> None:
    spec = build_spec(REF, ["a", "b"])
    assert evaluate(spec, REF).total == 0.0
    assert not residuals(spec, REF).any()
    assert residuals(spec, REF).size == residual_size(spec)


def test_terms_grow_with_the_mismatch_and_scales_come_from_the_reference() -> None:
    spec = build_spec(REF, ["a", "b"])
    assert spec.scales["cart_pos_m"] == pytest.approx(0.2 * (T[-1] - T[0]))
    late = {"a": trace("a", fall(0.05), 0.2 * T), "b": REF["b"]}
    later = {"a": trace("a", fall(0.15), 0.2 * T), "b": REF["b"]}
    v1, v2 = evaluate(spec, late), evaluate(spec, later)
    assert 0 < v1.total < v2.total
    assert v1.per_term["event"] > 0 and v1.per_scenario["b"] == 0.0
    # A candidate that blows its range up does not get a larger scale to hide behind.
    huge = {"a": trace("a", fall() * 10, 0.2 * T), "b": REF["b"]}
    assert evaluate(spec, huge).total > v2.total
    assert float(residuals(spec, late) @ residuals(spec, late)) < float(residuals(spec, later) @ residuals(spec, later))


def test_unstable_and_nonfinite_candidates_get_a_large_penalty() -> None:
    spec = build_spec(REF, ["a", "b"])
    worst_finite = {"a": trace("a", -fall(), -0.2 * T), "b": trace("b", fall(), 0.1 * T)}
    early = {"a": trace("a", fall()[:5], 0.2 * T[:5], "unstable"), "b": REF["b"]}
    late = {"a": trace("a", fall()[:40], 0.2 * T[:40], "unstable"), "b": REF["b"]}
    assert evaluate(spec, early).total > evaluate(spec, late).total > evaluate(spec, worst_finite).total
    assert evaluate(spec, early).unstable == ("a",)
    nan = {"a": trace("a", np.full(T.size, np.nan), 0.2 * T), "b": REF["b"]}
    assert math.isfinite(evaluate(spec, nan).total) and evaluate(spec, nan).total > 0.5
    assert np.isfinite(residuals(spec, nan)).all()


def test_missing_crossing_counts_at_the_end_of_the_log() -> None:
    threshold = Threshold(0.99)
    ref, never = Series(T, fall()), Series(T, np.zeros(T.size))
    crossing = T[int(np.argmax(fall() >= 0.99))]
    assert event_difference(ref, never, threshold) == pytest.approx(T[-1] - crossing, abs=0.04)
    assert event_difference(never, never, threshold) == 0.0


def test_reference_problems_are_reported() -> None:
    with pytest.raises(DualtwinError, match="no scenarios"):
        build_spec(REF, ["a", "zz"])
    with pytest.raises(DualtwinError, match="not logged"):
        build_spec(REF, ["a"], ["wheel_vel"])
    unstable = {"a": trace("a", fall()[:3], 0.2 * T[:3], "unstable"), "b": REF["b"]}
    assert build_spec(unstable, ["a", "b"]).skipped == ("a",)


def test_pseudo_huber_is_quadratic_then_linear() -> None:
    assert pseudo_huber(0.01, 0.1) == pytest.approx(0.01**2 / 0.2, rel=0.01)
    assert pseudo_huber(10.0, 0.1) == pytest.approx(10.0 - 0.1, rel=0.01)
    assert ObjectiveWeights().term_weights()["rmse"] == 0.0


def test_a_term_of_weight_zero_is_not_computed_and_the_others_are_unchanged() -> None:
    """Every weighted term comes out as when all four are computed; the zero-weight ones are left out (DTW was
    most of a score's time on the arm's fit, whose weights leave it out)."""
    late = {"a": trace("a", fall(0.05), 0.21 * T), "b": trace("b", -fall(0.12), -0.1 * T)}
    every = evaluate(build_spec(REF, ["a", "b"], weights=ObjectiveWeights(dtw=1.0, event=1.0, endpoint=0.5, rmse=1.0)),
                     late)
    for zero in ("dtw", "event", "endpoint", "rmse"):
        weights = {"dtw": 1.0, "event": 1.0, "endpoint": 0.5, "rmse": 1.0, zero: 0.0}
        value = evaluate(build_spec(REF, ["a", "b"], weights=ObjectiveWeights(**weights)), late)
        assert value.per_term[zero] == 0.0
        assert {k: v for k, v in value.per_term.items() if k != zero} == {
            k: v for k, v in every.per_term.items() if k != zero}
    ref, cand = REF["a"].series["pole_angle_rad"], late["a"].series["pole_angle_rad"]
    assert set(channel_terms(ref, cand, 1.0, None, 1.5, {"rmse"})) == {"rmse"}
    assert channel_terms(ref, cand, 1.0, None, 1.5, {"rmse"})["rmse"] == channel_terms(ref, cand, 1.0, None, 1.5)["rmse"]


def _terms_through_resample_common(ref: Series, cand: Series, scale: float) -> dict[str, float]:
    """The terms as the general path computes them: both series cut and put on one grid by resample_common."""
    common = resample_common(*finite_prefix(ref.t, ref.y), *finite_prefix(cand.t, cand.y))
    return {"dtw": dtw_distance(common.a, common.b).rms / scale,
            "endpoint": abs(float(common.b[-1] - common.a[-1])) / scale, "rmse": rmse(common.a, common.b) / scale}


def test_the_reference_is_cut_once_and_a_candidate_on_its_grid_scores_as_through_resample_common() -> None:
    """A fit scores every candidate against one reference: its finite prefix is kept on the spec
    (``prepared``), and a candidate logged on the reference's own time stamps skips resample_common. Every
    term equals the general path's, bit for bit, on the same grid, on another grid, and with a NaN tail."""
    spec = build_spec(REF, ["a", "b"], weights=ObjectiveWeights(dtw=1.0, event=0.0, endpoint=0.5, rmse=1.0))
    assert spec.prepared is spec.prepared  # computed once
    assert set(spec.prepared) == {(s, c) for s in ("a", "b") for c in ("pole_angle_rad", "cart_pos_m")}
    ref = REF["a"].series["pole_angle_rad"]
    same_grid = Series(T.copy(), fall(0.05))  # equal time stamps, another array
    shifted = Series(T + 0.004, fall(0.05))  # another grid: interpolated
    nan_tail = Series(T.copy(), np.where(T > 1.0, np.nan, fall(0.05)))
    for cand in (same_grid, shifted, nan_tail):
        fast = channel_terms(ref, cand, 2.0, None, 1.5, {"dtw", "endpoint", "rmse"}, spec.prepared["a", "pole_angle_rad"])
        assert fast == channel_terms(ref, cand, 2.0, None, 1.5, {"dtw", "endpoint", "rmse"})
        assert fast == _terms_through_resample_common(ref, cand, 2.0)
    # a reference whose time stamps resample_common refuses still fails the candidate, prepared or not
    bad = Series(np.array([0.0, 0.1, 0.1, 0.2]), np.zeros(4))
    refused = channel_terms(bad, Series(bad.t.copy(), np.ones(4)), 1.0, None, 1.0, {"rmse", "endpoint"},
                            None)
    assert refused == {"rmse": 1.0, "endpoint": 1.0}

