"""The ``prediction`` objective: fit knobs so the target twin predicts a reference over short horizons.

Multiple shooting instead of one long open-loop run: the target twin is put into the reference's recorded
state at many start points (every ``stride`` periods) and driven with the recorded commands for each
horizon ``h`` (default 1 and 5 control periods); the residuals are its state minus the reference's,
scaled per channel (:mod:`dualtwin.divergence.channels`) and weighted so that ``‖r‖²`` is the mean squared
normalised prediction error (:mod:`dualtwin.divergence.prediction`). Short horizons keep the residual nearly linear in
the knobs and insensitive to chaos, so least squares sees a well-conditioned problem where an open-loop
trajectory objective sees a rough one.

The reference is a twin (run once over a suite, with ``reference_knobs``, recording full states), or a
trajectory file (``trajectories.npz`` written by :func:`dualtwin.sync.run_lockstep`,
:func:`dualtwin.divergence.prediction.prediction_error` or the online monitor). It is a peer of the trajectory objective:
:class:`PredictionProblem` implements the same problem protocol, so optimisers, checkpoints and resume,
uncertainty and outputs are the same (``knobs.json``, ``dr_ranges.json``, the patched model,
``align_record.json``) and its report (``report.html``) shows the prediction error before and after.
Use it through :func:`dualtwin.align.run_align` with ``AlignConfig(objective="prediction", ...)``.
"""

from __future__ import annotations

import math
import multiprocessing
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.align.config import AlignConfig
from dualtwin.align.core import CachedProblem, Evaluation, GenerationInfo, estimate_uncertainty
from dualtwin.align.dr import ranges_from_intervals, ranges_from_population
from dualtwin.align.knobs import KnobSpec, check_values, select_knobs, unit_from_values, values_from_unit
from dualtwin.align.optimize import fit_cma, fit_lsq
from dualtwin.align.report import prediction_report_html
from dualtwin.align.simulate import DEFAULT_WORKERS, ExecutorKind
from dualtwin.align.writers import (
    AlignResult,
    fit_records,
    prediction_record,
    write_dr_ranges,
    write_knobs,
    write_patched_model,
)
from dualtwin.artifacts import sha256_file, write_json, write_text
from dualtwin.divergence.channels import channel_scales
from dualtwin.divergence.prediction import PredictionSettings, plot_prediction, predict
from dualtwin.divergence.trajectories import (
    Trajectory,
    load_trajectories,
    record_trajectories,
    save_trajectories,
)
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding, load_binding, resolve_robot
from dualtwin.suite.loader import load_suite, read_json
from dualtwin.suite.runner import check_against_binding
from dualtwin.twins import TWINS, make_twin
from dualtwin.twins.base import Twin

REFERENCE_FILE = "reference_trajectories.npz"


@dataclass(frozen=True)
class PredictionJob:
    """Predict the reference with ``knobs`` on a twin (plain data: pickles cheaply into workers)."""

    robot: str
    twin: str
    period: float
    reference: str
    horizons: tuple[int, ...]
    stride: int
    scales: tuple[tuple[str, float], ...]
    seed: int = 0
    knobs: tuple[tuple[str, float], ...] = ()

    def with_knobs(self, values: Mapping[str, float]) -> PredictionJob:
        return PredictionJob(self.robot, self.twin, self.period, self.reference, self.horizons, self.stride,
                             self.scales, self.seed, tuple(sorted(values.items())))


@dataclass
class PredictionOutcome:
    residuals: np.ndarray
    table: dict[str, Any]
    periods: int


class _Session:
    def __init__(self, job: PredictionJob) -> None:
        self.robot = load_binding(Path(job.robot))
        self.twin = make_twin(job.twin, self.robot, job.period)
        self.trajectories, _ = load_trajectories(Path(job.reference))


_SESSIONS: dict[tuple[str, str, float, str], _Session] = {}


def run_job(job: PredictionJob) -> PredictionOutcome:
    """Worker entry point: one candidate's residuals (the twin and reference are built once per process)."""
    key = (job.robot, job.twin, job.period, job.reference)
    if key not in _SESSIONS:
        _SESSIONS[key] = _Session(job)
    session = _SESSIONS[key]
    session.twin.set_knobs(dict(job.knobs))
    settings = PredictionSettings(job.horizons, job.stride, dict(job.scales))
    samples = predict(session.twin, session.trajectories, settings, job.seed)
    scales = channel_scales(samples.channels, settings.scales)
    return PredictionOutcome(samples.residuals(scales), samples.table(scales), samples.steps)


