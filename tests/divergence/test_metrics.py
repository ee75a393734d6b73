"""Divergence metrics on constructed series with known answers, and run comparison."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from dtaidistance import dtw as dtai

from dualtwin.divergence import (
    ChannelDivergence,
    ScoreWeights,
    Threshold,
    best_lag,
    compare_channel,
    compare_runs,
    crossing_time,
    dtw_distance,
    finite_prefix,
    load_run,
    load_tsv,
    pearson,
    regression,
    resample_common,
    rmse,
    runs,
)
from dualtwin.errors import DualtwinError
from tests.support.rundirs import cartpole_like

DT = 0.032
T = np.arange(0, 125) * DT  # 0 .. 3.968 s, one control period apart


def signal(t: np.ndarray) -> np.ndarray:
    """A non-periodic test signal: a chirp-like swing on a ramp, so lags and signs are unambiguous."""
    return np.sin(1.3 * t + 0.4 * t**2) + 0.3 * t


# --- resampling ---------------------------------------------------------------------------------


def test_identical_grids_pass_through_untouched() -> None:
    y = signal(T)
    common = resample_common(T, y, T, y * 2)
    assert np.array_equal(common.t, T)
    assert np.array_equal(common.a, y)
    assert np.array_equal(common.b, y * 2)


def test_resampling_between_rates_uses_finer_grid_on_overlap() -> None:
    t_fine = np.arange(0, 401) * 0.005  # 0 .. 2.0 s
    t_coarse = np.arange(0, 41) * 0.04 + 0.1  # 0.1 .. 1.7 s
    line = lambda t: 2.0 * t - 1.0  # noqa: E731 - linear interpolation is exact on a line
    common = resample_common(t_coarse, line(t_coarse), t_fine, line(t_fine))
    assert common.t[0] == pytest.approx(0.1) and common.t[-1] == pytest.approx(1.7)
    assert common.dt == pytest.approx(0.005)
    np.testing.assert_allclose(common.a, line(common.t), atol=1e-12)
    np.testing.assert_allclose(common.b, line(common.t), atol=1e-12)
    # The same signal at two rates has (almost) no divergence.
    assert rmse(common.a, common.b) < 1e-12


def test_shorter_log_is_compared_over_the_overlap() -> None:
    y = signal(T)
    common = resample_common(T, y, T[:50], y[:50])
    assert common.n == 50
    assert np.array_equal(common.b, y[:50])


def test_resampling_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="strictly increasing"):
        resample_common([0.0, 0.0, 1.0], [1, 2, 3], T, signal(T))
    with pytest.raises(ValueError, match="overlap"):
        resample_common(T, signal(T), T + 10.0, signal(T))


# --- identical, scaled, negated ------------------------------------------------------------------


def test_identical_series_give_zeros_and_correlation_one() -> None:
    y = signal(T)
    d = compare_channel(T, y, T, y.copy(), channel="x", threshold=1.0)
    assert d.mse == d.rmse == d.dtw == d.dtw_rms == d.max_abs_error == d.final_diff == 0.0
    assert d.correlation == pytest.approx(1.0)
    assert d.lag_s == 0.0
    assert d.slope == pytest.approx(1.0) and d.intercept == pytest.approx(0.0, abs=1e-12)
    assert not d.sign_inverted
    assert d.crossing_diff_s == 0.0
    assert d.score == pytest.approx(0.0, abs=1e-12)


def test_negated_series_is_flagged_as_sign_inversion() -> None:
    y = signal(T)
    d = compare_channel(T, y, T, -y)
    assert d.sign_inverted
    assert d.correlation == pytest.approx(-1.0)
    assert d.slope == pytest.approx(-1.0)
    assert d.lag_s == 0.0  # |r| is maximised, so the flip is not mistaken for a shift
    assert not compare_channel(T, y, T, 0.5 * y).sign_inverted


def test_scaled_series_slope_recovers_scale() -> None:
    y = signal(T)
    reg = regression(y, 1.7 * y + 0.25)
    assert reg.slope == pytest.approx(1.7)
    assert reg.intercept == pytest.approx(0.25)
    assert compare_channel(T, y, T, 1.7 * y).slope == pytest.approx(1.7)


def test_constant_series_are_handled() -> None:
    c = np.full(T.shape, 0.3)
    assert pearson(c, signal(T)) is None
    assert regression(c, signal(T)).slope is None
    same = compare_channel(T, c, T, c)
    assert same.correlation is None and same.score == 0.0
    offset = compare_channel(T, c, T, c + 0.1)
    assert offset.rmse == pytest.approx(0.1)
    assert 0.0 < offset.score <= 1.0
    json_ready = offset.to_dict()
    assert json_ready["correlation"] is None


# --- lag -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("shift_samples", [-7, -1, 3, 12])
def test_known_shift_is_recovered_as_lag(shift_samples: int) -> None:
    t = np.arange(0, 400) * DT
    delay = shift_samples * DT
    a = signal(t)
    b = signal(t - delay)  # B is A delayed by `delay`: positive when B lags
    lag = best_lag(a, b, DT, max_lag_s=1.0)
    assert abs(lag.lag_s - delay) <= DT
    assert lag.correlation is not None and lag.correlation > 0.99


def test_fractional_shift_is_refined_below_one_sample() -> None:
    t = np.arange(0, 400) * DT
    delay = 4.5 * DT
    lag = best_lag(signal(t), signal(t - delay), DT)
    assert abs(lag.lag_s - delay) < 0.5 * DT


def test_lag_is_limited_to_max_lag() -> None:
    t = np.arange(0, 400) * DT
    lag = best_lag(signal(t), signal(t - 1.0), DT, max_lag_s=0.2)
    assert abs(lag.lag_s) <= 0.2 + 1e-12


# --- DTW -----------------------------------------------------------------------------------------


def test_dtw_matches_dtaidistance_on_small_case() -> None:
    a = np.array([0.0, 1.0, 2.0, 1.0, 0.0, -1.0])
    b = np.array([0.0, 0.0, 1.0, 2.0, 1.0, 0.0])
    res = dtw_distance(a, b)
    assert res.distance == pytest.approx(dtai.distance(a, b, use_c=False))
    # Hand-checked: B is A delayed one sample, so the path only pays for the last pair (-1 vs 0).
    assert res.distance == pytest.approx(1.0)
    assert res.rms == pytest.approx(1.0 / math.sqrt(6))
    assert dtw_distance(a, b, window=1).distance == pytest.approx(dtai.distance(a, b, window=1, use_c=False))


def test_dtw_is_finite_when_diagonal_path_is_optimal() -> None:
    # Regression: dtaidistance's pruning returned inf here (DTW == Euclidean up to rounding).
    t_a, t_b = np.arange(0, 156) * DT, np.arange(0, 250) * 0.02
    line = lambda t: 0.2 * np.sin(0.8 * t) + 0.01 * t  # noqa: E731
    common = resample_common(t_a, line(t_a), t_b, line(t_b))
    res = dtw_distance(common.a, common.b)
    assert res.distance == pytest.approx(np.linalg.norm(common.a - common.b), rel=1e-9)


def test_dtw_is_smaller_than_euclidean_for_shifted_signal() -> None:
    t = np.arange(0, 200) * DT
    a, b = signal(t), signal(t - 5 * DT)
    res = dtw_distance(a, b)
    euclid = float(np.linalg.norm(a - b))
    assert res.distance < 0.5 * euclid
    assert res.rms <= rmse(a, b)


# --- crossings -----------------------------------------------------------------------------------


def test_crossing_times_on_cosh_curve_match_analytic() -> None:
    t = np.arange(0, 200) * DT
    a = 0.05 * np.cosh(1.5 * t)  # like a falling pole: crosses 0.99 rad at arccosh(19.8) / 1.5
    b = 0.05 * np.cosh(1.2 * t)
    expected_a = math.acosh(0.99 / 0.05) / 1.5
    expected_b = math.acosh(0.99 / 0.05) / 1.2
    assert crossing_time(t, a, 0.99) == pytest.approx(expected_a, abs=2e-3)
    assert crossing_time(t, -a, 0.99) == pytest.approx(expected_a, abs=2e-3)  # |y| handles a fall either way
    d = compare_channel(t, a, t, b, threshold=0.99)
    assert d.crossing_a_s == pytest.approx(expected_a, abs=2e-3)
    assert d.crossing_diff_s == pytest.approx(expected_b - expected_a, abs=4e-3)


def test_crossing_modes_and_edge_cases() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    y = np.array([0.0, 1.0, -3.0, 5.0])
    assert crossing_time(t, y, Threshold(2.0)) == pytest.approx(1.0 + 3.0 / 4.0)  # reaches -2 going 1 -> -3
    assert crossing_time(t, y, Threshold(2.0, "rising")) == pytest.approx(2.0 + 5.0 / 8.0)
    assert crossing_time(t, y, Threshold(-1.0, "falling")) == pytest.approx(1.5)
    assert crossing_time(t, y, 10.0) is None
    assert crossing_time(t, y + 20.0, 10.0) == 0.0
    d = compare_channel(t, y, t, np.zeros(4), threshold=2.0)
    assert d.crossing_b_s is None and d.crossing_diff_s is None
    assert d.score_terms["crossing"] == 1.0
    with pytest.raises(ValueError):
        Threshold(-1.0)


# --- score and serialisation ---------------------------------------------------------------------


def test_score_grows_with_divergence_and_respects_weights() -> None:
    y = signal(T)
    small = compare_channel(T, y, T, y + 0.01)
    large = compare_channel(T, y, T, y + 0.5)
    assert 0.0 < small.score < large.score <= 1.0
    only_rmse = ScoreWeights(rmse=1, dtw=0, max_abs=0, final=0, correlation=0, crossing=0)
    d = compare_channel(T, y, T, y + 0.5, weights=only_rmse)
    assert d.score == pytest.approx(d.rmse / d.scale)
    with pytest.raises(ValueError):
        ScoreWeights(rmse=-1)


def test_channel_divergence_round_trips_through_dict() -> None:
    d = compare_channel(T, signal(T), T, signal(T - 0.1), channel="pole_angle_rad", threshold=1.0)
    assert ChannelDivergence.from_dict(d.to_dict()) == d


def test_non_finite_tail_is_dropped() -> None:
    y = signal(T)
    blown = y.copy()
    blown[80:] = np.nan
    d = compare_channel(T, y, T, blown)
    assert d.n == 80 and d.rmse == 0.0


# --- runs ----------------------------------------------------------------------------------------


def test_load_tsv_reads_repr_floats_and_drops_truncated_tail(tmp_path: Path) -> None:
    path = tmp_path / "log.tsv"
    path.write_text(
        "time_s\tx\n0.0\t0.1\n0.032\t1e-17\n0.064\t0.30000000000000004\n0.096\t0.", encoding="utf-8"
    )
    header, data = load_tsv(path)
    assert header == ["time_s", "x"]
    assert data.shape == (4, 2)  # the last row parses, so it stays
    assert data[2, 1] == 0.30000000000000004
    path.write_text("time_s\tx\n0.0\t0.1\n0.032", encoding="utf-8")
    assert load_tsv(path)[1].shape == (1, 2)
    path.write_text("time_s\tx\n0.0\t0.1\n0.032\n0.064\t1\n", encoding="utf-8")
    with pytest.raises(ValueError, match=":3: expected 2 columns"):
        load_tsv(path)


def test_load_tsv_refuses_a_log_over_the_cap_before_reading(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A log is read whole into Python floats: one over runs.MAX_LOG_BYTES is one line naming the file and the limit
    (it was read whatever its size). The cap is set small here; the check reads it at call time."""
    path = tmp_path / "log.tsv"
    path.write_text("time_s\tx\n0.0\t0.1\n", encoding="utf-8")
    size = path.stat().st_size
    monkeypatch.setattr(runs, "MAX_LOG_BYTES", size)
    assert load_tsv(path)[1].shape == (1, 2)  # at the cap: read
    monkeypatch.setattr(runs, "MAX_LOG_BYTES", size - 1)
    with pytest.raises(DualtwinError) as err:
        load_tsv(path)
    assert str(err.value) == f"{path}: run log is {size} bytes; at most {size - 1} are read"


