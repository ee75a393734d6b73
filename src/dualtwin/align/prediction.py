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
:func:`dualtwin.sync.prediction_error` or the online monitor). Optimisers, checkpoints and resume,
uncertainty and outputs are those of :func:`dualtwin.align.align`: ``knobs.json``, ``dr_ranges.json``, the
patched model, ``align_record.json`` and a report (``report.html``: prediction error before and after).
Use it through ``align(..., objective="prediction")`` or :func:`align_prediction`.
"""

from __future__ import annotations

import html
import json
import math
import multiprocessing
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field

from dualtwin.align.dr import dr_document, ranges_from_intervals, ranges_from_population
from dualtwin.align.fit import (
    AlignConfig,
    AlignResult,
    GenerationInfo,
    Optimizer,
    _fit_cma,
    _fit_lsq,
    _patch_model,
    _Point,
    _Problem,
    _uncertainty,
    fit_records,
    sysid_status,
)
from dualtwin.align.knobs import KnobSpec, check_values, select_knobs, unit_from_values, values_from_unit
from dualtwin.align.simulate import DEFAULT_WORKERS, ExecutorKind
from dualtwin.artifacts import json_safe, package_versions, sha256_file, write_json, write_text
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
#: Horizons of the objective: 1 and 5 periods stay smooth in the knobs; 25 periods already cross impacts (a
#: pole landing on its stop) and make the residual as rough as an open-loop one.
OBJECTIVE_HORIZONS = (1, 5)


class PredictionAlignConfig(AlignConfig):
    """:class:`AlignConfig` plus the prediction objective's settings (resume requires them unchanged)."""

    objective: Literal["prediction"] = "prediction"
    horizons: list[int] = Field(default_factory=lambda: list(OBJECTIVE_HORIZONS))
    stride: int = Field(default=5, ge=1)
    scales: dict[str, float] = Field(default_factory=dict)
    reference_sha256: str = ""


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


class PredictionProblem(_Problem):
    """Unit-cube points -> prediction residuals; the training value is ``‖r‖²`` (what both optimisers minimise)."""

    def __init__(self, specs: Sequence[KnobSpec], job: PredictionJob, evaluator: PredictionEvaluator, budget: int,
                 regularization: float = 0.0) -> None:
        # The base class's simulation job, objective spec and evaluator are suite-run specific; only the parts
        # the optimisers use (specs, counting, the point cache, regularisation) are set up here.
        self.specs = list(specs)
        self.regularization = regularization
        self.u0 = np.array(unit_from_values(specs, {}))
        self.objective_scale = 0.0
        self.residual_scale = 0.0
        self.budget = budget
        self.evaluations = 0
        self._cache: dict[tuple[float, ...], _Point] = {}
        self.prediction_job = job
        self.prediction_evaluator = evaluator
        self.tables: dict[tuple[float, ...], dict[str, Any]] = {}

    def run(self, points: Sequence[Sequence[float]]) -> list[_Point]:
        points = [[min(1.0, max(0.0, float(x))) for x in p] for p in points]
        fresh = [p for i, p in enumerate(points) if tuple(p) not in self._cache and p not in points[:i]]
        results = self.prediction_evaluator.map([self.prediction_job.with_knobs(self.values(p)) for p in fresh])
        self.evaluations += len(fresh)
        for p, outcome in zip(fresh, results, strict=True):
            self._cache[tuple(p)] = self._score_residuals(list(p), outcome.residuals)
            self.tables[tuple(p)] = outcome.table
        return [self._cache[tuple(p)] for p in points]

    def run_values(self, values: Sequence[Mapping[str, float]]) -> list[float]:
        results = self.prediction_evaluator.map([self.prediction_job.with_knobs(v) for v in values])
        self.evaluations += len(values)
        return [float(r.residuals @ r.residuals) for r in results]

    def _score_residuals(self, u: list[float], r: np.ndarray) -> _Point:
        train = float(r @ r)
        if self.regularization:
            shift = np.asarray(u) - self.u0
            train += self.regularization * self.objective_scale * float(np.mean(shift ** 2))
            r = np.concatenate([r, math.sqrt(self.regularization * self.residual_scale / shift.size) * shift])
        return _Point(u, train, None, r)


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


