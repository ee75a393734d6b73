"""Alignment: fit a twin's knobs so that its suite runs match a reference, with CMA-ES or least squares.

`align` runs the suite on the target twin for many knob settings and minimises the objective of
:mod:`dualtwin.align.objective` over the training scenarios. Held-out scenarios are simulated for every
candidate but never steer the search. They show whether the fit generalises.

* ``optimizer="cma"``: CMA-ES (`cma`) in the unit cube of the knobs' normalised ranges (log-scaled for
  wide positive ranges), seeded through a private random generator, with each population evaluated in
  parallel, with the best point so far injected into every population (elitist: a start that is
  already good is kept, not lost). After every generation ``checkpoint.json`` (the commit point) is written
  atomically with every generation's injected point, asked solutions and their objective values (JSON, no
  pickle). ``resume=True`` rebuilds a freshly seeded strategy and replays ``ask``/``tell`` on those records:
  the strategy's sampler is seeded, so the replay reproduces its state bit for bit (each replayed generation is
  checked against the recorded solutions), loses at most one generation, and continues exactly as an
  uninterrupted run would. Nothing in an output folder is ever unpickled, and no path is read from it.
  It stops on the evaluation budget, CMA's own tolerances (``tolfun``, ``tolx``), ``patience``
  generations without improvement, or an exact match.
* ``optimizer="lsq"``: ``mujoco.minimize.least_squares`` (bounded Levenberg-Marquardt with a
  finite-difference Jacobian whose perturbed points are simulated in parallel) on the residual vector.
  When it stops, the points four finite-difference steps away along each knob are tried, and the fit
  restarts from a better one (``lsq_restarts`` times at most). Integer knobs (delays, physics sub-steps)
  have no derivative: each is first set to its best value by simulating every integer in its bounds, then
  held while least squares fits the continuous knobs.
  ``mujoco.sysid`` is not used, even when it is installed: it computes residuals with ``mujoco.rollout``
  on the MJCF's own actuators, while our MuJoCo twin emulates Webots motors (a velocity servo with torque
  saturation, switched per physics step in Python), control delays and sensor models outside MuJoCo.
  sysid would fit a different system. We call sysid's own optimiser on residuals from the twin instead,
  and that works for any target twin.

The twin's dynamics hold discrete events (motor torque saturation switching at physics steps, joint
stops, contacts), so objective and residuals are rough below about 1e-3 of a knob's range. The
finite-difference step is therefore 3 % of the range, which steps over them. With it, least squares
recovers a pole damping exactly where a 1e-3 step stalls at 5 % error. CMA-ES only ranks candidates,
so the roughness merely sets the floor it stops at.

Both report the uncertainty from the Jacobian at the optimum: covariance ``s²(JᵀJ)⁻¹`` and 95 %
Student-t half-widths, with a conditioning check. Residuals of a trajectory are autocorrelated, so these
intervals are optimistic: read them as a lower bound on the uncertainty.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import cma
import numpy as np
from pydantic import Field
from rich.console import Console
from rich.markup import escape
from scipy import stats

from dualtwin.align import nuisance
from dualtwin.align.analyze import Analysis, analyze_runs
from dualtwin.align.dr import dr_document, ranges_from_intervals, ranges_from_population
from dualtwin.align.knobs import KnobSpec, check_values, select_knobs, unit_from_values, values_from_unit
from dualtwin.align.objective import (
    ObjectiveSpec,
    ObjectiveWeights,
    build_spec,
    evaluate,
    mean_trace,
    residuals,
)
from dualtwin.align.patch import PatchResult, patch_mjcf, patch_webots
from dualtwin.align.propose import ProposalOutcome, ProposeFn, try_proposals
from dualtwin.align.reference import ensemble_members_of, shared_with_reference
from dualtwin.align.simulate import (
    Evaluator,
    ExecutorKind,
    SimJob,
    Traces,
    check_executor,
    load_member_traces,
    load_traces,
)
from dualtwin.artifacts import (
    package_versions,
    remove_output_dir,
    sha256_file,
    write_json,
    write_text,
)
from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.robots.io import RobotIO
from dualtwin.suite.loader import load_suite, read_json
from dualtwin.suite.runner import SuiteRun, check_against_binding
from dualtwin.twins import TWINS, make_twin
from dualtwin.twins.base import Twin

ALIGN_SCHEMA = "dualtwin.align/1"
KNOBS_SCHEMA = "dualtwin.knobs/1"
Optimizer = Literal["cma", "lsq"]
#: cond(JᵀJ) above this (in normalised knob units) is reported as ill-conditioned.
ILL_CONDITIONED = 1e10
#: Held-out objective this much above its value before fitting counts as overfitting ...
OVERFIT_RATIO = 1.05
#: ... and so does ending this much above its best value during the fit.
OVERFIT_FROM_BEST = 1.25


class AlignConfig(FrozenModel):
    """Every input and setting of an alignment (saved as ``align_config.json``; resume requires it unchanged)."""

    reference: str
    reference_kind: Literal["run", "twin"]
    reference_knobs: dict[str, float] = Field(default_factory=dict)
    target: str
    robot: str
    suite: str
    knobs: list[str]
    bounds: dict[str, tuple[float, float]] = Field(default_factory=dict)
    channels: list[str] | None = None
    holdout: list[str] = Field(default_factory=list)
    thresholds: dict[str, float] | None = None
    optimizer: Optimizer = "cma"
    seed: int = 0
    budget: int = Field(default=600, ge=2, description="maximum number of suite simulations")
    popsize: int | None = Field(default=None, ge=2)
    sigma0: float = Field(default=0.25, gt=0, le=1, description="CMA initial step, in normalised units")
    tolfun: float = Field(default=1e-9, ge=0)
    tolx: float = Field(default=1e-4, ge=0, description="CMA step-size tolerance, normalised units")
    patience: int | None = Field(default=None, ge=1,
                                 description="CMA generations without improvement before stopping (max(15, 3n))")
    fd_step: float = Field(default=0.03, gt=0, lt=0.5, description="finite-difference step, normalised units")
    lsq_max_iter: int = Field(default=50, ge=1)
    lsq_restarts: int = Field(default=3, ge=0, description="restarts from a better neighbour after a stall")
    executor: ExecutorKind = "process"
    workers: int = Field(default=2, ge=1)
    ray_address: str | None = None
    weights: ObjectiveWeights = Field(default_factory=ObjectiveWeights)
    regularization: float = Field(default=0.0, ge=0, description="pull toward nominal, relative to the nominal mismatch")
    dr_top_fraction: float = Field(default=0.25, gt=0, le=1)
    dr_generations: int = Field(default=3, ge=1)
    dr_min_rel_width: float = Field(default=0.02, ge=0)
    ensemble: Literal["off", "mean"] = Field(
        default="off", description="mean: fit the ensemble mean of the reference run's members, the target "
        "simulated with the same initial-condition shifts")

    def digest(self) -> str:
        return hashlib.sha256(self.model_dump_json().encode()).hexdigest()


@dataclass(frozen=True)
class GenerationInfo:
    """Progress after one CMA generation or least-squares iteration (passed to ``callback``)."""

    iteration: int
    evaluations: int
    best_value: float
    best_knobs: dict[str, float]
    holdout_value: float | None
    sigma: float | None = None


@dataclass(frozen=True)
class KnobFit:
    """One knob's nominal and fitted value, its 95 % half-width (if known) and bound status."""

    name: str
    unit: str
    nominal: float
    fitted: float
    lower: float
    upper: float
    half_width_95: float | None = None
    at_bound: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"nominal": self.nominal, "fitted": self.fitted, "lower": self.lower, "upper": self.upper,
                "unit": self.unit, "half_width_95": self.half_width_95, "at_bound": self.at_bound}


