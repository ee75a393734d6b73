"""Synchronisation benchmarks: lockstep overhead, and a targeted fit with the prediction objective.

Run: ``python bench/bench_sync.py`` (or ``make bench``). Three measurements, all in one run:

(a) overhead: the CartPole suite in lockstep (Webots primary, MuJoCo secondary, ``never``: both states read,
    differenced and logged every period) against the same suite run on the two twins separately (two suite
    runs writing their logs), interleaved, best of several repetitions. Goal: at most 10 % more time.
(b) targeted fit: a MuJoCo twin pair with one injected mismatch, pole damping x2 (nominal 0.05, truth 0.1).
    Least squares and CMA-ES with the prediction objective (horizons 1 and 5) against the open-loop objective
    of ``dualtwin.align`` (the suite-run trajectory/DTW objective), from the same start. Reported: simulator
    evaluations (candidate knob settings) until the fit is within 5 % of the truth, evaluations in total,
    the final error, and the simulated control periods (a prediction evaluation replays many short
    rollouts; a suite evaluation runs the whole suite). Goal: within 5 % with fewer evaluations.
(c) conditioning: three knobs (pole damping, pole mass, chassis mass) at the truth. cond(JᵀJ) of the
    residual Jacobian (unit-cube knob coordinates) for the prediction residuals and the open-loop trajectory
    residuals, and cond(H) of the finite-difference Hessian of the scalar objectives (the prediction
    objective ‖r‖², and the open-loop DTW objective that CMA-ES minimises).

The machine is shared (2 cores): wall times carry noise, evaluation counts do not.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.align import GenerationInfo, align
from dualtwin.align.fit import _Problem
from dualtwin.align.knobs import select_knobs, unit_from_values
from dualtwin.align.objective import build_spec, evaluate
from dualtwin.align.prediction import PredictionEvaluator, PredictionJob, PredictionProblem
from dualtwin.align.simulate import Evaluator, SimJob, load_traces
from dualtwin.robots.binding import BUNDLED, RobotBinding, load_binding, resolve_robot
from dualtwin.suite.runner import SuiteRun
from dualtwin.sync import run_lockstep
from dualtwin.sync.record import record_trajectories, save_trajectories
from dualtwin.twins import make_twin

DAMPING = "joint.pole_hinge.damping"
NOMINAL, TRUTH = 0.05, 0.1
OVERHEAD_GOAL = 0.10
SUITE = BUNDLED / "cartpole" / "suite.json"
FIT_SUITE = {
    "suite_name": "bench_sync",
    "global_settings": {"TIME_STEP": 32},
    "scenarios": [
        {"name": "fall", "duration_s": 1.5, "initial_angle": 0.2},
        {"name": "sine", "duration_s": 1.5, "initial_angle": -0.1,
         "wheel_velocity": {"kind": "sine", "amplitude": 6.0, "frequency_hz": 0.7}},
        {"name": "drive", "duration_s": 1.5, "initial_angle": 0.05, "wheel_velocity": 4.0},
    ],
}


# ------------------------------------------------------------------ (a) overhead
def _separate(root: Path, robot: RobotBinding) -> float:
    start = time.perf_counter()
    for name in ("webots", "mujoco"):
        twin = make_twin(name, robot)
        try:
            SuiteRun(SUITE, name, robot, root / name, twin=twin).run()
        finally:
            twin.close()
    return time.perf_counter() - start


def _lockstep(root: Path, robot: RobotBinding) -> float:
    start = time.perf_counter()
    run_lockstep("webots", "mujoco", robot, suite=SUITE, out_dir=root / "lockstep")
    return time.perf_counter() - start


def overhead(repeats: int = 8) -> dict[str, Any]:
    """Interleaved pairs (the order alternates), so load from other work on the machine hits both alike.

    Reported: the ratio of the best times, and the median of the per-pair ratios (robust to a busy moment).
    """
    robot = resolve_robot("cartpole")
    separate, lockstep, ratios = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats + 1):
            order = (_separate, _lockstep) if i % 2 == 0 else (_lockstep, _separate)
            pair = {}
            for fn in order:
                folder = Path(tmp) / f"{i}_{fn.__name__}"
                pair[fn.__name__] = fn(folder, robot)
                shutil.rmtree(folder)
            if i:  # the first pair warms caches (world parsing, imports)
                separate.append(pair["_separate"])
                lockstep.append(pair["_lockstep"])
                ratios.append(pair["_lockstep"] / pair["_separate"])
    best_sep, best_lock = min(separate), min(lockstep)
    return {"separate_s": separate, "lockstep_s": lockstep, "best_separate_s": best_sep, "best_lockstep_s": best_lock,
            "overhead": best_lock / best_sep - 1.0, "median_overhead": statistics.median(ratios) - 1.0}


# ------------------------------------------------------------------ robots and references
def damped_robot(folder: Path) -> RobotBinding:
    """The cart-pole with a nominal pole damping of 0.05 (the model we start from)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("binding.yaml", "cartpole.wbt"):
        shutil.copy(BUNDLED / "cartpole" / name, folder / name)
    xml = (BUNDLED / "cartpole" / "cartpole.xml").read_text(encoding="utf-8")
    xml = re.sub(r'(<joint name="pole_hinge"[^>]*?)damping="0"', rf'\1damping="{NOMINAL}"', xml)
    (folder / "cartpole.xml").write_text(xml, encoding="utf-8")
    return load_binding(folder / "binding.yaml")