class PredictionEvaluator:
    """Runs prediction jobs serially or in a process pool (forkserver, workers kept); counts evaluations."""

    def __init__(self, kind: ExecutorKind = "process", workers: int = DEFAULT_WORKERS) -> None:
        if kind not in ("serial", "process"):
            raise DualtwinError(f"the prediction objective runs 'serial' or 'process', not {kind!r}")
        self.kind = kind
        self.workers = workers
        self.evaluations = 0
        self.periods = 0
        self._pool: ProcessPoolExecutor | None = None

    def map(self, jobs: Sequence[PredictionJob]) -> list[PredictionOutcome]:
        jobs = list(jobs)
        self.evaluations += len(jobs)
        if self.kind == "serial" or self.workers == 1 or len(jobs) <= 1:
            results = [run_job(job) for job in jobs]
        else:
            if self._pool is None:
                context = multiprocessing.get_context("forkserver")
                context.set_forkserver_preload(["dualtwin.align.prediction"])
                self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context)
            chunk = max(1, math.ceil(len(jobs) / self.workers))
            results = list(self._pool.map(run_job, jobs, chunksize=chunk))
        self.periods += sum(r.periods for r in results)
        return results

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> PredictionEvaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PredictionProblem(CachedProblem):
    """Unit-cube points -> prediction residuals; the training value is ``‖r‖²`` (what both optimisers minimise).

    Each point keeps its prediction error table (``details``) for the report and the record.
    """

    def __init__(self, specs: Sequence[KnobSpec], job: PredictionJob, evaluator: PredictionEvaluator, budget: int,
                 regularization: float = 0.0) -> None:
        super().__init__(specs, budget, regularization)
        self.job = job
        self.evaluator = evaluator

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        results = self.evaluator.map([self.job.with_knobs(v) for v in values])
        return [Evaluation(float(r.residuals @ r.residuals), None, r.residuals, r.table) for r in results]


def _reference_trajectories(reference: str | Path, binding: RobotBinding, suite: Path | None,
                            reference_knobs: Mapping[str, float], seed: int, out_dir: Path,
                            resume: bool) -> tuple[Path, list[Trajectory], str]:
    """The reference as a trajectory file in ``out_dir`` (recorded on a twin, or copied from a file)."""
    target = out_dir / REFERENCE_FILE
    if resume and target.is_file():
        trajectories, _ = load_trajectories(target)
        return target, trajectories, "file"
    if str(reference) in TWINS and not Path(reference).exists():
        if suite is None:
            raise DualtwinError("a twin as the reference needs a suite to record it on")
        suite_obj = load_suite(suite)
        check_against_binding(suite_obj, suite, binding)
        twin = make_twin(str(reference), binding, suite_obj.global_settings.control_period_s)
        try:
            values = check_values(twin.knobs(), reference_knobs, f"reference twin {reference!r}")
            twin.set_knobs(values)
            trajectories = record_trajectories(twin, binding, suite_obj, seed=seed)
        finally:
            twin.close()
        save_trajectories(target, trajectories, {"twin": str(reference), "robot": binding.name,
                                                 "knobs": dict(reference_knobs), "seed": seed})
        return target, trajectories, "twin"
    path = Path(reference)
    if path.is_dir():
        path = path / "trajectories.npz"
    if reference_knobs:
        raise DualtwinError("reference_knobs apply only when the reference is a twin, not a recording")
    trajectories, meta = load_trajectories(path)
    save_trajectories(target, trajectories, meta)
    return target, trajectories, "file"