@dataclass
class AlignResult:
    """What `align` did and where it wrote it."""

    out_dir: Path
    optimizer: str
    knobs: dict[str, KnobFit]
    objective_before: float
    objective_after: float
    holdout_before: float | None
    holdout_after: float | None
    residual_before: float
    residual_after: float
    evaluations: int
    iterations: int
    wall_time_s: float
    stop_reason: str
    warnings: list[str] = field(default_factory=list)
    condition_number: float | None = None
    files: dict[str, str] = field(default_factory=dict)
    proposals: list[ProposalOutcome] = field(default_factory=list)
    #: The LLM narrative (labelled as LLM output) when the proposer was an LLM; None otherwise.
    narrative: dict[str, Any] | None = None
    #: Fitted nuisance knobs (per-scenario initial conditions, time offsets): about the reference, not the
    #: model, so never in ``knobs``, ``fitted``, knobs.json, the patched model or the DR ranges.
    nuisance: dict[str, KnobFit] = field(default_factory=dict)
    #: Scenarios and channels of the suite or the reference that only one side has, with why (not fitted).
    left_out: dict[str, dict[str, str]] = field(default_factory=dict)

    @property
    def fitted(self) -> dict[str, float]:
        """Fitted physics values, ready for ``twin.set_knobs`` (nuisance knobs excluded)."""
        return {name: k.fitted for name, k in self.knobs.items()}


class _BudgetExhausted(Exception):
    """Raised inside the least-squares residual when the evaluation budget is spent."""


@dataclass
class _Point:
    u: list[float]
    train: float
    holdout: float | None
    residual: np.ndarray


class _Problem:
    """Unit-cube points -> simulations -> objective values and residuals, with evaluation counting."""

    def __init__(self, specs: Sequence[KnobSpec], job: SimJob, train: ObjectiveSpec, holdout: ObjectiveSpec | None,
                 evaluator: Evaluator, budget: int, regularization: float = 0.0,
                 members: Sequence[Mapping[str, float]] = ()) -> None:
        self.specs = list(specs)
        self.regularization = regularization
        self.u0 = np.array(unit_from_values(specs, {}))
        # The pull toward nominal is relative to the nominal mismatch, so λ means the same on any problem.
        self.objective_scale = 0.0
        self.residual_scale = 0.0
        self.job = job
        # Ensemble members' initial-condition shifts: each point is simulated once per member and scored by
        # the members' mean trace (see objective.mean_trace); empty for a single trajectory.
        self.members = [dict(m) for m in members]
        self.train = train
        self.holdout = holdout
        self.evaluator = evaluator
        self.budget = budget
        self.evaluations = 0
        # Simulations are deterministic: a point seen before (an injected incumbent) costs nothing.
        self._cache: dict[tuple[float, ...], _Point] = {}

    def calibrate(self, nominal: _Point) -> None:
        """Fix the regularization scales from the nominal twin's objective and residuals."""
        self.objective_scale = nominal.train
        self.residual_scale = float(nominal.residual @ nominal.residual)

    def values(self, u: Sequence[float]) -> dict[str, float]:
        return values_from_unit(self.specs, u)

    def point_state(self, u: Sequence[float]) -> dict[str, Any] | None:
        """A cached point as JSON (for checkpoints), or None if it was never simulated."""
        point = self._cache.get(tuple(u))
        if point is None:
            return None
        return {"u": point.u, "train": point.train, "holdout": point.holdout, "residual": point.residual.tolist()}

    def restore_point(self, state: Mapping[str, Any]) -> None:
        """Put a checkpointed point back into the cache, so a resumed run simulates exactly what the original would."""
        u = [float(x) for x in state["u"]]
        self._cache[tuple(u)] = _Point(u, float(state["train"]), state["holdout"], np.asarray(state["residual"], float))

    def run(self, points: Sequence[Sequence[float]]) -> list[_Point]:
        points = [[min(1.0, max(0.0, float(x))) for x in p] for p in points]
        fresh = [p for i, p in enumerate(points) if tuple(p) not in self._cache and p not in points[:i]]
        results = self._simulate([self.values(p) for p in fresh])
        self.evaluations += len(fresh)
        for p, r in zip(fresh, results, strict=True):
            self._cache[tuple(p)] = self._score(list(p), r)
        return [self._cache[tuple(p)] for p in points]

    def run_values(self, values: Sequence[Mapping[str, float]]) -> list[float]:
        """Train objective of explicit knob settings (for proposals)."""
        results = self._simulate(list(values))
        self.evaluations += len(values)
        return [evaluate(self.train, r).total for r in results]

    def _simulate(self, values: Sequence[Mapping[str, float]]) -> list[Traces]:
        """Traces per knob setting: one simulation, or the ensemble mean of one simulation per member."""
        if not self.members:
            return self.evaluator.map([self.job.with_knobs(v) for v in values])
        n = len(self.members)
        runs = self.evaluator.map([self.job.with_knobs(v).with_offsets(m) for v in values for m in self.members])
        out: list[Traces] = []
        for i in range(len(values)):
            group = runs[i * n:(i + 1) * n]
            out.append({sid: mean_trace([g[sid] for g in group]) for sid in group[0]})
        return out

    def _score(self, u: list[float], traces: Traces) -> _Point:
        train = evaluate(self.train, traces).total
        holdout = evaluate(self.holdout, traces).total if self.holdout is not None else None
        r = residuals(self.train, traces)
        if self.regularization:
            # Ridge toward nominal in normalised units: data must pay for every move away from the model.
            shift = np.asarray(u) - self.u0
            train += self.regularization * self.objective_scale * float(np.mean(shift ** 2))
            r = np.concatenate([r, math.sqrt(self.regularization * self.residual_scale / shift.size) * shift])
        return _Point(u, train, holdout, r)


@dataclass
class _Outcome:
    u: list[float]
    iterations: int
    stop_reason: str
    trace: list[dict[str, Any]]
    population: list[tuple[list[float], float]] = field(default_factory=list)


