"""Synchronisation benchmarks: lockstep overhead, a targeted fit, and how well each objective is posed.

Run: ``python bench/bench_sync.py [--parts overhead,fit,conditioning]`` (or ``make bench``):

(a) overhead: the bundled CartPole suite in lockstep (Webots primary, MuJoCo secondary, ``never``: both states
    read, differenced and logged every period) against the same suite run on the two twins separately (two
    suite runs writing their logs), in interleaved pairs. Process CPU time (what other work on a shared
    machine disturbs least) and wall time; best-of and median of the paired ratios. Goal: at most 10 %.
(b) targeted fit: a MuJoCo twin pair with one injected mismatch, pole damping x2 (nominal 0.05, truth 0.1).
    Least squares and CMA-ES with the prediction objective (horizons 1 and 5) against the open-loop objective
    of ``dualtwin.align`` (the suite-run trajectory/DTW objective), from the same start. Reported: simulator
    evaluations (candidate knob settings) until the fit is within 5 % of the truth, evaluations in total,
    the final error, and the simulated control periods (a prediction evaluation replays many short
    rollouts; a suite evaluation runs the whole suite). Goal: within 5 % with fewer evaluations.
(c) local conditioning at the truth over four knobs with correlated effects (pole damping, pole mass, pole
    inertia, cart mass), unit-cube coordinates: eigenvalues and cond(JᵀJ) of the residual Jacobians, and of
    the finite-difference Hessians of the scalar objectives (prediction ‖r‖², open-loop DTW distance).
(d) global shape: a 1-D profile of both scalar objectives along the damping knob (local minima, roughness).
(e, f) recovery: the same optimiser from the same random starts with the same budget on each objective
    (four knobs; then damping alone and damping with cart mass): how often damping comes within 5 %.

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

from dualtwin.align import AlignConfig, GenerationInfo, run_align
from dualtwin.align.knobs import select_knobs, unit_from_values, values_from_unit
from dualtwin.align.objective import build_spec, evaluate
from dualtwin.align.prediction import PredictionEvaluator, PredictionJob, PredictionProblem
from dualtwin.align.simulate import Evaluator, SimJob, load_traces
from dualtwin.align.trajectory import TrajectoryProblem
from dualtwin.divergence.trajectories import record_trajectories, save_trajectories
from dualtwin.robots.binding import BUNDLED, RobotBinding, load_binding, resolve_robot
from dualtwin.suite.runner import SuiteRun
from dualtwin.sync import run_lockstep
from dualtwin.twins import make_twin

DAMPING = "joint.pole_hinge.damping"
NOMINAL, TRUTH = 0.05, 0.1
OVERHEAD_GOAL = 0.10
SUITE = BUNDLED / "cartpole" / "suite.json"
FIT_SUITE: dict[str, Any] = {
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
def _separate(root: Path, robot: RobotBinding) -> None:
    for name in ("webots", "mujoco"):
        twin = make_twin(name, robot)
        try:
            SuiteRun(SUITE, name, robot, root / name, twin=twin).run()
        finally:
            twin.close()


def _lockstep(root: Path, robot: RobotBinding) -> None:
    run_lockstep("webots", "mujoco", robot, suite=SUITE, out_dir=root / "lockstep")


def overhead(repeats: int = 10) -> dict[str, Any]:
    """Interleaved pairs (the order alternates), so load from other work on the machine hits both alike.

    Both runs are single-process (the lockstep log writer is a thread of it), so the process CPU time is the
    cost measure that other processes on a shared machine disturb least; wall time is reported beside it.
    Reported for each: the ratio of the best times and the median of the per-pair ratios.
    """
    robot = resolve_robot("cartpole")
    times: dict[str, dict[str, list[float]]] = {"cpu": {"_separate": [], "_lockstep": []},
                                                "wall": {"_separate": [], "_lockstep": []}}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats + 1):
            order = (_separate, _lockstep) if i % 2 == 0 else (_lockstep, _separate)
            for fn in order:
                folder = Path(tmp) / f"{i}_{fn.__name__}"
                wall, cpu = time.perf_counter(), time.process_time()
                fn(folder, robot)
                cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
                shutil.rmtree(folder)
                if i:  # the first pair warms caches (world parsing, imports)
                    times["cpu"][fn.__name__].append(cpu)
                    times["wall"][fn.__name__].append(wall)
    out: dict[str, Any] = {"repeats": repeats}
    for kind, t in times.items():
        sep, lock = t["_separate"], t["_lockstep"]
        out[kind] = {"separate_s": sep, "lockstep_s": lock, "best_separate_s": min(sep), "best_lockstep_s": min(lock),
                     "overhead": min(lock) / min(sep) - 1.0,
                     "median_overhead": statistics.median(b / a for a, b in zip(sep, lock, strict=True)) - 1.0}
    return out


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
            config = AlignConfig(reference="mujoco", target="mujoco", robot=str(robot.path), suite=str(suite),
                                 knobs=[DAMPING], optimizer=optimizer, reference_knobs={DAMPING: TRUTH},
                                 executor="serial", budget=200, seed=1, **extra)
            result = run_align(config, root / f"{objective}_{optimizer}", callback=watch)
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


KNOBS4 = [DAMPING, "body.pole.mass", "body.pole.inertia_scale", "body.cart.mass"]


class _Objectives:
    """The prediction objective and the open-loop DTW objective of the same twin pair, on unit-cube points.

    The truth is the nominal model with pole damping x2; both objectives see the same suite (the reference is
    recorded once, as trajectories for the prediction objective and as a suite run for DTW).
    """

    def __init__(self, root: Path, robot: RobotBinding, suite: Path, knobs: Sequence[str]) -> None:
        from dualtwin.align.objective import ObjectiveWeights
        from dualtwin.suite.loader import load_suite

        twin = make_twin("mujoco", robot)
        try:
            self.specs = select_knobs(twin.knobs(), knobs)
            twin.set_knobs({DAMPING: TRUTH})
            trajectories = record_trajectories(twin, robot, load_suite(suite))
            SuiteRun(suite, "mujoco", robot, root / "reference_run", twin=twin).run()
        finally:
            twin.close()
        self.truth = unit_from_values(self.specs, {DAMPING: TRUTH})
        ref = save_trajectories(root / "reference.npz", trajectories)
        reference = load_traces(root / "reference_run")
        ids = list(reference)
        self.sim = SimJob(str(robot.path), "mujoco", str(suite.resolve()), tuple(ids))
        self.dtw_spec = build_spec(reference, ids, weights=ObjectiveWeights(dtw=1.0, event=0.0, endpoint=0.0))
        self.job = PredictionJob(str(robot.path), "mujoco", 0.032, str(ref), (1, 5), 5, ())
        self.pred_eval = PredictionEvaluator("serial")
        self.sim_eval = Evaluator("serial")
        self.prediction = PredictionProblem(self.specs, self.job, self.pred_eval, 10**6)
        self.open_loop = TrajectoryProblem(self.specs, self.sim, build_spec(reference, ids), None, self.sim_eval, 10**6)

    def close(self) -> None:
        self.pred_eval.close()
        self.sim_eval.close()

    def scalar(self, name: str, points: Sequence[Sequence[float]]) -> list[float]:
        """``prediction``: ‖r‖² of the multiple-shooting residuals; ``dtw``: the open-loop DTW distance."""
        pts = [[min(1.0, max(0.0, float(x))) for x in p] for p in points]
        if name == "prediction":
            return [p.train for p in self.prediction.run(pts)]
        return [evaluate(self.dtw_spec, traces).total for traces in self.sim_eval.map(
            [self.sim.with_knobs(self.open_loop.values(p)) for p in pts])]

    def residual(self, name: str, points: Sequence[Sequence[float]]) -> list[np.ndarray]:
        return [p.residual for p in (self.prediction if name == "prediction" else self.open_loop).run(points)]


def conditioning(obj: _Objectives, steps: Sequence[float] = (0.01, 0.03)) -> dict[str, Any]:
    """Local conditioning at the truth, for finite-difference steps ``steps`` (unit-cube coordinates).

    The Hessian of each scalar objective (central differences) and cond(JᵀJ) of the residuals. Two steps
    because the open-loop residuals are rough at small scales (motor saturation switching, contacts): a
    condition number that changes with the step is a property of the step as much as of the objective.
    """
    out: dict[str, Any] = {"knobs": [s.name for s in obj.specs], "by_step": {}}
    u = list(obj.truth)
    for step in steps:
        jac_pred = _jacobian(lambda pts: obj.residual("prediction", pts), u, step)
        jac_ol = _jacobian(lambda pts: obj.residual("trajectory", pts), u, step)
        hess_pred = _hessian(lambda pts: obj.scalar("prediction", pts), u, step)
        hess_dtw = _hessian(lambda pts: obj.scalar("dtw", pts), u, step)
        out["by_step"][str(step)] = {
            # At the truth the residuals vanish, so the Hessian of ‖r‖² is exactly 2JᵀJ (Gauss-Newton).
            "prediction": {"cond_JtJ": _condition(jac_pred.T @ jac_pred), "eig_2JtJ": _eig(2 * jac_pred.T @ jac_pred),
                           "cond_fd_hessian": _condition(hess_pred), "eig_fd_hessian": _eig(hess_pred)},
            "open_loop_trajectory": {"cond_JtJ": _condition(jac_ol.T @ jac_ol), "eig_2JtJ": _eig(2 * jac_ol.T @ jac_ol)},
            "open_loop_dtw": {"cond_fd_hessian": _condition(hess_dtw), "eig_fd_hessian": _eig(hess_dtw)},
        }
    return out


def _local_minima(values: Sequence[float] | np.ndarray) -> int:
    v = list(values)
    return sum(1 for i in range(1, len(v) - 1) if v[i] < v[i - 1] and v[i] < v[i + 1])


def profiles(obj: _Objectives, points: int = 41) -> dict[str, Any]:
    """1-D profile of each scalar objective along the damping knob (0.02 to 0.3, the others at the truth):
    local minima, the arg-min, and the roughness (RMS of second differences over the RMS of the values' range),
    which is what makes a 5 % fit hard for an optimiser that needs a smooth descent."""
    spec = obj.specs[0]
    values = np.linspace(0.02, 0.3, points)
    pts = [[spec.to_unit(float(v)), *obj.truth[1:]] for v in values]
    out: dict[str, Any] = {"damping": values.tolist()}
    for name in ("prediction", "dtw"):
        f = np.array(obj.scalar(name, pts))
        second = np.diff(f, 2)
        smooth = np.convolve(f, np.ones(5) / 5, mode="valid")
        out[name] = {"values": f.tolist(), "local_minima": _local_minima(f),
                     "argmin_damping": float(values[int(np.argmin(f))]),
                     "roughness": float(np.sqrt(np.mean((f[2:-2] - smooth) ** 2)) / (f.max() - f.min())),
                     "max_abs_second_difference": float(np.max(np.abs(second)) / (f.max() - f.min()))}
    return out


def multistart(obj: _Objectives, starts: int = 6, budget: int = 120, spread: float = 0.25,
               seed: int = 7) -> dict[str, Any]:
    """The same optimiser on each scalar objective from the same random starts (truth + uniform ±``spread`` in
    every unit-cube coordinate), with the same budget: CMA-ES (step 0.1, population 8) for several knobs,
    Nelder-Mead for one (CMA-ES needs two dimensions). Reported per objective: how often the injected damping
    is recovered within 5 %, how often every knob is, the median relative error of each knob, and the
    evaluations until damping first came within 5 %."""
    import cma
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    x0s = [np.clip(np.array(obj.truth) + rng.uniform(-spread, spread, len(obj.truth)), 0.0, 1.0) for _ in range(starts)]
    truth = {s.name: s.from_unit(x) for s, x in zip(obj.specs, obj.truth, strict=True)}
    method = "cma-es" if len(obj.truth) > 1 else "nelder-mead"
    out: dict[str, Any] = {"starts": starts, "budget": budget, "spread": spread, "method": method, "by_objective": {}}
    for name in ("prediction", "dtw"):
        runs: list[dict[str, Any]] = []
        for i, x0 in enumerate(x0s):
            trace: list[tuple[float, list[float]]] = []  # (value, point) of every evaluation, in order

            def f(points: Sequence[Sequence[float]], trace: list[tuple[float, list[float]]] = trace,
                  name: str = name) -> list[float]:
                values = obj.scalar(name, points)
                trace.extend((v, list(map(float, p))) for v, p in zip(values, points, strict=True))
                return values

            if method == "cma-es":
                es = cma.CMAEvolutionStrategy(x0.tolist(), 0.1, {"bounds": [0.0, 1.0], "popsize": 8, "seed": seed + i,
                                                                 "maxfevals": budget, "verbose": -9})
                while not es.stop() and len(trace) < budget:
                    points = es.ask()
                    es.tell(points, f(points))
            else:
                minimize(lambda x: f([x])[0], x0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(x0),
                         options={"maxfev": budget, "xatol": 1e-4, "fatol": 0.0})
            first, best = None, (math.inf, list(x0))
            for n, (value, point) in enumerate(trace, 1):
                if value < best[0]:
                    best = (value, point)
                    if first is None and abs(values_from_unit(obj.specs, point)[DAMPING] - TRUTH) / TRUTH < 0.05:
                        first = n
            fitted = values_from_unit(obj.specs, best[1])
            errors = {k: abs(fitted[k] - truth[k]) / abs(truth[k]) for k in truth}
            runs.append({"start": x0.tolist(), "errors": errors, "evaluations": len(trace), "evaluations_to_5pct": first})
        out["by_objective"][name] = {
            "damping_within_5pct": sum(r["errors"][DAMPING] < 0.05 for r in runs),
            "all_within_5pct": sum(all(e < 0.05 for e in r["errors"].values()) for r in runs),
            "median_error": {k: float(np.median([r["errors"][k] for r in runs])) for k in truth},
            "median_evaluations_to_5pct": (float(np.median([r["evaluations_to_5pct"] for r in runs
                                                            if r["evaluations_to_5pct"] is not None]))
                                           if any(r["evaluations_to_5pct"] is not None for r in runs) else None),
            "runs": runs}
    return out


def _print_multistart(multi: dict[str, Any]) -> None:
    for name, r in multi["by_objective"].items():
        med = ", ".join(f"{k.split('.')[-2]}.{k.split('.')[-1]} {v * 100:.2g} %" for k, v in r["median_error"].items())
        print(f"      {name:10s}: damping within 5 % in {r['damping_within_5pct']}/{multi['starts']}, every knob in "
              f"{r['all_within_5pct']}/{multi['starts']}; median errors {med}; median evaluations to 5 % on damping "
              f"{_fmt(r['median_evaluations_to_5pct'])}")


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


def main(argv: Sequence[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", default="overhead,fit,conditioning",
                        help="comma-separated subset of overhead, fit, conditioning (default: all)")
    parts = set(parser.parse_args(argv).parts.split(","))
    print("== bench_sync: lockstep overhead, targeted fit, conditioning (shared 2-core machine) ==")
    results: dict[str, Any] = {}
    if "overhead" in parts:
        results["overhead"] = overhead_report()
    if parts & {"fit", "conditioning"}:
        results.update(fits_report(parts))
    print(json.dumps(results, default=str))


def overhead_report() -> dict[str, Any]:
    a = overhead()
    for kind in ("cpu", "wall"):
        r = a[kind]
        print(f"(a) CartPole suite ({SUITE.name}), Webots + MuJoCo, {kind} time, {a['repeats']} interleaved pairs: "
              f"separately best {r['best_separate_s']:.3f} s, in lockstep best {r['best_lockstep_s']:.3f} s -> "
              f"overhead {r['overhead'] * 100:+.1f} % (median of paired ratios {r['median_overhead'] * 100:+.1f} %; "
              f"goal <= {OVERHEAD_GOAL * 100:.0f} %: {'met' if r['median_overhead'] <= OVERHEAD_GOAL else 'NOT met'})")
    return a


def fits_report(parts: set[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        robot = damped_robot(root / "robot")
        suite = root / "suite.json"
        suite.write_text(json.dumps(FIT_SUITE), encoding="utf-8")
        if "fit" in parts:
            rows = out["fit"] = targeted_fit(root / "fits", robot, suite)
            print(f"(b) pole damping x2 (nominal {NOMINAL}, truth {TRUTH}), MuJoCo <- MuJoCo, from the nominal model:")
            print(_table(rows, ["objective", "optimizer", "fitted", "error", "evaluations_to_5pct", "evaluations",
                                "simulated_periods", "seconds"]))
        if "conditioning" not in parts:
            return out
        obj = _Objectives(root / "cond", robot, suite, KNOBS4)
        try:
            c = conditioning(obj)
            prof = profiles(obj)
            multi = multistart(obj)
        finally:
            obj.close()
        print(f"(c) conditioning at the truth over {', '.join(c['knobs'])} (unit-cube coordinates; eigenvalues in []):")
        for step, r in c["by_step"].items():
            print(f"    finite-difference step {step}:")
            print(f"      prediction objective:     cond(JᵀJ) = {r['prediction']['cond_JtJ']:.3g} "
                  f"{[float(f'{v:.3g}') for v in r['prediction']['eig_2JtJ']]}, "
                  f"FD Hessian cond = {r['prediction']['cond_fd_hessian']:.3g}")
            print(f"      open-loop trajectory LSQ: cond(JᵀJ) = {r['open_loop_trajectory']['cond_JtJ']:.3g} "
                  f"{[float(f'{v:.3g}') for v in r['open_loop_trajectory']['eig_2JtJ']]}")
            print(f"      open-loop DTW objective:  FD Hessian cond = {r['open_loop_dtw']['cond_fd_hessian']:.3g} "
                  f"{[float(f'{v:.3g}') for v in r['open_loop_dtw']['eig_fd_hessian']]}")
        print("(d) 1-D profile along pole damping 0.02-0.3 (41 points, other knobs at the truth):")
        for name in ("prediction", "dtw"):
            r = prof[name]
            print(f"      {name:10s}: local minima {r['local_minima']}, arg-min {r['argmin_damping']:.3g} "
                  f"(truth {TRUTH}), roughness {r['roughness']:.3g}")
        print(f"(e) CMA-ES from {multi['starts']} random starts (truth ± {multi['spread']} per unit-cube coordinate), "
              f"{multi['budget']} evaluations each, same starts/step/population for both objectives:")
        _print_multistart(multi)
        smaller = {}
        for knobs in ([DAMPING], [DAMPING, "body.cart.mass"]):
            obj = _Objectives(root / f"cond{len(knobs)}", robot, suite, knobs)
            try:
                smaller[len(knobs)] = multi_k = multistart(obj, starts=8, budget=60, spread=0.4)
            finally:
                obj.close()
            print(f"(f) {multi_k['method']} over {', '.join(knobs)} from {multi_k['starts']} random starts (truth ± "
                  f"{multi_k['spread']}), {multi_k['budget']} evaluations each:")
            _print_multistart(multi_k)
    out.update({"conditioning": c, "profiles": prof, "multistart": multi, "multistart_fewer_knobs": smaller})
    return out


if __name__ == "__main__":
    main()