def run_prediction(config: AlignConfig, out_dir: Path, *, resume: bool = False,
                   callback: Callable[[GenerationInfo], None] | None = None) -> AlignResult:
    """Fit the target twin's knobs with the prediction objective; see :func:`dualtwin.align.run_align`.

    ``config.reference`` is a twin name (recorded over ``config.suite`` with ``reference_knobs``), a
    trajectory file, or a folder holding ``trajectories.npz`` (a lockstep or prediction-error run);
    ``config.suite`` may be empty for a trajectory file.
    """
    t_start = time.perf_counter()
    out = Path(out_dir)
    binding = resolve_robot(config.robot)
    optimizer, seed = config.optimizer, config.seed
    settings = PredictionSettings(tuple(int(h) for h in config.horizons), int(config.stride), dict(config.scales))
    suite = Path(config.suite) if config.suite else None
    config_path = out / "align_config.json"
    if not resume and out.exists() and any(out.iterdir()):
        raise DualtwinError(f"{out}: output folder is not empty; use resume to continue an alignment, "
                            "or choose another folder")
    out.mkdir(parents=True, exist_ok=True)
    ref_path, trajectories, kind = _reference_trajectories(config.reference, binding, suite,
                                                           dict(config.reference_knobs), seed, out, resume)
    period = trajectories[0].period
    config = config.model_copy(update={
        "reference_kind": "twin" if kind == "twin" else "run", "robot": str(binding.path),
        "suite": str(suite.resolve()) if suite is not None else "", "horizons": list(settings.horizons),
        "stride": settings.stride, "scales": dict(settings.scales), "reference_sha256": sha256_file(ref_path)})
    if resume and config_path.is_file() and read_json(config_path) != config.saved():
        raise DualtwinError(f"{config_path}: cannot resume: the configuration differs from the interrupted run")
    write_json(config_path, config.saved())

    target_twin_name = config.target
    target: Twin = make_twin(target_twin_name, binding, period)
    try:
        specs = select_knobs(target.knobs(), list(config.knobs), config.bounds, where=f"twin {target_twin_name!r}")
    finally:
        target.close()
    if optimizer == "lsq":
        integer = [s.name for s in specs if s.integer]
        if integer:
            raise DualtwinError(f"least squares needs continuous knobs; {', '.join(integer)} take integer values: "
                                "use optimizer 'cma'")
    job = PredictionJob(str(binding.path), target_twin_name, period, str(ref_path.resolve()), settings.horizons,
                        settings.stride, tuple(sorted(settings.scales.items())), seed)
    warnings: list[str] = []
    with PredictionEvaluator(config.executor, config.workers) as evaluator:
        problem = PredictionProblem(specs, job, evaluator, config.budget, config.regularization)
        nominal_u = unit_from_values(specs, {})
        before = problem.run([nominal_u])[0]
        problem.calibrate(before)
        fit = fit_cma if optimizer == "cma" else fit_lsq
        outcome = fit(problem, config, out, nominal_u, before.train, resume, callback)
        after = problem.run([outcome.u])[0]
        if after.train > before.train:
            outcome.u, after = nominal_u, before
            warnings.append("no knob setting beat the nominal twin; the fitted values are the nominal ones")
        uncertainty = estimate_uncertainty(problem, outcome.u, config.fd_step)
        periods = evaluator.periods
    fitted = values_from_unit(specs, outcome.u)
    warnings += uncertainty.warnings
    knob_fits, bound_warnings = fit_records(specs, fitted, uncertainty.half_widths)
    warnings += bound_warnings
    files: dict[str, str] = {"config": "align_config.json", "reference": REFERENCE_FILE}
    write_knobs(out, files, target_twin_name, binding.name, optimizer, fitted, knob_fits, objective="prediction")
    if optimizer == "cma" and outcome.population:
        ranges, source = ranges_from_population(specs, outcome.population, config.dr_top_fraction), "cma-population"
    else:
        ranges, source = ranges_from_intervals(specs, fitted, uncertainty.half_widths), "lsq-interval"
    write_dr_ranges(out, files, specs, fitted, ranges, source, config.dr_min_rel_width)
    patch = write_patched_model(out, files, binding, target_twin_name, fitted)
    result = AlignResult(
        out_dir=out, optimizer=optimizer, knobs=knob_fits, objective_before=before.train,
        objective_after=after.train, holdout_before=None, holdout_after=None,
        residual_before=float(before.residual @ before.residual), residual_after=float(after.residual @ after.residual),
        evaluations=problem.evaluations, iterations=outcome.iterations, wall_time_s=0.0,
        stop_reason=outcome.stop_reason, warnings=warnings, condition_number=uncertainty.condition, files=files)
    table_before = problem.details.get(tuple(nominal_u), {})
    table_after = problem.details.get(tuple(outcome.u), table_before)
    if table_before and table_after:
        plot_prediction([("before", table_before), ("after", table_after)], out / "prediction.png")
        files["plot"] = "prediction.png"
    files["report"] = "report.html"
    write_text(out / "report.html", prediction_report_html(result, table_before, table_after, config))
    files["record"] = "align_record.json"
    write_json(out / "align_record.json", prediction_record(config, result, outcome, patch, binding, ref_path, kind,
                                                            specs, table_before, table_after, periods))
    result.wall_time_s = time.perf_counter() - t_start  # printed only: no file of the run folder holds it
    return result