def test_compare_runs_matches_scenarios_and_channels(make_run: Callable[..., Path]) -> None:
    a = make_run("a", {"00_Step": cartpole_like(T), "01_Step": cartpole_like(T)}, twin="webots")
    b = make_run("b", {"00_Step": cartpole_like(T, delay=0.1), "01_Step": cartpole_like(T)}, twin="mujoco")
    run = load_run(a)
    assert run.twin == "webots" and [s.id for s in run.scenarios] == ["00_Step", "01_Step"]
    comp = compare_runs(a, b)
    assert [s.id for s in comp.scenarios] == ["00_Step", "01_Step"]
    first, second = comp.scenarios
    assert set(first.channels) == {"pole_angle_rad", "cart_pos_m", "wheel_vel_rad_s"}
    # Default threshold only on *_angle_rad channels.
    assert first.channels["pole_angle_rad"].threshold == Threshold(0.99)
    assert first.channels["cart_pos_m"].threshold is None
    assert first.channels["pole_angle_rad"].crossing_diff_s == pytest.approx(0.1, abs=3e-3)
    assert first.channels["wheel_vel_rad_s"].lag_s == pytest.approx(0.1, abs=DT)
    assert second.score == pytest.approx(0.0, abs=1e-12)
    assert comp.summary_score == pytest.approx(first.score / 2)
    # Ranked by significance (rmse / resolution): the identical scenario never ranks; shares sum to 1.
    ranked = comp.contributions()
    assert ranked and {c.scenario_id for c in ranked} == {"00_Step"}
    assert sum(c.share for c in ranked) == pytest.approx(1.0)
    assert ranked[0].contribution == first.channels[ranked[0].channel or ""].significance > 1
    custom = compare_runs(a, b, thresholds={"pole_angle_rad": None, "cart_pos_m": 0.1})
    assert custom.scenarios[0].channels["pole_angle_rad"].threshold is None
    assert custom.scenarios[0].channels["cart_pos_m"].threshold == Threshold(0.1)