def _within(fitted: float) -> bool:
    return abs(fitted - TRUTH) / TRUTH < 0.05


# ------------------------------------------------------------------ (b) targeted fit
def targeted_fit(root: Path, robot: RobotBinding, suite: Path) -> list[dict[str, Any]]:
    rows = []
    for objective in ("prediction", "trajectory"):
        for optimizer in ("lsq", "cma"):
            reached: list[int] = []

            def watch(info: GenerationInfo, reached: list[int] = reached) -> None:
                if not reached and _within(info.best_knobs.get(DAMPING, math.nan)):
                    reached.append(info.evaluations)

            extra: dict[str, Any] = {"objective": objective}
            if optimizer == "cma":
                extra["popsize"] = 6
            start = time.perf_counter()
            result = align("mujoco", "mujoco", robot, suite, [DAMPING], root / f"{objective}_{optimizer}",
                           optimizer=optimizer, reference_knobs={DAMPING: TRUTH}, executor="serial", budget=200,
                           seed=1, callback=watch, **extra)
            seconds = time.perf_counter() - start
            record = json.loads((result.out_dir / "align_record.json").read_text())
            periods = record.get("simulated_periods")
            if periods is None:  # suite runs: every evaluation simulates the whole suite
                periods = result.evaluations * sum(math.ceil(s["duration_s"] / 0.032 - 1e-9)
                                                   for s in FIT_SUITE["scenarios"])
            fitted = result.fitted[DAMPING]
            rows.append({"objective": objective, "optimizer": optimizer, "fitted": fitted,
                         "error": abs(fitted - TRUTH) / TRUTH, "within_5pct": _within(fitted),
                         "evaluations_to_5pct": reached[0] if reached else None, "evaluations": result.evaluations,
                         "simulated_periods": periods, "seconds": seconds, "stop": result.stop_reason})
    return rows


# ------------------------------------------------------------------ (c) conditioning
def _condition(matrix: np.ndarray) -> float:
    eig = np.linalg.eigvalsh((matrix + matrix.T) / 2)
    return float(eig.max() / eig.min()) if eig.min() > 0 else math.inf


def _jacobian(residual: Callable[[list[list[float]]], list[np.ndarray]], u: list[float], h: float) -> np.ndarray:
    points = [list(u)] + [[*u[:i], u[i] + h, *u[i + 1:]] for i in range(len(u))] + \
             [[*u[:i], u[i] - h, *u[i + 1:]] for i in range(len(u))]
    r = residual(points)
    n = len(u)
    return np.stack([(r[1 + i] - r[1 + n + i]) / (2 * h) for i in range(n)], axis=1)


def _hessian(value: Callable[[list[list[float]]], list[float]], u: list[float], h: float) -> np.ndarray:
    n = len(u)
    points = []
    for i in range(n):
        for j in range(n):
            for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                p = list(u)
                p[i] += si * h
                p[j] += sj * h
                points.append(p)
    f = value(points)
    hess = np.zeros((n, n))
    k = 0
    for i in range(n):
        for j in range(n):
            hess[i, j] = (f[k] - f[k + 1] - f[k + 2] + f[k + 3]) / (4 * h * h)
            k += 4
    return hess


def _eig(matrix: np.ndarray) -> list[float]:
    return [float(v) for v in np.linalg.eigvalsh((matrix + matrix.T) / 2)]