class _Randn:
    """CMA's normal sampler on a private generator: a fresh strategy with the same seed replays exactly."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, *shape: int) -> np.ndarray:
        return self.rng.standard_normal(shape)


# ------------------------------------------------------------------ CMA-ES
def _cma_stop(es: Any, problem: _Problem, config: AlignConfig, stale: int, best: float) -> str | None:
    if problem.evaluations + es.popsize > config.budget:
        return f"budget ({problem.evaluations} of {config.budget} evaluations used)"
    if best <= 1e-12:
        return "exact match"
    # More knobs need more generations before a stall means anything.
    patience = config.patience or max(15, 3 * len(problem.specs))
    if stale >= patience:
        return f"no improvement in {stale} generations"
    # tolfunhist watches the best value per generation, which the injected incumbent keeps flat while the
    # population still searches; `patience` is the stall rule instead.
    stop = {k: v for k, v in es.stop().items() if k not in ("maxfevals", "tolfunhist")}
    if stop:
        return "cma: " + ", ".join(f"{k}={v}" for k, v in stop.items())
    return None


def _fit_cma(problem: _Problem, config: AlignConfig, out_dir: Path, x0: Sequence[float], f0: float, resume: bool,
             callback: Callable[[GenerationInfo], None] | None) -> _Outcome:
    checkpoint = out_dir / "checkpoint.json"
    if resume and checkpoint.is_file():
        state = read_json(checkpoint)
        if not isinstance(state, dict) or state.get("config") != config.digest():
            raise DualtwinError(f"{checkpoint}: cannot resume: written by a different configuration")
        es, x0, generations = _replay_cma(checkpoint, state, config)
        try:
            problem.evaluations = int(state["evaluations"])
            trace: list[dict[str, Any]] = list(state["trace"])
            archive: list[list[tuple[list[float], float]]] = [[(list(u), float(f)) for u, f in gen]
                                                              for gen in state["archive"]]
            best_u, best_f, stale = list(state["best_u"]), float(state["best_value"]), int(state["stale"])
            if state.get("incumbent"):
                problem.restore_point(state["incumbent"])
        except (KeyError, TypeError, ValueError) as exc:
            raise DualtwinError(f"{checkpoint}: damaged CMA checkpoint ({type(exc).__name__}: {exc})") from None
    else:
        integer = [i for i, spec in enumerate(problem.specs) if spec.integer]
        if integer:
            screened = problem.run([_screen_integers(problem, x0, integer, config.budget, lambda p: p.train)])[0]
            if screened.train < f0:
                x0, f0 = screened.u, screened.train
        es = _new_cma(list(x0), config)
        generations = []
        trace, archive = [], []
        # The start point (nominal, the best kept proposal, or the best integer setting) is the one to beat.
        best_u, best_f, stale = list(x0), f0, 0
    while True:
        reason = _cma_stop(es, problem, config, stale, best_f)
        if reason:
            break
        # Elitist injection: the incumbent (at first the start point) joins every population, so when the
        # start is already good the search contracts around it instead of drifting off with a worse mean.
        injected = list(best_u)
        _cma_inject(es, injected)
        candidates = es.ask()
        points = problem.run([list(map(float, x)) for x in candidates])
        es.tell(candidates, [p.train for p in points])
        generations.append({"inject": injected, "asked": [[float(v) for v in x] for x in candidates],
                            "fitness": [p.train for p in points]})
        gen_best = min(points, key=lambda p: p.train)
        if not math.isfinite(best_f) or gen_best.train < best_f - 1e-12 * max(1.0, abs(best_f)):
            best_u, best_f, stale = gen_best.u, gen_best.train, 0
        else:
            stale += 1
        archive = [*archive, [(p.u, p.train) for p in points]][-config.dr_generations:]
        holdout = next((p.holdout for p in points if p.u == best_u), None)
        if holdout is None and trace:
            holdout = trace[-1].get("holdout_of_best")
        trace.append({"iteration": int(es.countiter), "evaluations": problem.evaluations,
                      "best_in_generation": gen_best.train, "best": best_f, "holdout_of_best": holdout,
                      "sigma": float(es.sigma), "mean": problem.values(list(es.mean))})
        _write_cma_checkpoint(out_dir, config, es, problem, trace, archive, best_u, best_f, stale, x0, generations)
        if callback is not None:
            callback(GenerationInfo(int(es.countiter), problem.evaluations, best_f, problem.values(best_u),
                                    holdout, float(es.sigma)))
    # The distribution mean is often better than any sample once the search has converged.
    if problem.evaluations < config.budget:
        mean = problem.run([list(map(float, es.mean))])[0]
        if mean.train < best_f:
            best_u, best_f = mean.u, mean.train
    population = [p for gen in archive for p in gen]
    return _Outcome(best_u, int(es.countiter), reason, trace, population)


#: CMA-ES checkpoints record the ask/tell history (JSON); version 1 named a pickled strategy, never loaded now.
CMA_CHECKPOINT_SCHEMA = "dualtwin.align.checkpoint/2"


def _new_cma(x0: list[float], config: AlignConfig) -> Any:
    opts: dict[str, Any] = {"bounds": [0.0, 1.0], "randn": _Randn(config.seed), "tolfun": config.tolfun,
                            "tolx": config.tolx, "verbose": -9, "verb_log": 0, "verb_disp": 0}
    if config.popsize:
        opts["popsize"] = config.popsize
    return cma.CMAEvolutionStrategy(x0, config.sigma0, opts)


def _cma_inject(es: Any, u: list[float]) -> None:
    es.inject([es.boundary_handler.inverse(np.asarray(u))] if es.boundary_handler is not None
              else [np.asarray(u)], force=True)


def confined_path(folder: Path, value: Any, where: str) -> Path:
    """``folder / value`` if that stays inside ``folder``; else a :class:`DualtwinError` naming ``where``."""
    if not isinstance(value, str) or not value:
        raise DualtwinError(f"{where}: expected a file name inside {folder}, got {value!r}")
    root = folder.resolve()
    path = (root / value).resolve()
    if not path.is_relative_to(root):
        raise DualtwinError(f"{where}: {value!r} points outside the output folder {folder}; refused")
    return path


def _replay_cma(checkpoint: Path, state: dict[str, Any], config: AlignConfig
                ) -> tuple[Any, list[float], list[dict[str, Any]]]:
    """A fresh strategy brought to the checkpoint's generation by replaying its recorded ask/tell history.

    Returns the strategy, the start point and the history (to be extended by the resumed run).
    """
    # Any path named in a checkpoint is confined to its folder, whatever it is used for.
    for key, value in state.items():
        if key.endswith("_file"):
            confined_path(checkpoint.parent, value, f"{checkpoint}: {key}")
    if state.get("schema") != CMA_CHECKPOINT_SCHEMA:
        raise DualtwinError(f"{checkpoint}: checkpoint format {state.get('schema')!r} (a pickled CMA state) is not "
                            "resumable: pickles from a run folder are never loaded; start the alignment again in a new "
                            "folder")
    try:
        x0 = [float(v) for v in state["x0"]]
        history = [([float(v) for v in g["inject"]], [[float(v) for v in x] for x in g["asked"]],
                    [float(f) for f in g["fitness"]]) for g in state["generations"]]
        iteration = int(state["iteration"])
    except (KeyError, TypeError, ValueError) as exc:
        raise DualtwinError(f"{checkpoint}: damaged CMA checkpoint ({type(exc).__name__}: {exc})") from None
    es = _new_cma(x0, config)
    for n, (injected, asked, fitness) in enumerate(history, start=1):
        es.stop()  # as in the original loop (the stop test runs before every generation)
        _cma_inject(es, injected)
        candidates = es.ask()
        if len(candidates) != len(asked) or not np.array_equal(np.asarray(candidates, float), np.asarray(asked)):
            raise DualtwinError(f"{checkpoint}: generation {n} does not replay to the recorded solutions (a "
                                "different cma version?); start the alignment again in a new folder")
        es.tell(candidates, fitness)
    if es.countiter != iteration:
        raise DualtwinError(f"{checkpoint}: the CMA history ({es.countiter} generations) does not match the "
                            f"checkpoint's iteration {iteration}")
    return es, x0, [{"inject": i, "asked": a, "fitness": f} for i, a, f in history]


def _write_cma_checkpoint(out_dir: Path, config: AlignConfig, es: Any, problem: _Problem,
                          trace: list[dict[str, Any]], archive: list[list[tuple[list[float], float]]],
                          best_u: list[float], best_f: float, stale: int, x0: Sequence[float],
                          generations: list[dict[str, Any]]) -> None:
    write_json(out_dir / "checkpoint.json", {
        "schema": CMA_CHECKPOINT_SCHEMA, "config": config.digest(), "optimizer": "cma",
        "iteration": int(es.countiter), "x0": list(x0), "generations": generations,
        "evaluations": problem.evaluations, "best_u": best_u, "best_value": best_f, "stale": stale,
        "incumbent": problem.point_state(best_u), "trace": trace, "archive": [[[u, f] for u, f in gen] for gen in archive],
    })


# ------------------------------------------------------------------ least squares
#: Rounds of re-screening integer knobs at the fitted continuous values (least squares only).
LSQ_INTEGER_ROUNDS = 2


def _fit_lsq(problem: _Problem, config: AlignConfig, out_dir: Path, x0: Sequence[float], f0: float, resume: bool,
             callback: Callable[[GenerationInfo], None] | None) -> _Outcome:
    minimize = _mujoco_module("minimize")
    checkpoint = out_dir / "checkpoint.json"
    trace: list[dict[str, Any]] = []
    start = list(x0)
    if resume and checkpoint.is_file():
        state = read_json(checkpoint)
        if state.get("config") != config.digest():
            raise DualtwinError(f"{checkpoint}: cannot resume: written by a different configuration")
        # Levenberg-Marquardt keeps little state: restarting from the last iterate loses only its damping.
        start, trace = list(state["u"]), list(state["trace"])
        problem.evaluations = int(state["evaluations"])
    seen: dict[tuple[float, ...], _Point] = {}
    offset = len(trace)
    integer = [i for i, s in enumerate(problem.specs) if s.integer]
    free = [i for i in range(len(problem.specs)) if i not in integer]
    if integer and not trace:
        start = _screen_integers(problem, start, integer, config.budget, _residual_norm)
    held = list(start)

    def expand(x: Sequence[float] | np.ndarray) -> list[float]:
        """The full unit vector: least squares moves the continuous knobs, integer ones stay as screened."""
        full = list(held)
        for j, i in enumerate(free):
            full[i] = min(1.0, max(0.0, float(x[j])))
        return full

    def residual(x: np.ndarray) -> np.ndarray:
        columns = [expand(x[:, j]) for j in range(x.shape[1])]
        if problem.evaluations + len(columns) > config.budget:
            raise _BudgetExhausted
        points = problem.run(columns)
        for p in points:
            seen[tuple(p.u)] = p
        return np.stack([p.residual for p in points], axis=1).astype(np.float64)

    def on_iteration(logs: list[Any]) -> None:
        u = expand(np.asarray(logs[-1].candidate).ravel())
        point = seen.get(tuple(u))
        entry: dict[str, Any] = {"iteration": offset + len(logs), "evaluations": problem.evaluations,
                 "best": point.train if point else None, "lsq_objective": float(logs[-1].objective),
                 "holdout_of_best": point.holdout if point else None, "knobs": problem.values(u)}
        trace.append(entry)
        write_json(checkpoint, {"schema": "dualtwin.align.checkpoint/1", "config": config.digest(),
                                "optimizer": "lsq", "iteration": entry["iteration"], "u": u,
                                "evaluations": problem.evaluations, "trace": trace})
        if callback is not None:
            callback(GenerationInfo(entry["iteration"], problem.evaluations, float(point.train if point else math.nan),
                                    problem.values(u), point.holdout if point else None))

    def fit_continuous(u: list[float]) -> tuple[list[float], str, int, bool]:
        """Least squares with restarts from a better neighbour; (u, reason, restarts, budget exhausted)."""
        nonlocal offset
        held[:] = u
        reason, restarts = "done", 0
        for attempt in range(config.lsq_restarts + 1):
            offset = len(trace)
            output = io.StringIO()
            try:
                x, _ = minimize.least_squares(np.asarray([u[i] for i in free], dtype=np.float64), residual,
                                              bounds=[np.zeros(len(free)), np.ones(len(free))], eps=config.fd_step,
                                              # Every rejected step costs a suite simulation: raise the damping
                                              # 3x per rejection (not 1.26x) and give up at 1e6 (not 1e8).
                                              mu_factor=10 ** 0.5, mu_max=1e6,
                                              max_iter=config.lsq_max_iter, verbose=1, output=output,
                                              iter_callback=on_iteration)
                u = expand(np.asarray(x).ravel())
                final = [line for line in output.getvalue().splitlines() if line.startswith("Terminated after")]
                reason = final[-1].split(": ", 1)[-1].split(" y:")[0] if final else "done"
            except _BudgetExhausted:
                best = min(seen.values(), key=_residual_norm, default=None)
                u = best.u if best is not None else u
                return u, f"budget ({problem.evaluations} of {config.budget} evaluations used)", restarts, True
            # Rough residuals (impacts sampled once per control period) can trap a Gauss-Newton step in a dent:
            # probe a few finite-difference steps away and restart from a better point if there is one.
            kick = 4 * config.fd_step
            probes = [p for i in free for p in (
                [*u[:i], min(1.0, u[i] + kick), *u[i + 1:]], [*u[:i], max(0.0, u[i] - kick), *u[i + 1:]]) if p != u]
            if attempt == config.lsq_restarts or not probes or problem.evaluations + len(probes) + 1 > config.budget:
                break
            here = seen.get(tuple(u)) or problem.run([u])[0]
            scored = problem.run(probes)
            for p in scored:
                seen[tuple(p.u)] = p
            better = min(scored, key=_residual_norm)
            if _residual_norm(better) >= _residual_norm(here) * (1 - 1e-9):
                break
            u = better.u
            restarts += 1
        return u, reason, restarts, False

    u = list(start)
    if not free:
        return _Outcome(u, 0, "integer knobs screened; no continuous knob to fit", trace)
    u, reason, restarts, spent = fit_continuous(u)
    # Integer and continuous knobs can stand in for each other (a coarser step for less damping): screen the
    # integers again at the fitted values and refit until they settle.
    for _ in range(LSQ_INTEGER_ROUNDS):
        if not integer or spent:
            break
        again = _screen_integers(problem, u, integer, config.budget, _residual_norm)
        if again == u:
            break
        u, reason, more, spent = fit_continuous(again)
        restarts += more
    if restarts:
        reason += f" (after {restarts} restart{'s' if restarts > 1 else ''} from a better neighbour)"
    iterations = len(trace)
    return _Outcome(u, iterations, reason, trace)


def _screen_integers(problem: _Problem, u: Sequence[float], integer: Sequence[int], budget: int,
                     criterion: Callable[[_Point], float]) -> list[float]:
    """Set each integer knob to its best value by ``criterion``, trying every integer with the others held.

    An integer knob's effect does not change smoothly (least squares cannot follow it, and CMA-ES's rounded
    steps rarely cross a rough landscape to a distant value). Its values are few, so they are all simulated
    (in parallel) and the optimiser starts from the best.
    """
    u = list(u)
    for i in integer:
        _, points = _integer_sweep(problem, u, i)
        if problem.evaluations + len(points) > budget:
            break
        scored = problem.run([u, *points])
        u = min(scored, key=criterion).u
    return u


def _residual_norm(p: _Point) -> float:
    return float(p.residual @ p.residual)


def _integer_sweep(problem: _Problem, u: Sequence[float], i: int) -> tuple[list[int], list[list[float]]]:
    """Every integer value of knob ``i`` within its bounds, and ``u`` with knob ``i`` set to each of them."""
    spec = problem.specs[i]
    values = list(range(math.ceil(spec.lower), math.floor(spec.upper) + 1))
    return values, [[*u[:i], spec.to_unit(v), *u[i + 1:]] for v in values]


# ------------------------------------------------------------------ uncertainty
@dataclass
class _Uncertainty:
    half_widths: dict[str, float | None]
    condition: float | None
    warnings: list[str]


def _uncertainty(problem: _Problem, u: Sequence[float], step: float) -> _Uncertainty:
    """Jacobian of the residuals at ``u`` (continuous knobs), covariance s²(JᵀJ)⁻¹ and 95 % half-widths."""
    specs = problem.specs
    cont = [i for i, s in enumerate(specs) if not s.integer]
    half: dict[str, float | None] = {s.name: None for s in specs}
    for i, spec in enumerate(specs):
        if spec.integer:
            half[spec.name] = _integer_half_width(problem, u, i)
    if not cont:
        return _Uncertainty(half, None, [])
    points = [list(u)]
    for i in cont:
        p = list(u)
        p[i] = u[i] - step if u[i] + step > 1.0 else u[i] + step
        points.append(p)
    results = problem.run(points)
    r0 = results[0].residual
    jac = np.stack([(res.residual - r0) / (p[i] - u[i]) for res, p, i in zip(results[1:], points[1:], cont,
                                                                          strict=True)], axis=1)
    return interval_estimate(jac, r0, [specs[i] for i in cont], [u[i] for i in cont], half)


def _integer_half_width(problem: _Problem, u: Sequence[float], i: int) -> float:
    """95 % half-width of an integer knob from its residuals at every integer, the other knobs held.

    An integer knob has no Jacobian column. Its interval holds the values whose residual sum of squares stays
    within the one-parameter likelihood-ratio bound ``SSR <= SSR_min (1 + t²/dof)``, the same 95 % level as the
    continuous knobs' intervals (conditional on the others, so it is, if anything, narrow).
    """
    values, points = _integer_sweep(problem, u, i)
    results = problem.run(points)  # cached when the last screening ran at this point
    ssr = [float(r.residual @ r.residual) for r in results]
    dof = max(len(results[0].residual) - len(problem.specs), 1)
    limit = min(ssr) * (1.0 + float(stats.t.ppf(0.975, dof)) ** 2 / dof)
    fitted = problem.specs[i].from_unit(u[i])
    return float(max(abs(v - fitted) for v, s in zip(values, ssr, strict=True) if s <= limit))


def interval_estimate(jac: np.ndarray, r0: np.ndarray, specs: Sequence[KnobSpec], u: Sequence[float],
                      half: dict[str, float | None] | None = None) -> _Uncertainty:
    """Covariance ``s²(JᵀJ)⁻¹`` in unit coordinates, 95 % Student-t half-widths in knob units, conditioning.

    Knobs whose Jacobian column vanishes are unidentifiable (no half-width). Trade-offs are named by the
    cosine between Jacobian columns, which stays meaningful when JᵀJ is singular.
    """
    half = dict(half or {s.name: None for s in specs})
    warnings: list[str] = []
    m, k = jac.shape
    norms = np.linalg.norm(jac, axis=0)
    live = [j for j in range(k) if norms[j] > 1e-12 * max(float(norms.max()), 1e-300)]
    for j in range(k):
        if j not in live:
            warnings.append(f"{specs[j].name} has no measurable effect on the fitted channels at its fitted value: "
                            "it cannot be identified from this suite (add a scenario that excites it, or drop it)")
    if not live:
        return _Uncertainty(half, math.inf, warnings)
    sub = jac[:, live]
    jtj = sub.T @ sub
    eig, vec = np.linalg.eigh(jtj)
    top = float(eig.max())
    small = eig <= top * 1e-12
    condition = math.inf if len(live) < k or small.any() else float(top / eig.min())
    dof = max(m - len(live), 1)
    s2 = float(r0 @ r0) / dof
    t = float(stats.t.ppf(0.975, dof))
    for col, j in enumerate(live):
        loading = vec[col] ** 2
        if float(loading[small].sum()) > 1e-8:
            continue  # lies along an unidentifiable direction: unbounded
        var = s2 * float(np.sum(loading[~small] / eig[~small]))
        value = specs[j].from_unit(u[j])
        half[specs[j].name] = float(t * math.sqrt(var) * specs[j].dvalue_du(value))
    if condition > ILL_CONDITIONED and len(live) > 1:
        unit = sub / np.linalg.norm(sub, axis=0)
        cosine = unit.T @ unit
        np.fill_diagonal(cosine, 0.0)
        a, b = np.unravel_index(int(np.argmax(np.abs(cosine))), cosine.shape)
        warnings.append(f"ill-conditioned: cond(JᵀJ) = {condition:.3g}; {specs[live[a]].name} and "
                        f"{specs[live[b]].name} trade off (their effects are {abs(cosine[a, b]):.3f} parallel); "
                        "the suite cannot pin these knobs down separately")
    return _Uncertainty(half, condition, warnings)


def fit_records(specs: Sequence[KnobSpec], fitted: Mapping[str, float],
                half_widths: Mapping[str, float | None]) -> tuple[dict[str, KnobFit], list[str]]:
    """Per-knob fit records, and a warning for every knob that left its nominal value to end at a bound."""
    records: dict[str, KnobFit] = {}
    warnings: list[str] = []
    for spec in specs:
        value = fitted[spec.name]
        bound = spec.at_bound(value)
        records[spec.name] = KnobFit(spec.name, spec.unit, spec.nominal, value, spec.lower, spec.upper,
                                     half_widths.get(spec.name), bound)
        if bound is not None and value != spec.nominal:
            edge = spec.lower if bound == "lower" else spec.upper
            warnings.append(f"{spec.name} ended at its {bound} bound ({edge:g}): the best value may lie beyond "
                            "it; widen the bounds if that is physical, or suspect a structural mismatch")
    return records, warnings


def overfit_warning(train_before: float, train_after: float, hold_before: float, hold_after: float,
                    hold_best: float) -> str | None:
    """A warning when the training objective fell while the held-out one rose (above its start or its best)."""
    if train_after >= train_before:
        return None
    if hold_after > hold_before * OVERFIT_RATIO or hold_after > hold_best * OVERFIT_FROM_BEST + 1e-12:
        return (f"overfitted: the training criterion fell {train_before:.4g} → {train_after:.4g} while the held-out "
                f"one rose to {hold_after:.4g} (before {hold_before:.4g}, best during the fit {hold_best:.4g}); "
                "fit fewer knobs, add regularization or add scenarios")
    return None


# ------------------------------------------------------------------ entry point
def _reference_kind(reference: str | Path) -> Literal["run", "twin"]:
    path = Path(reference)
    if (path / "manifest.json").is_file():
        return "run"
    if str(reference) in TWINS:
        return "twin"
    raise DualtwinError(f"reference {str(reference)!r} is neither a run directory (no manifest.json there) nor a "
                        f"twin ({', '.join(sorted(TWINS))})")


def _record_run_knobs(run_dir: Path, knobs: Mapping[str, float]) -> None:
    """Add the knob values a run was made with to its manifest (provenance)."""
    manifest = read_json(run_dir / "manifest.json")
    manifest["knobs"] = dict(knobs)
    write_json(run_dir / "manifest.json", manifest)


def _run_suite(suite: Path, twin_name: str, robot: RobotBinding, out: Path, seed: int, twin: Twin,
               knobs: Mapping[str, float], resume: bool) -> Path:
    if out.exists() and not resume:
        remove_output_dir(out, "suite-run")  # only a suite run this alignment wrote, never a foreign folder
    twin.set_knobs(dict(knobs))
    SuiteRun(suite, twin_name, robot, out, seed=seed, twin=twin).run(resume=resume)
    _record_run_knobs(out, knobs)
    return out


def _mujoco_module(name: str) -> Any:
    # Imported by name: mujoco.sysid ships a py.typed marker, and a static import makes mypy analyse the
    # untyped mujoco package itself (every attribute then fails to resolve, project-wide).
    return importlib.import_module(f"mujoco.{name}")


def sysid_status() -> str:
    """Whether ``mujoco.sysid`` is usable here, and why alignment uses ``mujoco.minimize`` either way."""
    try:
        usable = hasattr(_mujoco_module("sysid"), "optimize")
    except ImportError:
        usable = False
    where = "installed" if usable else "not installed (extra mujoco-core[sysid])"
    return (f"mujoco.sysid is {where}; not used because it simulates the MJCF's own actuators with "
            "mujoco.rollout, while the twin emulates Webots motors, delays and sensor models outside MuJoCo. "
            "The lsq optimiser is mujoco.minimize.least_squares (sysid's own) on residuals from the twin.")


def align(
    reference_run_or_twin: str | Path,
    target_twin_name: str,
    robot: str | RobotBinding,
    suite_path: Path,
    knob_patterns: Sequence[str],
    out_dir: Path,
    *,
    optimizer: Optimizer = "cma",
    seed: int = 0,
    budget: int = 600,
    resume: bool = False,
    executor: ExecutorKind = "process",
    ray_address: str | None = None,
    holdout: list[str] | None = None,
    workers: int = 2,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    channels: Sequence[str] | None = None,
    thresholds: Mapping[str, float] | None = None,
    reference_knobs: Mapping[str, float] | None = None,
    weights: ObjectiveWeights | None = None,
    popsize: int | None = None,
    sigma0: float = 0.25,
    patience: int | None = None,
    fd_step: float = 0.03,
    regularization: float = 0.0,
    propose_fn: ProposeFn | None = None,
    callback: Callable[[GenerationInfo], None] | None = None,
    objective: Literal["trajectory", "prediction"] = "trajectory",
    ensemble: Literal["off", "mean"] = "off",
    horizons: Sequence[int] = (1, 5),
    stride: int = 5,
) -> AlignResult:
    """Fit the target twin's knobs so its suite runs match the reference; write every artifact to ``out_dir``.

    Args:
        reference_run_or_twin: A recorded run directory, or a twin name that is run once (into
            ``out_dir/reference``, with ``reference_knobs`` applied).
        target_twin_name: Twin whose knobs are fitted (``mujoco`` or ``webots``; either may be the target).
        robot: Robot name or binding.
        suite_path: Suite to simulate; its scenarios must match the reference run's.
        knob_patterns: Knob names or fnmatch globs of the target twin.
        out_dir: Output folder (must be empty unless ``resume``).
        optimizer: ``cma`` (default) or ``lsq``.
        seed: Seed of the optimiser (simulations use the reference run's seed).
        budget: Maximum number of suite simulations.
        resume: Continue an interrupted alignment in ``out_dir``.
        executor: ``process`` (default), ``serial`` or ``ray``.
        ray_address: Ray cluster address for ``executor="ray"``.
        holdout: Scenario ids left out of the fit and reported separately.
        workers: Process-pool size.
        bounds: ``(lower, upper)`` overrides per knob name or glob.
        channels: Channels to fit (default: all logged channels).
        thresholds: Crossing thresholds per channel (default 0.99 rad on ``*_angle_rad``).
        reference_knobs: Knobs applied to a reference *twin*.
        weights: Objective weights.
        popsize: CMA population size (default: CMA's ``4 + 3 ln n``).
        sigma0: CMA initial step in normalised units.
        patience: CMA generations without improvement before stopping (default ``max(15, 3 × knobs)``).
        fd_step: Finite-difference step of least squares and of the uncertainty, in normalised units.
        regularization: Weight λ of a pull toward nominal: ``λ·f₀·mean((u - u_nominal)²)`` is added to the
            training objective (``f₀`` its nominal value; likewise as residuals), with ``u`` the normalised
            knob values. λ = 0.1 means that moving every knob across its whole range costs 10 % of the
            nominal mismatch. 0 (the default) fits the data alone; 0.05 to 0.5 keeps weakly identified knobs
            near their model values in cross-simulator fits.
        propose_fn: Optional proposer ``analysis -> [knob values]``; proposals that lower the objective
            seed the search (see :mod:`dualtwin.align.propose`).
        callback: Called after every generation/iteration, after the checkpoint is written.
        objective: ``trajectory`` (default: the suite-run objective above) or ``prediction``: short-horizon
            prediction error from synchronised start states (:mod:`dualtwin.align.prediction`; the reference
            is then a twin or a trajectory file, and holdout, channels, thresholds, weights and proposals do
            not apply).
        horizons: Prediction horizons in control periods (``prediction`` only).
        stride: A prediction start every ``stride`` periods (``prediction`` only).
        ensemble: ``off`` (default) fits the reference's own trajectory. ``mean`` needs a reference run with
            ensemble members (``suite run --ensemble N --perturb KEY=EPS``): the objective compares the
            members' mean with the mean of the target simulated with the same initial-condition shifts, so a
            chaotic scenario is fitted on what its members share. Each candidate then costs N simulations
            (``budget`` still counts candidates).

    Raises:
        DualtwinError: Bad input (unknown knobs, bounds excluding nominal, mismatched reference, ...).
    """
    if objective == "prediction":
        unused = [name for name, value in (("holdout", holdout), ("channels", channels), ("thresholds", thresholds),
                                           ("weights", weights), ("propose_fn", propose_fn)) if value]
        if unused or executor == "ray":
            raise DualtwinError(f"the prediction objective does not take {', '.join(unused) or 'executor ray'}")
        from dualtwin.align.prediction import align_prediction

        return align_prediction(reference_run_or_twin, target_twin_name, robot, suite_path, knob_patterns, out_dir,
                                optimizer=optimizer, seed=seed, budget=budget, resume=resume, executor=executor,
                                workers=workers, bounds=bounds, reference_knobs=reference_knobs, horizons=horizons,
                                stride=stride, popsize=popsize, sigma0=sigma0, patience=patience, fd_step=fd_step,
                                regularization=regularization, callback=callback)
    if objective != "trajectory":
        raise DualtwinError(f"unknown objective {objective!r}; use 'trajectory' or 'prediction'")
    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    binding = resolve_robot(robot) if isinstance(robot, str) else robot
    suite_path = Path(suite_path)
    suite = load_suite(suite_path)
    check_against_binding(suite, suite_path, binding)
    ids = suite.scenario_ids()
    held = list(holdout or [])
    unknown = sorted(set(held) - set(ids))
    if unknown:
        raise DualtwinError(f"holdout names unknown scenarios {unknown}; the suite has {ids}")
    if not [s for s in ids if s not in held]:
        raise DualtwinError("every scenario is held out; nothing is left to fit")
    if optimizer not in ("cma", "lsq"):
        raise DualtwinError(f"unknown optimizer {optimizer!r}; use 'cma' or 'lsq'")
    check_executor(executor)
    kind = _reference_kind(reference_run_or_twin)
    config = AlignConfig(
        reference=str(Path(reference_run_or_twin).resolve()) if kind == "run" else str(reference_run_or_twin),
        reference_kind=kind, reference_knobs=dict(reference_knobs or {}), target=target_twin_name,
        robot=str(binding.path), suite=str(suite_path.resolve()), knobs=list(knob_patterns),
        bounds={k: (float(v[0]), float(v[1])) for k, v in (bounds or {}).items()},
        channels=None if channels is None else list(channels), holdout=held,
        thresholds=None if thresholds is None else dict(thresholds), optimizer=optimizer, seed=seed,
        budget=budget, popsize=popsize, sigma0=sigma0, patience=patience, fd_step=fd_step,
        regularization=regularization, executor=executor, workers=workers, ray_address=ray_address,
        weights=weights or ObjectiveWeights(), ensemble=ensemble)
    if kind == "run" and reference_knobs:
        raise DualtwinError("reference_knobs apply only when the reference is a twin, not a recorded run")

    period = suite.global_settings.control_period_s
    target = make_twin(target_twin_name, binding, period)
    try:
        # Everything checkable is checked before the output folder is touched, so a typo costs nothing.
        channel_names = list(RobotIO(binding, target).channel_info())
        fitted_ids = [s for s in ids if s not in held]
        left: dict[str, dict[str, str]] = {}
        if kind == "run":
            shared = shared_with_reference(load_traces(Path(reference_run_or_twin)), ids, channel_names,
                                           Path(reference_run_or_twin))
            missing_held = [s for s in held if s not in shared.scenarios]
            if missing_held:
                raise DualtwinError(f"holdout names scenarios the reference does not have: {missing_held}")
            fitted_ids = [s for s in shared.scenarios if s not in held]
            if not fitted_ids:
                raise DualtwinError(f"every scenario the reference has ({shared.scenarios}) is held out; "
                                    "nothing is left to fit")
            if channels is not None:
                absent = [c for c in channels if c not in shared.channels]
                if absent:
                    raise DualtwinError(f"channels {absent} are not shared by the reference and the robot binding; "
                                        f"shared: {shared.channels}")
            left = shared.left_out
        members: list[dict[str, float]] = []
        if ensemble == "mean":
            members = ensemble_members_of(reference_run_or_twin, kind, fitted_ids + held, binding)
        # Physics knobs of the target twin, and nuisance knobs (initial conditions, time offsets) of the
        # fitted scenarios; `nuisance` explains why the two are kept apart.
        registry = {**target.knobs(), **nuisance.registry(suite, binding, fitted_ids)}
        specs = select_knobs(registry, list(knob_patterns), config.bounds, where=f"twin {target_twin_name!r}")

        # Output folder: fresh, or the same configuration when resuming.
        config_path = out_dir / "align_config.json"
        if resume and config_path.is_file():
            if read_json(config_path) != json.loads(config.model_dump_json()):
                raise DualtwinError(f"{config_path}: cannot resume: the configuration differs from the interrupted run")
        elif out_dir.exists() and any(out_dir.iterdir()):
            raise DualtwinError(f"{out_dir}: output folder is not empty; use resume to continue an alignment, "
                                "or choose another folder")
        write_json(config_path, json.loads(config.model_dump_json()))

        # The reference: a recorded run, or a twin run once into out_dir/reference.
        if kind == "run":
            ref_dir = Path(reference_run_or_twin)
            sim_seed = load_run(ref_dir).seed or 0
        else:
            ref_dir = out_dir / "reference"
            sim_seed = seed
            ref_twin = make_twin(str(reference_run_or_twin), binding, period)
            try:
                values = check_values(ref_twin.knobs(), config.reference_knobs, f"reference twin {reference_run_or_twin!r}")
                _run_suite(suite_path, str(reference_run_or_twin), binding, ref_dir, sim_seed, ref_twin, values, resume)
            finally:
                ref_twin.close()
        reference = load_traces(ref_dir)
        if members:
            reference.update({sid: mean_trace(m) for sid, m in load_member_traces(ref_dir).items()})
        shared = shared_with_reference(reference, ids, channel_names, ref_dir)
        train_ids = [s for s in shared.scenarios if s not in held]
        train = build_spec(reference, train_ids, channels if channels is not None else shared.channels,
                           thresholds=thresholds, weights=config.weights)
        hold = build_spec(reference, held, train.channels, thresholds=thresholds, weights=config.weights) if held else None
        warnings = [f"scenario {s} is unstable in the reference and is not fitted" for s in train.skipped]
        left = shared.left_out
        warnings += [f"left out: {what[:-1]} {name}: {why}" for what, names in left.items() for name, why in names.items()]

        before_dir = _run_suite(suite_path, target_twin_name, binding, out_dir / "runs" / "before", sim_seed, target,
                                {}, resume)
        job = SimJob(str(binding.path), target_twin_name, str(suite_path.resolve()), tuple(shared.scenarios), (),
                     sim_seed)
        with Evaluator(executor, workers, ray_address) as evaluator:
            problem = _Problem(specs, job, train, hold, evaluator, budget, config.regularization, members)
            nominal_u = unit_from_values(specs, {})
            before = problem.run([nominal_u])[0]
            problem.calibrate(before)
            analysis_before = analyze_runs(ref_dir, before_dir, thresholds=thresholds)
            x0, f0 = nominal_u, before.train
            proposals: list[ProposalOutcome] = []
            if propose_fn is not None:
                proposals = try_proposals(propose_fn, analysis_before, specs, before.train, problem.run_values)
                accepted = [p for p in proposals if p.accepted and p.objective is not None]
                if accepted:
                    best = min(accepted, key=lambda p: p.objective or math.inf)
                    x0, f0 = unit_from_values(specs, best.knobs), float(best.objective or before.train)
            fit = _fit_cma if optimizer == "cma" else _fit_lsq
            outcome = fit(problem, config, out_dir, x0, f0, resume, callback)
            after = problem.run([outcome.u])[0]

            def criterion(p: _Point) -> float:
                # Each optimiser is judged by what it minimises: the objective, or the residual norm.
                return p.train if optimizer == "cma" else _residual_norm(p)

            if criterion(after) > criterion(before):
                # Never hand back something worse than where we started.
                outcome.u, after = nominal_u, before
                warnings.append("no knob setting beat the nominal twin; the fitted values are the nominal ones")
            uncertainty = _uncertainty(problem, outcome.u, config.fd_step)
        fitted, fitted_nuisance = nuisance.split(values_from_unit(specs, outcome.u))
        warnings += uncertainty.warnings
        all_fits, bound_warnings = fit_records(specs, {**fitted, **fitted_nuisance}, uncertainty.half_widths)
        knob_fits = {n: k for n, k in all_fits.items() if not nuisance.is_nuisance(n)}
        nuisance_fits = {n: k for n, k in all_fits.items() if nuisance.is_nuisance(n)}
        warnings += bound_warnings
        if hold is not None and before.holdout is not None and after.holdout is not None:
            best_seen = min((t["holdout_of_best"] for t in outcome.trace if t.get("holdout_of_best") is not None),
                            default=after.holdout)
            overfit = overfit_warning(criterion(before), criterion(after), before.holdout, after.holdout, best_seen)
            if overfit:
                warnings.append(overfit)

        # The after run uses the fitted initial conditions too, so it shows what the fit matched; time offsets
        # only move the objective's time axis and are not in the run.
        after_suite = suite_path
        if any(nuisance.parse(n, ids)[1] != nuisance.TIME_OFFSET for n in fitted_nuisance):
            after_suite = out_dir / "suite_with_nuisance.json"
            write_json(after_suite, nuisance.apply_to_document(read_json(suite_path), ids, fitted_nuisance))
        after_dir = _run_suite(after_suite, target_twin_name, binding, out_dir / "runs" / "after", sim_seed, target,
                               fitted, False)
        analysis_after = analyze_runs(ref_dir, after_dir, thresholds=thresholds)
    finally:
        target.close()

    files: dict[str, str] = {"config": "align_config.json", "reference": str(ref_dir),
                             "before": "runs/before", "after": "runs/after"}
    knobs_doc = {"schema": KNOBS_SCHEMA, "twin": target_twin_name, "robot": binding.name, "optimizer": optimizer,
                 "values": fitted, "knobs": {n: k.to_dict() for n, k in knob_fits.items()}}
    write_json(out_dir / "knobs.json", knobs_doc)
    files["knobs"] = "knobs.json"

    if optimizer == "cma" and outcome.population:
        ranges = ranges_from_population(specs, outcome.population, config.dr_top_fraction)
        source = "cma-population"
    else:
        ranges = ranges_from_intervals([s for s in specs if not nuisance.is_nuisance(s.name)], fitted,
                                       uncertainty.half_widths)
        source = "lsq-interval" if optimizer == "lsq" else "jacobian-interval"
    physics_specs = [s for s in specs if not nuisance.is_nuisance(s.name)]
    ranges = {k: v for k, v in ranges.items() if not nuisance.is_nuisance(k)}
    write_json(out_dir / "dr_ranges.json", dr_document(physics_specs, fitted, ranges, source, config.dr_min_rel_width))
    files["dr_ranges"] = "dr_ranges.json"

    patch = _patch_model(binding, target_twin_name, fitted, period)
    if patch.text is not None:
        suffix = ".xml" if target_twin_name == "mujoco" else ".wbt"
        name = f"{binding.name}_aligned{suffix}"
        write_text(out_dir / name, patch.text)
        files["model"] = name
    result = AlignResult(
        out_dir=out_dir, optimizer=optimizer, knobs=knob_fits, objective_before=before.train,
        objective_after=after.train, holdout_before=before.holdout, holdout_after=after.holdout,
        residual_before=float(before.residual @ before.residual), residual_after=float(after.residual @ after.residual),
        evaluations=problem.evaluations, iterations=outcome.iterations, wall_time_s=0.0,
        stop_reason=outcome.stop_reason, warnings=warnings, condition_number=uncertainty.condition,
        files=files, proposals=proposals, nuisance=nuisance_fits, left_out=left)
    narrative = getattr(propose_fn, "narrative", None)
    if narrative is not None:
        result.narrative = narrative.to_dict()

    from dualtwin.align.report import write_align_report

    result.wall_time_s = time.perf_counter() - t_start  # up to the report; the record gets the final time
    files["report"] = write_align_report(out_dir, result, ref_dir, before_dir, after_dir, analysis_before,
                                         analysis_after, train_ids, held, thresholds).name
    result.wall_time_s = time.perf_counter() - t_start
    record = _record(config, result, outcome, patch, binding, suite_path, ref_dir, kind, sim_seed, specs,
                     analysis_before)
    write_json(out_dir / "align_record.json", record)
    files["record"] = "align_record.json"
    return result


def _patch_model(binding: RobotBinding, twin: str, fitted: Mapping[str, float],
                 control_period: float | None = None) -> PatchResult:
    """The patched target model; ``control_period`` (default: the binding's) is the one the knobs were fitted at."""
    if twin == "mujoco":
        section = binding.spec.twins.get("mujoco")
        period = control_period if control_period is not None else binding.spec.control_period_ms / 1000.0
        return patch_mjcf(binding.model_path("mujoco"), fitted, dict(section.aliases) if section else None, period)
    if twin == "webots":
        return patch_webots(binding.model_path("webots"), fitted)
    return PatchResult(None, note=f"no model patcher for twin {twin!r}; knobs.json holds the values")


def _record(config: AlignConfig, result: AlignResult, outcome: _Outcome, patch: PatchResult, binding: RobotBinding,
            suite_path: Path, ref_dir: Path, kind: str, sim_seed: int, specs: Sequence[KnobSpec],
            analysis: Analysis) -> dict[str, Any]:
    inputs: dict[str, Any] = {
        "suite": {"path": str(suite_path), "sha256": sha256_file(suite_path)},
        "binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)},
        "model": {"path": str(binding.model_path(config.target)), "sha256": sha256_file(binding.model_path(config.target))},
        "reference": {"path": str(ref_dir), "kind": kind, "manifest_sha256": sha256_file(ref_dir / "manifest.json")},
    }
    return {
        "schema": ALIGN_SCHEMA,
        "config": json.loads(config.model_dump_json()),
        "seed": config.seed,
        "simulation_seed": sim_seed,
        "versions": package_versions(),
        "inputs": inputs,
        "knob_specs": [s.to_dict() for s in specs],
        "result": {
            "knobs": {n: k.to_dict() for n, k in result.knobs.items()},
            # Per-scenario initial conditions and time offsets: about the reference, not in the aligned model.
            "nuisance": {n: k.to_dict() for n, k in result.nuisance.items()},
            "left_out": result.left_out,
            "objective_before": result.objective_before, "objective_after": result.objective_after,
            "holdout_before": result.holdout_before, "holdout_after": result.holdout_after,
            "residual_norm2_before": result.residual_before, "residual_norm2_after": result.residual_after,
            "condition_number": None if result.condition_number is None or not math.isfinite(result.condition_number)
            else result.condition_number,
            "stop_reason": result.stop_reason, "warnings": result.warnings,
        },
        "evaluations": result.evaluations,
        "iterations": result.iterations,
        "wall_time_s": result.wall_time_s,
        "trace": outcome.trace,
        "findings_before": [f.model_dump(mode="json") for f in analysis.findings],
        "proposals": [p.to_dict() for p in result.proposals],
        **({"llm_narrative": result.narrative} if result.narrative is not None else {}),
        "model_patch": {"applied": patch.applied, "not_applied": patch.not_applied, "note": patch.note},
        "sysid": sysid_status(),
        "files": result.files,
    }


def print_result(result: AlignResult, console: Console) -> None:
    """The fitted knobs, before → after objectives and warnings, for the terminal."""
    console.print(f"{result.optimizer}: {result.stop_reason}; {result.evaluations} evaluations, "
                  f"{result.iterations} iterations, {result.wall_time_s:.1f} s")
    if result.optimizer == "lsq":
        # Least squares minimises the trajectory residual; the DTW/event/endpoint objective is reported too.
        console.print(f"trajectory residual (train, minimised): {result.residual_before:.4g} → "
                      f"[bold]{result.residual_after:.4g}[/]")
    console.print(f"DTW + event-time + endpoint objective (train): {result.objective_before:.4g} → "
                  f"{'[bold]' if result.optimizer == 'cma' else ''}{result.objective_after:.4g}"
                  f"{'[/]' if result.optimizer == 'cma' else ''}")
    if result.holdout_before is not None and result.holdout_after is not None:
        console.print(f"DTW + event-time + endpoint objective (held out): {result.holdout_before:.4g} → "
                      f"{result.holdout_after:.4g}")
    from dualtwin.reporting import Column, print_table

    columns = [Column("knob", False), Column("nominal"), Column("fitted"), Column("± 95 %"), Column("unit", False),
               Column("note", False)]

    def knob_rows(knobs: Mapping[str, KnobFit]) -> list[list[str]]:
        return [[k.name, f"{k.nominal:.5g}", f"{k.fitted:.5g}",
                 f"{k.half_width_95:.2g}" if k.half_width_95 is not None else "–", k.unit,
                 f"at {k.at_bound} bound" if k.at_bound else ""] for k in knobs.values()]

    print_table(console, columns, knob_rows(result.knobs))
    if result.nuisance:
        console.print("nuisance knobs (this reference's initial conditions and time offsets; not in the aligned model):")
        print_table(console, columns, knob_rows(result.nuisance))
    for warning in result.warnings:
        console.print(f"[yellow]warning:[/] {escape(warning)}")
    console.print(f"wrote {result.out_dir / result.files.get('report', 'report.html')}")