def test_mismatched_scenarios_and_channels_list_both_sides(make_run: Callable[..., Path]) -> None:
    a = make_run("a", {"00_Step": cartpole_like(T), "01_Push": cartpole_like(T)})
    channels_b = {
        "pole_angle_rad": {"source": "ground_truth", "unit": "rad"},
        "cart_vel_m_s": {"source": "ground_truth", "unit": "m/s"},
    }
    data_b = {
        "00_Step": {"pole_angle_rad": (T, T), "cart_vel_m_s": (T, T)},
        "02_Drop": {"pole_angle_rad": (T, T)},
    }
    b = make_run("b", data_b, channels=channels_b)
    # Only what both runs have is compared; what one side lacks is listed with why (issue 15.2).
    comp = compare_runs(a, b)
    assert [s.id for s in comp.scenarios] == ["00_Step"] and comp.channel_names == ["pole_angle_rad"]
    assert set(comp.scenarios[0].channels) == {"pole_angle_rad"}
    assert sorted(comp.left_out["scenarios"]) == ["01_Push", "02_Drop"]
    assert comp.left_out["scenarios"]["01_Push"].startswith("only in A")
    assert sorted(comp.left_out["channels"]) == ["cart_pos_m", "cart_vel_m_s", "wheel_vel_rad_s"]
    assert comp.left_out["channels"]["cart_vel_m_s"].startswith("only in B")
    assert type(comp).from_dict(comp.to_dict()).left_out == comp.to_dict()["left_out"]
    # Nothing shared: one line naming both sides.
    c = make_run("c", {"00_Step": {"cart_vel_m_s": (T, T)}}, channels={"cart_vel_m_s": channels_b["cart_vel_m_s"]})
    with pytest.raises(ValueError) as err:
        compare_runs(a, c)
    msg = str(err.value)
    assert "\n" not in msg and "no channel in common" in msg and "['cart_vel_m_s']" in msg
    d = make_run("d", {"09_Other": cartpole_like(T)})
    with pytest.raises(ValueError, match=r"no scenario in common: A .* has \['00_Step', '01_Push'\]"):
        compare_runs(a, d)


