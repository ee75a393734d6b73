"""Divergence between twins: pure metrics, run loading and comparison, and reports.

State-level divergence lives here too: state-difference channels and their scales (:mod:`.channels`),
recorded trajectories with full states and commands (:mod:`.trajectories`) and the short-horizon
prediction error (:mod:`.prediction`). The lockstep runner, the drift monitor (:mod:`dualtwin.sync`) and the
prediction objective of :mod:`dualtwin.align` all build on them.

Typical use::

    from dualtwin.divergence import compare_runs, write_report

    comparison = compare_runs(Path("runs/webots"), Path("runs/mujoco"))
    write_report(comparison, Path("runs/compare"), "Webots", "MuJoCo")

`report` (matplotlib, rich) is imported lazily so metric users don't pay for it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dualtwin.divergence.comparison import (
    DEFAULT_ANGLE_THRESHOLD_RAD,
    Contribution,
    RunComparison,
    ScenarioComparison,
    ToleranceViolation,
    compare_runs,
    resolve_thresholds,
)
from dualtwin.divergence.floor import (
    ChannelFloor,
    FloorJudgement,
    ensemble_floor,
    floor_verdict,
    judge_against_floor,
    simulate_floor,
)
from dualtwin.divergence.metrics import (
    DEFAULT_MAX_LAG_S,
    DEFAULT_WEIGHTS,
    ChannelDivergence,
    CommonSeries,
    DtwResult,
    LagResult,
    Regression,
    ScoreWeights,
    Threshold,
    best_lag,
    compare_channel,
    crossing_time,
    default_resolution,
    dtw_distance,
    finite_prefix,
    is_sign_inverted,
    max_abs_error,
    mse,
    pearson,
    predictability_horizon,
    regression,
    resample_common,
    rmse,
    score_terms,
    significance,
    weighted_score,
)
from dualtwin.divergence.runs import ChannelInfo, Run, ScenarioEntry, Series, load_run, load_tsv

if TYPE_CHECKING:
    from dualtwin.divergence.report import plot_channel, plot_overlay, print_summary, write_report

_REPORT_NAMES = ("plot_channel", "plot_overlay", "print_summary", "write_report")


def __getattr__(name: str) -> Any:
    if name in _REPORT_NAMES:
        from dualtwin.divergence import report

        return getattr(report, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "DEFAULT_ANGLE_THRESHOLD_RAD",
    "DEFAULT_MAX_LAG_S",
    "DEFAULT_WEIGHTS",
    "ChannelDivergence",
    "ChannelFloor",
    "ChannelInfo",
    "CommonSeries",
    "Contribution",
    "DtwResult",
    "FloorJudgement",
    "LagResult",
    "Regression",
    "Run",
    "RunComparison",
    "ScenarioComparison",
    "ScenarioEntry",
    "ScoreWeights",
    "Series",
    "Threshold",
    "ToleranceViolation",
    "best_lag",
    "compare_channel",
    "compare_runs",
    "crossing_time",
    "default_resolution",
    "dtw_distance",
    "ensemble_floor",
    "finite_prefix",
    "floor_verdict",
    "is_sign_inverted",
    "judge_against_floor",
    "load_run",
    "load_tsv",
    "max_abs_error",
    "mse",
    "pearson",
    "plot_channel",
    "plot_overlay",
    "predictability_horizon",
    "print_summary",
    "regression",
    "resample_common",
    "resolve_thresholds",
    "rmse",
    "score_terms",
    "significance",
    "simulate_floor",
    "weighted_score",
    "write_report",
]