def conditioning(root: Path, robot: RobotBinding, suite: Path, steps: Sequence[float] = (0.01, 0.03)) -> dict[str, Any]:
    """Condition numbers at the truth, for finite-difference steps ``steps`` (unit-cube coordinates).

    Two steps because the residuals are rough at small scales (motor saturation switching, contacts): a
    condition number that changes with the step is a property of the step as much as of the objective.
    """
    from dualtwin.align.objective import ObjectiveWeights
    from dualtwin.suite.loader import load_suite

    knobs = [DAMPING, "body.pole.mass", "body.cart.mass"]
    twin = make_twin("mujoco", robot)
    try:
        specs = select_knobs(twin.knobs(), knobs)
        truth_values = {DAMPING: TRUTH}
        twin.set_knobs(truth_values)
        trajectories = record_trajectories(twin, robot, load_suite(suite))
        SuiteRun(suite, "mujoco", robot, root / "reference_run", twin=twin).run()
    finally:
        twin.close()
    u = unit_from_values(specs, truth_values)
    ref = save_trajectories(root / "reference.npz", trajectories)
    reference = load_traces(root / "reference_run")
    ids = list(reference)
    sim = SimJob(str(robot.path), "mujoco", str(suite.resolve()), tuple(ids))
    dtw_spec = build_spec(reference, ids, weights=ObjectiveWeights(dtw=1.0, event=0.0, endpoint=0.0))
    out: dict[str, Any] = {"knobs": knobs, "by_step": {}}
    job = PredictionJob(str(robot.path), "mujoco", 0.032, str(ref), (1, 5), 5, ())
    with PredictionEvaluator("serial") as pred_eval, Evaluator("serial") as sim_eval:
        problem = PredictionProblem(specs, job, pred_eval, 10_000)
        open_loop = _Problem(specs, sim, build_spec(reference, ids), None, sim_eval, 10_000)

        def dtw_values(pts: list[list[float]]) -> list[float]:
            return [evaluate(dtw_spec, traces).total for traces in sim_eval.map(
                [sim.with_knobs(open_loop.values(p)) for p in pts])]

        for step in steps:
            jac_pred = _jacobian(lambda pts: [p.residual for p in problem.run(pts)], u, step)
            hess_pred = _hessian(lambda pts: [p.train for p in problem.run(pts)], u, step)
            jac_ol = _jacobian(lambda pts: [p.residual for p in open_loop.run(pts)], u, step)
            hess_dtw = _hessian(dtw_values, u, step)
            out["by_step"][str(step)] = {
                # At the truth the residuals vanish, so the Hessian of ‖r‖² is exactly 2JᵀJ (Gauss-Newton).
                "prediction": {"cond_JtJ": _condition(jac_pred.T @ jac_pred), "eig_2JtJ": _eig(2 * jac_pred.T @ jac_pred),
                               "cond_fd_hessian": _condition(hess_pred), "eig_fd_hessian": _eig(hess_pred)},
                "open_loop_trajectory": {"cond_JtJ": _condition(jac_ol.T @ jac_ol), "eig_2JtJ": _eig(2 * jac_ol.T @ jac_ol)},
                "open_loop_dtw": {"cond_fd_hessian": _condition(hess_dtw), "eig_fd_hessian": _eig(hess_dtw)},
            }
    return out


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def _table(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> str:
    lines = ["  ".join(f"{c:>20}" for c in columns)]
    lines += ["  ".join(f"{_fmt(r[c]):>20}" for c in columns) for r in rows]
    return "\n".join(lines)


def main() -> None:
    print("== bench_sync: lockstep overhead, targeted fit, conditioning (shared 2-core machine) ==")
    a = overhead()
    print(f"(a) CartPole suite ({SUITE.name}), Webots + MuJoCo: separately best {a['best_separate_s']:.3f} s, "
          f"in lockstep best {a['best_lockstep_s']:.3f} s -> overhead {a['overhead'] * 100:+.1f} % "
          f"(median {a['median_overhead'] * 100:+.1f} %; goal <= {OVERHEAD_GOAL * 100:.0f} %: "
          f"{'met' if a['overhead'] <= OVERHEAD_GOAL else 'NOT met'})")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        robot = damped_robot(root / "robot")
        suite = root / "suite.json"
        suite.write_text(json.dumps(FIT_SUITE), encoding="utf-8")
        rows = targeted_fit(root / "fits", robot, suite)
        print(f"(b) pole damping x2 (nominal {NOMINAL}, truth {TRUTH}), MuJoCo <- MuJoCo, from the nominal model:")
        print(_table(rows, ["objective", "optimizer", "fitted", "error", "evaluations_to_5pct", "evaluations",
                            "simulated_periods", "seconds"]))
        c = conditioning(root / "cond", robot, suite)
        print(f"(c) conditioning at the truth over {', '.join(c['knobs'])} (unit-cube coordinates; eigenvalues in []):")
        for step, r in c["by_step"].items():
            print(f"    finite-difference step {step}:")
            print(f"      prediction objective:     cond(JᵀJ) = {r['prediction']['cond_JtJ']:.3g} "
                  f"{[round(v, 4) for v in r['prediction']['eig_2JtJ']]}, "
                  f"FD Hessian cond = {r['prediction']['cond_fd_hessian']:.3g}")
            print(f"      open-loop trajectory LSQ: cond(JᵀJ) = {r['open_loop_trajectory']['cond_JtJ']:.3g} "
                  f"{[round(v, 4) for v in r['open_loop_trajectory']['eig_2JtJ']]}")
            print(f"      open-loop DTW objective:  FD Hessian cond = {r['open_loop_dtw']['cond_fd_hessian']:.3g} "
                  f"{[round(v, 4) for v in r['open_loop_dtw']['eig_fd_hessian']]}")
    print(json.dumps({"overhead": a, "fit": rows, "conditioning": c}, default=str))


if __name__ == "__main__":
    main()
