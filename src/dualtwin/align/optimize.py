"""The optimisers: CMA-ES and least squares over a :class:`~dualtwin.align.core.Problem`, with checkpoints.

Both see an objective only through the problem protocol, so every objective is fitted the same way.

* ``optimizer="cma"`` (:func:`fit_cma`): CMA-ES (`cma`) in the unit cube of the knobs' normalised ranges
  (log-scaled for wide positive ranges), seeded through a private random generator, with each population evaluated in
  parallel, with the best point so far injected into every population (elitist: a start that is
  already good is kept, not lost). After every generation ``checkpoint.json`` (the commit point) is written
  atomically with every generation's injected point, asked solutions and their objective values (JSON, no
  pickle). ``resume=True`` rebuilds a freshly seeded strategy and replays ``ask``/``tell`` on those records:
  the strategy's sampler is seeded, so the replay reproduces its state bit for bit (each replayed generation is
  checked against the recorded solutions), loses at most one generation, and continues exactly as an
  uninterrupted run would. Nothing in an output folder is ever unpickled, and no path is read from it.
  It stops on the evaluation budget, CMA's own tolerances (``tolfun``, ``tolx``), ``patience``
  generations without improvement, or an exact match.
* ``optimizer="lsq"`` (:func:`fit_lsq`): ``mujoco.minimize.least_squares`` (bounded Levenberg-Marquardt with
  a finite-difference Jacobian whose perturbed points are simulated in parallel) on the residual vector.
  When it stops, the points four finite-difference steps away along each knob are tried, and the fit
  restarts from a better one (``lsq_restarts`` times at most). Before it, ``global_search="multistart"`` (the
  default) finds the basin: a scrambled Sobol screen of the knob box, simulated as one batch, gives up to two
  distinct starts that beat the given one. The starts (and the given one) then race: each runs
  :data:`RACE_ITERATIONS` least-squares iterations, the one that got furthest is polished with everything left,
  and the others go on (best first) only with what it did not need; the best end wins. Equal shares, as before,
  left every start of a small budget short of the minimum in a curved valley (a CartPole fall: 4 knobs, least
  squares needs 150-200 runs along it). The stop reason says how many points were screened, how the race went
  and which start won: a fit that ends in a valley while the truth scores better elsewhere is what this prevents. Integer knobs (delays, physics sub-steps)
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
"""

from __future__ import annotations

import importlib
import io
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.align.cma_quiet import cma  # cma without matplotlib.pyplot (see there)
from dualtwin.align.config import AlignConfig
from dualtwin.align.core import (
    GenerationInfo,
    Outcome,
    Point,
    Problem,
    fd_jacobian,
    residual_norm,
    screen_integers,
)
from dualtwin.artifacts import resolved, write_json
from dualtwin.errors import DualtwinError
from dualtwin.suite.loader import read_json


class BudgetExhausted(Exception):
    """Raised inside the least-squares residual when the evaluation budget is spent."""