def test_unstable_scenario_is_reported_not_crashed(make_run: Callable[..., Path]) -> None:
    short = {k: (t[:40], y[:40]) for k, (t, y) in cartpole_like(T).items()}
    a = make_run("a", {"00_Step": cartpole_like(T), "01_Push": cartpole_like(T), "02_Kick": cartpole_like(T)})
    b = make_run(
        "b",
        {"00_Step": cartpole_like(T), "01_Push": short, "02_Kick": cartpole_like(T)},
        statuses={"01_Push": "unstable", "02_Kick": "unstable"},
        skip_logs=("02_Kick",),
    )
    comp = compare_runs(a, b)
    _, push, kick = comp.scenarios
    assert push.unstable and push.status_b == "unstable"
    assert push.channels["cart_pos_m"].n == 40  # compared over the overlap
    assert push.score == 1.0 and push.note and "unstable in B only" in push.note
    assert kick.channels == {} and kick.score == 1.0
    assert kick.note and "no log" in kick.note
    assert comp.contributions()[0].channel is None


def test_missing_log_of_completed_scenario_is_an_error(make_run: Callable[..., Path]) -> None:
    a = make_run("a", {"00_Step": cartpole_like(T)})
    b = make_run("b", {"00_Step": cartpole_like(T)}, skip_logs=("00_Step",))
    with pytest.raises(ValueError, match="no log data"):
        compare_runs(a, b)