def align_prediction(
    reference: str | Path,
    target_twin_name: str,
    robot: str | RobotBinding,
    suite_path: Path | None,
    knob_patterns: Sequence[str],
    out_dir: Path,
    *,
    optimizer: Optimizer = "cma",
    seed: int = 0,
    budget: int = 600,
    resume: bool = False,
    executor: ExecutorKind = "process",
    workers: int = 2,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    reference_knobs: Mapping[str, float] | None = None,
    horizons: Sequence[int] = OBJECTIVE_HORIZONS,
    stride: int = 5,
    scales: Mapping[str, float] | None = None,
    popsize: int | None = None,
    sigma0: float = 0.25,
    patience: int | None = None,
    fd_step: float = 0.03,
    regularization: float = 0.0,
    callback: Callable[[GenerationInfo], None] | None = None,
) -> AlignResult:
    """Fit the target twin's knobs with the prediction objective; same outputs as :func:`dualtwin.align.align`.

    Args:
        reference: A twin name (recorded over ``suite_path`` with ``reference_knobs``), a trajectory file, or
            a folder holding ``trajectories.npz`` (a lockstep or prediction-error run).
        target_twin_name: Twin whose knobs are fitted.
        robot: Robot name or binding.
        suite_path: Suite to record a twin reference on (may be None for a trajectory file).
        knob_patterns: Knob names or globs of the target twin.
        out_dir: Output folder (empty unless ``resume``).
        horizons: Prediction horizons in control periods.
        stride: A start state every ``stride`` periods of every reference trajectory.
        scales: Channel scale overrides (fnmatch patterns; ``inf`` ignores a channel).

    The other arguments mean what they mean for :func:`dualtwin.align.align`.
    """
    t_start = time.perf_counter()
    out = Path(out_dir)
    binding = resolve_robot(robot) if isinstance(robot, str) else robot
    if optimizer not in ("cma", "lsq"):
        raise DualtwinError(f"unknown optimizer {optimizer!r}; use 'cma' or 'lsq'")
    settings = PredictionSettings(tuple(int(h) for h in horizons), int(stride), dict(scales or {}))
    suite = Path(suite_path) if suite_path is not None else None
    config_path = out / "align_config.json"
    if not resume and out.exists() and any(out.iterdir()):
        raise DualtwinError(f"{out}: output folder is not empty; use resume to continue an alignment, "
                            "or choose another folder")
    out.mkdir(parents=True, exist_ok=True)
    ref_path, trajectories, kind = _reference_trajectories(reference, binding, suite, dict(reference_knobs or {}),
                                                           seed, out, resume)
    period = trajectories[0].period
    config = PredictionAlignConfig(
        reference=str(reference), reference_kind="twin" if kind == "twin" else "run",
        reference_knobs=dict(reference_knobs or {}), target=target_twin_name, robot=str(binding.path),
        suite=str(suite.resolve()) if suite is not None else "", knobs=list(knob_patterns),
        bounds={k: (float(v[0]), float(v[1])) for k, v in (bounds or {}).items()}, optimizer=optimizer, seed=seed,
        budget=budget, popsize=popsize, sigma0=sigma0, patience=patience, fd_step=fd_step,
        regularization=regularization, executor=executor, workers=workers, horizons=list(settings.horizons),
        stride=settings.stride, scales=dict(settings.scales), reference_sha256=sha256_file(ref_path))
    if resume and config_path.is_file() and read_json(config_path) != json.loads(config.model_dump_json()):
        raise DualtwinError(f"{config_path}: cannot resume: the configuration differs from the interrupted run")
    write_json(config_path, json.loads(config.model_dump_json()))

    target: Twin = make_twin(target_twin_name, binding, period)
    try:
        specs = select_knobs(target.knobs(), list(knob_patterns), config.bounds, where=f"twin {target_twin_name!r}")
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
    with PredictionEvaluator(executor, workers) as evaluator:
        problem = PredictionProblem(specs, job, evaluator, budget, regularization)
        nominal_u = unit_from_values(specs, {})
        before = problem.run([nominal_u])[0]
        problem.calibrate(before)
        fit = _fit_cma if optimizer == "cma" else _fit_lsq
        outcome = fit(problem, config, out, nominal_u, before.train, resume, callback)
        after = problem.run([outcome.u])[0]
        if after.train > before.train:
            outcome.u, after = nominal_u, before
            warnings.append("no knob setting beat the nominal twin; the fitted values are the nominal ones")
        uncertainty = _uncertainty(problem, outcome.u, fd_step)
        periods = evaluator.periods
    fitted = values_from_unit(specs, outcome.u)
    warnings += uncertainty.warnings
    knob_fits, bound_warnings = fit_records(specs, fitted, uncertainty.half_widths)
    warnings += bound_warnings
    files: dict[str, str] = {"config": "align_config.json", "reference": REFERENCE_FILE}
    write_json(out / "knobs.json", {"schema": "dualtwin.knobs/1", "twin": target_twin_name, "robot": binding.name,
                                    "optimizer": optimizer, "objective": "prediction", "values": fitted,
                                    "knobs": {n: k.to_dict() for n, k in knob_fits.items()}})
    files["knobs"] = "knobs.json"
    if optimizer == "cma" and outcome.population:
        ranges, source = ranges_from_population(specs, outcome.population, config.dr_top_fraction), "cma-population"
    else:
        ranges, source = ranges_from_intervals(specs, fitted, uncertainty.half_widths), "lsq-interval"
    write_json(out / "dr_ranges.json", dr_document(specs, fitted, ranges, source, config.dr_min_rel_width))
    files["dr_ranges"] = "dr_ranges.json"
    patch = _patch_model(binding, target_twin_name, fitted)
    if patch.text is not None:
        name = f"{binding.name}_aligned{'.xml' if target_twin_name == 'mujoco' else '.wbt'}"
        write_text(out / name, patch.text)
        files["model"] = name
    result = AlignResult(
        out_dir=out, optimizer=optimizer, knobs=knob_fits, objective_before=before.train,
        objective_after=after.train, holdout_before=None, holdout_after=None,
        residual_before=float(before.residual @ before.residual), residual_after=float(after.residual @ after.residual),
        evaluations=problem.evaluations, iterations=outcome.iterations, wall_time_s=0.0,
        stop_reason=outcome.stop_reason, warnings=warnings, condition_number=uncertainty.condition, files=files)
    table_before = problem.tables.get(tuple(nominal_u), {})
    table_after = problem.tables.get(tuple(outcome.u), table_before)
    if table_before and table_after:
        plot_prediction([("before", table_before), ("after", table_after)], out / "prediction.png")
        files["plot"] = "prediction.png"
    files["report"] = "report.html"
    write_text(out / "report.html", _report_html(result, table_before, table_after, config))
    result.wall_time_s = time.perf_counter() - t_start
    files["record"] = "align_record.json"
    write_json(out / "align_record.json", {
        "schema": "dualtwin.align/1", "objective": "prediction", "config": json.loads(config.model_dump_json()),
        "seed": seed, "versions": package_versions(),
        "inputs": {"reference": {"path": str(ref_path), "sha256": config.reference_sha256, "kind": kind},
                   "binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)},
                   "model": {"path": str(binding.model_path(target_twin_name)),
                             "sha256": sha256_file(binding.model_path(target_twin_name))}},
        "knob_specs": [s.to_dict() for s in specs],
        "result": {"knobs": {n: k.to_dict() for n, k in knob_fits.items()},
                   "objective_before": result.objective_before, "objective_after": result.objective_after,
                   "condition_number": None if result.condition_number is None
                   or not math.isfinite(result.condition_number) else result.condition_number,
                   "stop_reason": result.stop_reason, "warnings": warnings},
        "prediction": {"before": json_safe(table_before), "after": json_safe(table_after)},
        "evaluations": result.evaluations, "simulated_periods": periods, "iterations": result.iterations,
        "wall_time_s": result.wall_time_s, "trace": outcome.trace,
        "model_patch": {"applied": patch.applied, "not_applied": patch.not_applied, "note": patch.note},
        "sysid": sysid_status(), "files": files})
    return result