class _Randn:
    """CMA's normal sampler on a private generator: a fresh strategy with the same seed replays exactly."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, *shape: int) -> np.ndarray:
        return self.rng.standard_normal(shape)


# ------------------------------------------------------------------ CMA-ES
def _cma_stop(es: Any, problem: Problem, config: AlignConfig, stale: int, best: float) -> str | None:
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


def fit_cma(problem: Problem, config: AlignConfig, out_dir: Path, x0: Sequence[float], f0: float, resume: bool,
             callback: Callable[[GenerationInfo], None] | None) -> Outcome:
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
            if len(best_u) != len(problem.specs):
                raise ValueError(f"best_u has {len(best_u)} coordinates for {len(problem.specs)} knobs")
            if state.get("incumbent"):
                problem.restore_point(state["incumbent"])
        except (KeyError, TypeError, ValueError) as exc:
            raise DualtwinError(f"{checkpoint}: damaged CMA checkpoint ({type(exc).__name__}: {exc})") from None
    else:
        integer = [i for i, spec in enumerate(problem.specs) if spec.integer]
        if integer:
            screened = problem.run([screen_integers(problem, x0, integer, config.budget, lambda p: p.train)])[0]
            if screened.train < f0:
                x0, f0 = screened.u, screened.train
        es = _new_cma(list(x0), config, _affordable_popsize(len(x0), config, config.budget - problem.evaluations))
        generations = []
        trace, archive = [], []
        # The start point (nominal, the best kept proposal, or the best integer setting) is the one to beat.
        best_u, best_f, stale = list(x0), f0, 0
    while True:
        reason = _cma_stop(es, problem, config, stale, best_f)
        if reason:
            on_budget = problem.evaluations + es.popsize > config.budget  # _cma_stop's first rule
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
    return Outcome(best_u, int(es.countiter), reason, trace, population, on_budget)


#: CMA-ES checkpoints record the ask/tell history (JSON); version 1 named a pickled strategy, never loaded now.
CMA_CHECKPOINT_SCHEMA = "dualtwin.align.checkpoint/2"


def _affordable_popsize(n: int, config: AlignConfig, left: int) -> int | None:
    """The population of a first CMA generation the budget cannot otherwise afford, else None (CMA's default).

    CMA-ES's default population is 4 + 3 ln n; a smaller budget (a tutorial's ``--budget 4``) would end before
    its first generation and fit nothing, so the population shrinks to what is left (at least 2). A population
    the user set is kept."""
    if config.popsize or left < 2:
        return None
    default = 4 + int(3 * math.log(max(n, 1)))
    return left if left < default else None


def _new_cma(x0: list[float], config: AlignConfig, popsize: int | None = None) -> Any:
    opts: dict[str, Any] = {"bounds": [0.0, 1.0], "randn": _Randn(config.seed), "tolfun": config.tolfun,
                            "tolx": config.tolx, "verbose": -9, "verb_log": 0, "verb_disp": 0}
    if popsize or config.popsize:
        opts["popsize"] = popsize or config.popsize
    return cma.CMAEvolutionStrategy(x0, config.sigma0, opts)


def _cma_inject(es: Any, u: list[float]) -> None:
    es.inject([es.boundary_handler.inverse(np.asarray(u))] if es.boundary_handler is not None
              else [np.asarray(u)], force=True)


def confined_path(folder: Path, value: Any, where: str) -> Path:
    """``folder / value`` if that stays inside ``folder``; else a :class:`DualtwinError` naming ``where``."""
    if not isinstance(value, str) or not value:
        raise DualtwinError(f"{where}: expected a file name inside {folder}, got {value!r}")
    root = resolved(folder)
    path = resolved(root / value)
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
    popsize = state.get("popsize")
    es = _new_cma(x0, config, popsize if isinstance(popsize, int) and popsize >= 2 else None)
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


def _write_cma_checkpoint(out_dir: Path, config: AlignConfig, es: Any, problem: Problem,
                          trace: list[dict[str, Any]], archive: list[list[tuple[list[float], float]]],
                          best_u: list[float], best_f: float, stale: int, x0: Sequence[float],
                          generations: list[dict[str, Any]]) -> None:
    write_json(out_dir / "checkpoint.json", {
        "schema": CMA_CHECKPOINT_SCHEMA, "config": config.digest(), "optimizer": "cma",
        "iteration": int(es.countiter), "x0": list(x0), "generations": generations,
        "popsize": int(es.popsize), "evaluations": problem.evaluations, "best_u": best_u, "best_value": best_f, "stale": stale,
        "incumbent": problem.point_state(best_u), "trace": trace, "archive": [[[u, f] for u, f in gen] for gen in archive],
    })


# ------------------------------------------------------------------ least squares
#: Rounds of re-screening integer knobs at the fitted continuous values (least squares only).
LSQ_INTEGER_ROUNDS = 2
#: Least-squares iterations each start of the basin search runs before the race picks the one to continue.
RACE_ITERATIONS = 3


def fit_lsq(problem: Problem, config: AlignConfig, out_dir: Path, x0: Sequence[float], f0: float, resume: bool,
             callback: Callable[[GenerationInfo], None] | None) -> Outcome:
    minimize = mujoco_module("minimize")
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
    seen: dict[tuple[float, ...], Point] = {}
    offset = len(trace)
    integer = [i for i, s in enumerate(problem.specs) if s.integer]
    free = [i for i in range(len(problem.specs)) if i not in integer]
    if integer and not trace:
        start = screen_integers(problem, start, integer, config.budget, residual_norm)
    held = list(start)

    def expand(x: Sequence[float] | np.ndarray) -> list[float]:
        """The full unit vector: least squares moves the continuous knobs, integer ones stay as screened."""
        full = list(held)
        for j, i in enumerate(free):
            full[i] = min(1.0, max(0.0, float(x[j])))
        return full

    limit = config.budget  # the evaluation count a polish may reach (a race's heat is shorter)

    def residual(x: np.ndarray) -> np.ndarray:
        columns = [expand(x[:, j]) for j in range(x.shape[1])]
        if problem.evaluations + len(columns) > limit:
            raise BudgetExhausted
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

    def fit_continuous(u: list[float], max_iter: int | None = None) -> tuple[list[float], str, int, bool]:
        """Least squares with restarts from a better neighbour; (u, reason, restarts, budget exhausted).
        ``max_iter`` caps the iterations of the one run (a race's heat: no restarts)."""
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
                                              max_iter=max_iter or config.lsq_max_iter, verbose=1, output=output,
                                              iter_callback=on_iteration)
                u = expand(np.asarray(x).ravel())
                final = [line for line in output.getvalue().splitlines() if line.startswith("Terminated after")]
                reason = final[-1].split(": ", 1)[-1].split(" y:")[0] if final else "done"
            except BudgetExhausted:
                best = min((q for q in seen.values() if _near(q.u, held, free)), key=residual_norm, default=None)
                u = best.u if best is not None else u
                return u, f"budget ({problem.evaluations} of {config.budget} evaluations used)", restarts, True
            if max_iter is not None or attempt == config.lsq_restarts:
                break
            # Rough residuals (impacts sampled once per control period) can trap a Gauss-Newton step in a dent:
            # probe a few finite-difference steps away and restart from a better point if there is one.
            kick = 4 * config.fd_step
            probes = [p for i in free for p in (
                [*u[:i], min(1.0, u[i] + kick), *u[i + 1:]], [*u[:i], max(0.0, u[i] - kick), *u[i + 1:]]) if p != u]
            better = None
            if probes and problem.evaluations + len(probes) + 1 <= limit:
                here = seen.get(tuple(u)) or problem.run([u])[0]
                scored = problem.run(probes)
                for p in scored:
                    seen[tuple(p.u)] = p
                better = min(scored, key=residual_norm)
                if residual_norm(better) >= residual_norm(here) * (1 - 1e-9):
                    better = None
            if better is None:
                break
            u = better.u
            restarts += 1
        return u, reason, restarts, False

    def polish(u: list[float]) -> tuple[list[float], str, int, bool]:
        """One start: least squares, then (with integer knobs) re-screen the integers and refit until they settle."""
        u, reason, restarts, spent = fit_continuous(u)
        # Integer and continuous knobs can stand in for each other (a coarser step for less damping): screen the
        # integers again at the fitted values and refit until they settle.
        for _ in range(LSQ_INTEGER_ROUNDS):
            if not integer or spent:
                break
            again = screen_integers(problem, u, integer, limit, residual_norm)
            if again == u:
                break
            u, reason, more, spent = fit_continuous(again)
            restarts += more
        if restarts:
            reason += f" (after {restarts} restart{'s' if restarts > 1 else ''} from a better neighbour)"
        return u, reason, restarts, spent

    u = list(start)
    if not free:
        return Outcome(u, 0, "integer knobs screened; no continuous knob to fit", trace)
    starts, screened = [u], 0
    if config.global_search == "multistart" and not trace:
        starts, screened = basin_starts(problem, config, u, free)
    race, beaten = "", len(starts) - 1  # screened starts that beat the given one
    if len(starts) > 1:
        # A race, not equal shares: every start runs a few iterations, then the one that got furthest continues
        # with everything left. Equal shares of a small budget leave every start short of the minimum (a
        # curved valley takes least squares many iterations), and the best of several unfinished ends is still
        # unfinished.
        heat = max(len(free) + 2, (config.budget - problem.evaluations) // (3 * len(starts)))
        ends: list[tuple[float, int, list[float]]] = []
        for begin in starts:
            limit = problem.evaluations + heat
            end, _, _, _ = fit_continuous(list(begin), max_iter=RACE_ITERATIONS)
            point = seen.get(tuple(end)) or problem.run([end])[0]
            ends.append((residual_norm(point), len(ends), end))
            if problem.evaluations >= config.budget - len(free) - 1:
                break
        ends.sort()
        race = f"a race of {len(ends)} starts ({RACE_ITERATIONS} iterations each), start {ends[0][1] + 1} ahead; "
        starts = [e[2] for e in ends]
    results: list[tuple[list[float], str, float, bool]] = []
    for begin in starts:
        # The leader takes what is left; a runner-up continues only with what the leader did not need.
        limit = config.budget
        end, reason, _, spent = polish(list(begin))
        point = seen.get(tuple(end)) or problem.run([end])[0]
        results.append((end, reason, residual_norm(point), spent))
        if problem.evaluations >= config.budget - len(free) - 1:
            break
    best_i = min(range(len(results)), key=lambda j: results[j][2])
    u, reason, _, on_budget = results[best_i]
    steps = gauss_newton_polish(problem, u, free, config)
    if steps[1]:
        u = steps[0]
        reason += f"; {steps[1]} central-difference Gauss-Newton step{'s' if steps[1] > 1 else ''}"
    if screened:
        beat = f"{beaten} beat the start" if beaten else "none beat the start"
        reason = (f"basin search: {screened} points screened ({beat}), {race}{len(results)} start"
                  f"{'s' if len(results) > 1 else ''} polished, start {best_i + 1} best; least squares: {reason}")
    return Outcome(u, len(trace), reason, trace, ended_on_budget=on_budget)


#: Gauss-Newton steps with a central-difference Jacobian after least squares (each costs 2·knobs + 2 runs).
POLISH_STEPS = 4


def gauss_newton_polish(problem: Problem, u: list[float], free: Sequence[int], config: AlignConfig
                        ) -> tuple[list[float], int]:
    """Full and half Gauss-Newton steps from ``u`` with a central-difference Jacobian, kept while they lower the
    residual norm (within the budget). Least squares stops where the *forward*-difference gradient vanishes,
    which at a 3 % step is not where the true gradient does; this moves the end to the true minimum."""
    taken = 0
    for _ in range(POLISH_STEPS):
        if problem.evaluations + 2 * len(free) + 3 > config.budget:
            break
        jac, r0 = fd_jacobian(problem, u, config.fd_step, free, central=True)
        delta, *_ = np.linalg.lstsq(jac, -r0, rcond=1e-10)
        tries = []
        for scale in (1.0, 0.5):
            p = list(u)
            for j, i in enumerate(free):
                p[i] = min(1.0, max(0.0, u[i] + scale * float(delta[j])))
            tries.append(p)
        here = float(r0 @ r0)
        best = min(problem.run(tries), key=residual_norm)
        if residual_norm(best) >= here * (1 - 1e-9):
            break
        u, taken = best.u, taken + 1
    return u, taken


def _near(a: Sequence[float], b: Sequence[float], free: Sequence[int]) -> bool:
    """Same held (integer) coordinates: a point least squares could have reached from ``b``."""
    return all(a[i] == b[i] for i in range(len(a)) if i not in free)


#: Distinct starts polished after the basin screen (besides the given start), at least this far apart (unit cube).
POLISH_STARTS = 2
START_SEPARATION = 0.15


def basin_starts(problem: Problem, config: AlignConfig, u: Sequence[float], free: Sequence[int]
                 ) -> tuple[list[list[float]], int]:
    """Find the basin before polishing: a scrambled Sobol screen of the continuous knobs (one batch), and the
    starts worth polishing, best first: the screen's best points that beat the given start, spread at least
    :data:`START_SEPARATION` apart, then the given start itself.

    The screen's size is ``config.starts`` (0: ``max(8, 4·knobs)``, at most a quarter of the budget).
    """
    from scipy.stats import qmc

    size = min(config.starts or max(8, 4 * len(free)), max(0, config.budget // 4 - 1))
    if size < 2:
        return [list(u)], 0
    # Sobol points keep their balance in powers of two.
    exponent = int(math.log2(size))
    size = 2 ** exponent
    sample = qmc.Sobol(len(free), scramble=True, seed=config.seed).random_base2(exponent)
    points = []
    for row in sample:
        p = list(u)
        for j, i in enumerate(free):
            p[i] = float(row[j])
        points.append(p)
    scored = problem.run([list(u), *points])
    here, rest = residual_norm(scored[0]), sorted(scored[1:], key=residual_norm)
    chosen: list[list[float]] = []
    for q in rest:
        if residual_norm(q) >= here or len(chosen) >= POLISH_STARTS:
            break
        if all(max(abs(q.u[i] - c[i]) for i in free) > START_SEPARATION for c in [list(u), *chosen]):
            chosen.append(q.u)
    return [*chosen, list(u)], size


def mujoco_module(name: str) -> Any:
    # Imported by name: mujoco.sysid ships a py.typed marker, and a static import makes mypy analyse the
    # untyped mujoco package itself (every attribute then fails to resolve, project-wide).
    return importlib.import_module(f"mujoco.{name}")


def sysid_status() -> str:
    """Whether ``mujoco.sysid`` is usable here, and why alignment uses ``mujoco.minimize`` either way."""
    usable = _sysid_installed()
    where = "installed" if usable else "not installed (extra mujoco-core[sysid])"
    return (f"mujoco.sysid is {where}; not used because it simulates the MJCF's own actuators with "
            "mujoco.rollout, while the twin emulates Webots motors, delays and sensor models outside MuJoCo. "
            "The lsq optimiser is mujoco.minimize.least_squares (sysid's own) on residuals from the twin.")



def _sysid_installed() -> bool:
    """Whether ``mujoco.sysid`` imports here: it ships with mujoco and needs its ``sysid`` extra's packages.
    Read from package metadata: importing it to find out costs about a CPU-second (it loads matplotlib)."""
    import importlib.metadata as metadata
    import importlib.util
    import re

    try:
        if importlib.util.find_spec("mujoco.sysid") is None:
            return False
        requirements = metadata.requires("mujoco") or []
        for requirement in requirements:
            name, _, marker = requirement.partition(";")
            if re.search(r"extra\s*==\s*['\"]sysid['\"]", marker):
                metadata.version(re.split(r"[\s\[<>=!~;]", name.strip(), maxsplit=1)[0])
    except (ImportError, metadata.PackageNotFoundError):
        return False
    return True