def test_manifest_tolerances_are_checked(make_run: Callable[..., Path]) -> None:
    tol = {"00_Step": {"cart_pos_m": {"rmse": 1e-6, "dtw_rms": 10.0}}}
    a = make_run("a", {"00_Step": cartpole_like(T)}, tolerances=tol)
    b = make_run("b", {"00_Step": cartpole_like(T, delay=0.2)})
    comp = compare_runs(a, b)
    (violation,) = comp.scenarios[0].tolerance_violations
    assert violation.channel == "cart_pos_m" and violation.metric == "rmse"
    assert not comp.within_tolerance
    bad = make_run("c", {"00_Step": cartpole_like(T)}, tolerances={"00_Step": {"cart_pos_m": {"rmsd": 1}}})
    with pytest.raises(ValueError, match="unknown metrics"):
        compare_runs(bad, b)


# --- the score judges against the channel's resolution (issue 28, item 2) ---------------------------


def test_score_of_an_unresolvable_difference_is_near_zero_with_a_control() -> None:
    """A difference of 1e-7 m on a channel resolved to 1 mm is no divergence, however unlike the shapes are."""
    t = np.linspace(0.0, 2.0, 201)
    a = 1e-7 * np.sin(3 * t)
    b = 1e-7 * np.sin(3 * t + 2.5)
    unresolved = compare_channel(t, a, t, b)
    resolved = compare_channel(t, a, t, b, resolution=1e-3)
    assert unresolved.score > 0.2  # the control: relative to its own tiny range the pair looks different
    assert resolved.score < 0.01
    assert resolved.rmse == unresolved.rmse  # the metrics themselves are unchanged


def test_two_flat_lines_within_resolution_have_no_shape_to_disagree_on() -> None:
    """Two flat velocity lines 60 µm/s apart (noise below 1 mm/s) show r < 0 but share their shape."""
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 2.0, 201)
    a = 0.04 + 1e-5 * rng.standard_normal(t.size)
    b = 0.03994 - 0.8 * (a - 0.04) + 2e-6 * rng.standard_normal(t.size)
    plain = compare_channel(t, a, t, b)
    judged = compare_channel(t, a, t, b, resolution=1e-3)
    assert plain.correlation is not None and plain.correlation < -0.5  # the control: r is negative
    assert plain.score > 0.2
    assert judged.score_terms["correlation"] == 0.0
    assert judged.score < 0.05


def test_a_resolvable_divergence_scores_as_before() -> None:
    """Where the range is far above the resolution, the resolution changes nothing."""
    t = np.linspace(0.0, 2.0, 201)
    a = 0.5 * np.sin(3 * t)
    b = 0.5 * np.sin(3 * t + 0.4)
    assert compare_channel(t, a, t, b, resolution=1e-3).score == pytest.approx(compare_channel(t, a, t, b).score)


def test_dtw_takes_read_only_arrays() -> None:
    """Arrays from a read-only source (Ray's object store hands them out so) are copied for dtaidistance's C code,
    which refuses a read-only buffer."""
    a, b = np.linspace(0.0, 1.0, 50), np.linspace(0.0, 1.1, 50)
    expected = dtw_distance(a, b)
    a.flags.writeable = False
    b.flags.writeable = False
    assert dtw_distance(a, b) == expected


def test_finite_prefix_stops_at_the_first_non_finite_time_or_value() -> None:
    t = np.arange(6, dtype=np.float64)
    y = np.array([0.0, 1.0, 2.0, np.nan, 4.0, 5.0])
    assert finite_prefix(t, y)[0].tolist() == [0.0, 1.0, 2.0]
    assert finite_prefix(np.array([0.0, np.inf, 2.0]), np.zeros(3))[1].tolist() == [0.0]
    assert finite_prefix(t, t)[0].tolist() == t.tolist()
    assert finite_prefix(np.zeros(0), np.zeros(0))[0].size == 0
    assert finite_prefix(np.array([np.nan]), np.array([1.0]))[0].size == 0