def _report_html(result: AlignResult, before: Mapping[str, Any], after: Mapping[str, Any],
                 config: PredictionAlignConfig) -> str:
    from dualtwin.reporting import html_table, img_html, page_head

    knobs = html_table(["knob", "nominal", "fitted", "± 95 %", "unit"],
                       [[n, f"{k.nominal:.5g}", f"{k.fitted:.5g}",
                         "–" if k.half_width_95 is None else f"{k.half_width_95:.2g}", k.unit]
                        for n, k in result.knobs.items()])
    horizons = [str(h) for h in config.horizons]
    pred = html_table(["horizon [periods]", "before", "after"],
                      [[h, before.get("by_horizon", {}).get(h, {}).get("normalized_rms"),
                        after.get("by_horizon", {}).get(h, {}).get("normalized_rms")] for h in horizons], left=())
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in result.warnings)
    image = ""
    if "plot" in result.files:
        image = img_html((result.out_dir / result.files["plot"]).read_bytes(), "prediction error")
    cond = "–" if result.condition_number is None else f"{result.condition_number:.4g}"
    return (f"{page_head('Prediction alignment')}<h1>Alignment with the prediction objective</h1>"
            f"<p>target <b>{html.escape(config.target)}</b>, reference <code>{html.escape(config.reference)}</code>, "
            f"optimizer {html.escape(result.optimizer)}: {html.escape(result.stop_reason)}; "
            f"{result.evaluations} evaluations; cond(JᵀJ) {cond}</p>"
            f"<p>objective (mean squared normalised prediction error): {result.objective_before:.4g} → "
            f"<b>{result.objective_after:.4g}</b></p>{knobs}"
            f"<h2>Normalised RMS prediction error</h2>{pred}{image}<ul>{warnings}</ul></body></html>")
