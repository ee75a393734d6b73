"""Alignment goals of issue 15 (recordings, nuisance knobs, ensembles), each measured once, with controls.

Run: ``python bench/bench_align_goals.py`` (all parts) or ``--parts floor,paper,recording``.
Set ``DUALTWIN_BENCH_ALIGN_GOALS_OUT=DIR`` to keep the runs.

* ``floor``: the bundled MuJoCo CartPole aligned to the Webots twin (the setup of ``bench_align.py``: least
  squares on the pole angle, ``05_Sine_Drive`` held out), once on the single Webots trajectory and once on
  the ensemble mean (``ensemble="mean"``, 3 members at ±10 µrad). Goal: every fitted scenario's pole DTW
  after the fit within 1.5× its reproducibility floor (the larger of the two twins' floors, from
  ``dualtwin.divergence.floor.simulate_floor`` with the initial angle moved by ±1 µrad and by ±10 µrad), or
  the scenarios beyond it named by align (``align_record.json``: ``result.floor_check.beyond``) and left out with
  the user's consent (``exclude``): the mean fit runs once more without them.
* ``paper``: the paper-like mismatch (pole damping 0.08, floor friction ×0.8 in the MuJoCo twin) fitted on the
  ensemble mean. Goal: pole-fall DTW (single trajectories, as before) cut by >= 90 %.
* ``recording``: the Webots twin with known physics (pole damping 0.03, pole mass ×1.25) records the suite
  with an unknown kick of the pole (a random initial rate) in every scenario where the pole starts free. The
  logs are written in the paper's format with values rounded to 3 decimals, wall-clock stamps with 2 ms
  jitter, logging one control period late, and imported with ``dualtwin.recorded.import_paper``. The
  Webots twin (nominal) is aligned to it by least squares with nuisance knobs (those scenarios' initial pole
  rate, one shared time offset) and, as the control, without them. Goals: pole-fall crossing-time error
  <= 0.05 s, the driven scenarios' cart speed within 5 % and of the same sign, every fitted physics knob
  within its 95 % interval of the true value.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from _common import output_folder
from bench_align import SUITE, paper_like_robot
from dualtwin.align import AlignConfig, run_align
from dualtwin.align.nuisance import SHARED_TIME_OFFSET
from dualtwin.align.objective import build_spec, residuals
from dualtwin.align.simulate import load_traces, simulate_twin
from dualtwin.demo import CHANNELS, HOLDOUT, KNOBS
from dualtwin.divergence import compare_runs
from dualtwin.divergence.floor import simulate_floor
from dualtwin.divergence.metrics import Threshold, crossing_time
from dualtwin.robots.binding import BUNDLED, RobotBinding, load_binding
from dualtwin.suite.ensemble import EnsembleRun, make_spec
from dualtwin.suite.loader import load_suite
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

BINDING = BUNDLED / "cartpole" / "binding.yaml"
FALL = "00_Step_Response"
POLE = "pole_angle_rad"
EPS = (1e-6, 1e-5)
ENSEMBLE = {"members": 3, "perturb": {"initial_angle": 1e-5}}
#: The pole angle's resolution (the binding's default for rad channels): differences below it never rank.
RESOLUTION_RAD = 1e-3


def pole_dtw(reference: Path, run: Path) -> dict[str, float]:
    return {s.id: s.channels[POLE].dtw for s in compare_runs(reference, run).scenarios}


def floors(robot: RobotBinding) -> dict[float, dict[str, float]]:
    """Per eps and scenario: the larger of the two twins' pole-angle DTW floors (mean of the ± members)."""
    out: dict[float, dict[str, float]] = {}
    for eps in EPS:
        per_twin = {twin: simulate_floor(robot, twin, SUITE, {"initial_angle": eps}, members=3, channels=[POLE])
                    for twin in ("webots", "mujoco")}
        out[eps] = {sid: max(per_twin[t][sid][POLE].dtw for t in per_twin) for sid in per_twin["webots"]}
        for twin, floor in per_twin.items():
            print(f"   {twin:<7} floor ±{eps * 1e6:.0f} µrad: "
                  + ", ".join(f"{sid} {f[POLE].dtw:.4g}" for sid, f in floor.items()))
    return out


def ensemble_reference(robot: RobotBinding, out: Path) -> Path:
    spec = make_spec(ENSEMBLE["members"], ENSEMBLE["perturb"], robot)  # type: ignore[arg-type]
    EnsembleRun(SUITE, "webots", robot, out, spec).run()
    return out


def fit(reference: Path, binding: Path, out: Path, ensemble: str, exclude: tuple[str, ...] = ()
        ) -> tuple[dict[str, float], dict[str, float], float]:
    """Before and after pole DTW per scenario (single trajectories against the reference's member 0)."""
    start = time.perf_counter()
    config = AlignConfig(reference=str(reference), target="mujoco", robot=str(load_binding(binding).path),
                         suite=str(SUITE), knobs=list(KNOBS), optimizer="lsq", budget=300, holdout=HOLDOUT,
                         channels=CHANNELS, ensemble=ensemble, exclude=list(exclude))  # type: ignore[arg-type]
    result = run_align(config, out)
    wall = time.perf_counter() - start
    print(f"   {ensemble:<4} fit{' without ' + ', '.join(exclude) if exclude else ''}: {result.evaluations} "
          f"candidates, {wall:.0f} s; " + ", ".join(f"{k} {v.fitted:.4g}" for k, v in result.knobs.items()))
    return pole_dtw(reference, out / "runs" / "before"), pole_dtw(reference, out / "runs" / "after"), wall


def floor_table(reference: Path, out: Path, floor: dict[float, dict[str, float]], train: list[str]) -> dict[float, bool]:
    """Print before/after pole DTW against the floors; True per eps when every fitted scenario is within 1.5x.

    The last column says whether the after-fit pole difference (DTW per sample) is below the pole channel's
    1 mrad resolution: a floor far below the resolution (a pole resting on its stop) asks for agreement that
    no log can show, so those rows are marked rather than hidden.
    """
    before, after = (pole_dtw(reference, out / "runs" / phase) for phase in ("before", "after"))
    rms = {s.id: s.channels[POLE].dtw_rms for s in compare_runs(reference, out / "runs" / "after").scenarios}
    print(f"   {'scenario':<20}{'before':>9}{'after':>9}{'floor 1µ':>10}{'ratio':>9}{'floor 10µ':>11}{'ratio':>8}"
          f"{'after, per sample':>19}")
    ok = dict.fromkeys(EPS, True)
    for sid in train:
        ratios = {eps: after[sid] / max(floor[eps][sid], 1e-12) for eps in EPS}
        for eps in EPS:
            ok[eps] &= ratios[eps] <= 1.5
        below = "below 1 mrad" if rms[sid] < RESOLUTION_RAD else ""
        print(f"   {sid:<20}{before[sid]:9.4f}{after[sid]:9.4f}{floor[EPS[0]][sid]:10.3g}{ratios[EPS[0]]:9.2f}"
              f"{floor[EPS[1]][sid]:11.3g}{ratios[EPS[1]]:8.2f}{1000 * rms[sid]:10.3f} mrad {below}")
    print(f"   every fitted scenario within 1.5x its floor: ±1 µrad {ok[EPS[0]]}, ±10 µrad {ok[EPS[1]]}")
    return ok


def part_floor(root: Path, reference: Path) -> dict[str, object]:
    robot = load_binding(BINDING)
    print("-- bundled pair: pole DTW after alignment against the reproducibility floor (goal <= 1.5x)")
    floor = floors(robot)
    train = [s for s in load_suite(SUITE).scenario_ids() if s not in HOLDOUT]
    verdict: dict[str, object] = {}
    named: dict[str, str] = {}
    for ensemble in ("off", "mean"):
        out = root / f"bundled_{ensemble}"
        fit(reference, BINDING, out, ensemble)
        verdict[ensemble] = floor_table(reference, out, floor, train)
        named = beyond_named(out)
        verdict[f"{ensemble}_named"] = sorted(named)
    # The goal's other branch: the scenarios align named as beyond the target's floor, left out with consent
    # (--exclude), and the others fitted again
    if named:
        out = root / "bundled_mean_excluded"
        fit(reference, BINDING, out, "mean", tuple(sorted(named)))
        record = json.loads((out / "align_record.json").read_text())["result"]
        print(f"   the record says: excluded {record.get('excluded')}")
        verdict["mean_excluded"] = floor_table(reference, out, floor, [s for s in train if s not in named])
    return verdict


def beyond_named(out: Path) -> dict[str, str]:
    """What align itself named in ``align_record.json`` as beyond the target's reproducibility floor, and why."""
    record = json.loads((out / "align_record.json").read_text())["result"]
    beyond = dict((record.get("floor_check") or {}).get("beyond") or {})
    for sid, why in beyond.items():
        print(f"   align named {sid}: {why}")
    if not beyond:
        print("   align named no scenario beyond the floor")
    for sid, why in ((record.get("floor_check") or {}).get("within_resolution") or {}).items():
        print(f"   align named {sid} above the floor within its channels' resolution: {why}")
    return beyond


#: The knobs that undo the paper-like mismatch (pole damping back to nominal, floor friction x 1/0.8); the other
#: knobs at nominal. Not a zero of the criterion: the engines still differ (the bundled pair's own mismatch).
PAPER_TRUTH = {"joint.pole_hinge.damping": 0.0, "geom.floor.friction": 1.0}
ENSEMBLE_MODES = ("off", "mean", "members")


def part_paper(root: Path, reference: Path) -> dict[str, float]:
    print("-- paper-like mismatch: pole-fall DTW cut (goal >= 90 %)")
    folder = root / "paper_like"
    folder.mkdir(exist_ok=True)
    binding = paper_like_robot(folder)
    out: dict[str, float] = {}
    for ensemble in ENSEMBLE_MODES:
        before, after, _ = fit(reference, binding, root / f"paper_{ensemble}", ensemble)
        cut = 1 - after[FALL] / before[FALL]
        print(f"   {ensemble:<7} pole-fall DTW {before[FALL]:.4f} -> {after[FALL]:.4f}: cut {cut:.1%}")
        out[ensemble] = cut
    paper_control(root, reference, binding)
    return out


def paper_control(root: Path, reference: Path, binding: Path) -> None:
    """Each fit's knobs, the truth's and the nominal twin's under all three criteria (residual norm², the fitted
    scenarios), and the fall's pole DTW member by member (each target member run with its reference member's
    shift): which criterion prefers which knobs, and whether a fit is good for one member or for all."""
    from dualtwin.align.ensemble import member_spec
    from dualtwin.align.objective import mean_trace
    from dualtwin.align.simulate import SimJob, ensemble_offsets, load_member_traces, simulate

    offsets = ensemble_offsets(reference)
    members = load_member_traces(reference)
    single = load_traces(reference)
    train = [s for s in single if s not in HOLDOUT]
    mean_ref = {**single, **{sid: mean_trace(m) for sid, m in members.items()}}
    spec_mean = build_spec(mean_ref, train, CHANNELS)
    spec_single = member_spec(spec_mean, members, 0)
    spec_members = [member_spec(spec_mean, members, k) for k in range(len(offsets))]
    points: dict[str, dict[str, float]] = {"nominal": {}, "truth": PAPER_TRUTH}
    for mode in ENSEMBLE_MODES:
        record = json.loads((root / f"paper_{mode}" / "align_record.json").read_text())
        points[f"fit {mode}"] = {k: v["fitted"] for k, v in record["result"]["knobs"].items()}
    print(f"   control: criteria at each point (single | mean | members) and the fall's pole DTW per member "
          f"(truth: {PAPER_TRUTH}, other knobs nominal)")
    for label, knobs in points.items():
        job = SimJob(str(load_binding(binding).path), "mujoco", str(SUITE.resolve()), tuple(single),
                     tuple(sorted(knobs.items())))
        runs = [simulate(job.with_offsets(o)) for o in offsets]
        mean_run = {sid: mean_trace([r[sid] for r in runs]) for sid in single}
        r_single = residuals(spec_single, runs[0])
        r_mean = residuals(spec_mean, mean_run)
        r_members = np.concatenate([residuals(s, r) for s, r in zip(spec_members, runs, strict=True)])
        per_member = [compare_traces(members[FALL][k], runs[k][FALL]) for k in range(len(offsets))]
        shown = ", ".join(f"{k.split('.', 1)[1]} {v:.4g}" for k, v in knobs.items() if k != "physics.substeps")
        print(f"   {label:<12} {r_single @ r_single:9.3g} | {r_mean @ r_mean:9.3g} | "
              f"{r_members @ r_members / len(offsets):9.3g}   fall DTW " + ", ".join(f"{d:.4f}" for d in per_member)
              + (f"   ({shown})" if shown else ""))


def compare_traces(a: Any, b: Any) -> float:
    """Pole DTW (as the divergence report computes it) of two scenario traces."""
    from dualtwin.divergence.metrics import dtw_distance, finite_prefix, resample_common

    sa, sb = a.series[POLE], b.series[POLE]
    common = resample_common(*finite_prefix(sa.t, sa.y), *finite_prefix(sb.t, sb.y))
    return dtw_distance(common.a, common.b).distance


# ------------------------------------------------------------------ recording
KICK_KEY = "initial_angular_velocity"


def write_paper_logs(run: Path, folder: Path, period: float, rng: np.random.Generator) -> None:
    """The run's ground truth in the paper's format, degraded like a real orchestrator's log."""
    folder.mkdir(parents=True, exist_ok=True)
    for i, sid in enumerate(load_suite(SUITE).scenario_ids()):
        table = np.genfromtxt(run / "scenarios" / sid / "ground_truth.tsv", names=True, delimiter="\t")
        t, pole, cart = (np.atleast_1d(table[c]) for c in ("time_s", POLE, "cart_pos_m"))
        # Logging starts one control period late; stamps are wall clock with 2 ms jitter; 3 decimals.
        t, pole, cart = t[1:], pole[1:], cart[1:]
        wall = 1_700_000_000.0 + 100.0 * i + t + rng.uniform(-0.002, 0.002, size=t.size)
        rows = [f"{w:.4f}\t{p:.3f}\t{c:.3f}" for w, p, c in zip(wall, pole, cart, strict=True)]
        (folder / f"simulation_log_SUP_{i}.tsv").write_text("time_s\tpole_angle_rad\tcart_pos_m\n"
                                                            + "\n".join(rows) + "\n")


def kicked_suite(folder: Path, kicks: dict[str, float]) -> Path:
    doc = json.loads(SUITE.read_text())
    ids = load_suite(SUITE).scenario_ids()
    for sid, kick in kicks.items():
        doc["scenarios"][ids.index(sid)][KICK_KEY] = kick
    path = folder / "suite_kicked.json"
    path.write_text(json.dumps(doc))
    return path


def cart_speed(t: np.ndarray, x: np.ndarray) -> float:
    return float(np.polyfit(t, x, 1)[0])


#: The recording's first seed keeps issue 15's truth (damping 0.03, pole mass x1.25); others draw it.
FIRST_SEED = 15


def part_recording(root: Path, seed: int = FIRST_SEED, control: bool = True) -> dict[str, object]:
    print(f"-- recording of the Webots twin (seed {seed}), imported from the paper's format, aligned with "
          "nuisance knobs")
    from dualtwin.recorded import import_paper

    robot = load_binding(BINDING)
    suite = load_suite(SUITE)
    ids = suite.scenario_ids()
    # The supervisor kicks the pole where it starts free (not resting on its stop at 1 rad).
    fresh = [sid for sid, s in zip(ids, suite.scenarios, strict=True)
             if s.reset == "fresh" and abs(float(s.inputs.get("initial_angle", 0.0))) < 0.99]
    twin = make_twin("webots", robot, suite.global_settings.control_period_s)
    rng = np.random.default_rng(seed)
    damping, mass_scale = (0.03, 1.25) if seed == FIRST_SEED else (float(rng.uniform(0.01, 0.06)),
                                                                  float(rng.uniform(0.8, 1.5)))
    true = {"joint.pole_hinge.damping": damping, "body.pole.mass": mass_scale * twin.knobs()["body.pole.mass"].nominal}
    kicks = {sid: float(rng.uniform(-0.3, 0.3)) for sid in fresh}
    folder = root / ("recording" if seed == FIRST_SEED else f"recording_seed{seed}")
    folder.mkdir(exist_ok=True)
    truth_run = folder / "truth"
    twin.set_knobs(true)
    SuiteRun(kicked_suite(folder, kicks), "webots", robot, truth_run, twin=twin).run()
    twin.close()
    write_paper_logs(truth_run, folder / "paper_logs", suite.global_settings.control_period_s, rng)
    imported = import_paper(folder / "paper_logs", SUITE, robot, folder / "imported")
    print(f"   true physics {true}; kicks (rad/s) " + ", ".join(f"{k} {v:+.3f}" for k, v in kicks.items()))
    reference = load_traces(imported)
    physics = list(true)
    nuisance = [f"scenario.{sid}.{KICK_KEY}" for sid in fresh] + [SHARED_TIME_OFFSET]
    threshold = Threshold(0.99)
    ref_fall = reference[FALL].series[POLE]
    ref_cross = crossing_time(ref_fall.t, ref_fall.y, threshold)
    driven = [sid for sid, s in zip(ids, suite.scenarios, strict=True)
              if isinstance(s.inputs.get("wheel_velocity"), float) and s.inputs["wheel_velocity"] != 0.0]
    results: dict[str, object] = {}
    runs = (("with nuisance knobs", physics + nuisance), ("control: physics only", physics))
    for label, patterns in runs if control else runs[:1]:
        start = time.perf_counter()
        bounds = {"body.pole.mass": (0.5 * true["body.pole.mass"], 2 * true["body.pole.mass"]),
                  "joint.pole_hinge.damping": (0.0, 0.1)}
        config = AlignConfig(reference=str(imported), target="webots", robot=str(robot.path), suite=str(SUITE),
                             knobs=list(patterns), optimizer="lsq", budget=400, bounds=bounds)
        result = run_align(config, folder / f"fit_{len(patterns)}")
        wall = time.perf_counter() - start
        values = {**result.fitted, **{k: v.fitted for k, v in result.nuisance.items()}}
        sim_twin = make_twin("webots", robot, suite.global_settings.control_period_s)
        sim = simulate_twin(robot, sim_twin, SUITE, values)
        sim_twin.close()
        fall = sim[FALL].series[POLE]
        cross = crossing_time(fall.t, fall.y, threshold)
        cross_err = abs(cross - ref_cross) if cross is not None and ref_cross is not None else float("inf")
        print(f"   {label}: {result.evaluations} candidates, {wall:.0f} s, stop: {result.stop_reason}")
        print(f"     pole-fall crossing {ref_cross} (recording) vs {cross} (fit): error {cross_err:.4f} s "
              "(goal <= 0.05 s)")
        speeds_ok = True
        for sid in driven:
            ref_c, fit_c = reference[sid].series["cart_pos_m"], sim[sid].series["cart_pos_m"]
            v_ref, v_fit = cart_speed(ref_c.t, ref_c.y), cart_speed(fit_c.t, fit_c.y)
            rel = abs(v_fit - v_ref) / abs(v_ref)
            speeds_ok &= rel <= 0.05 and np.sign(v_fit) == np.sign(v_ref)
            print(f"     {sid:<18} cart speed {v_ref:+.4f} (recording) vs {v_fit:+.4f} m/s (fit): {rel:.2%} "
                  "(goal <= 5 %, same sign)")
        print(f"     stop reason: {result.stop_reason}")
        for line in result.identifiability.get("before", {}).get("advice", []):
            print(f"     before the fit: {line}")
        for pair in result.identifiability.get("after", {}).get("correlated", []):
            print(f"     after the fit: {pair['knobs'][0]} and {pair['knobs'][1]} correlated, r = {pair['r']:+.3f}")
        inside = True
        for name, knob in result.knobs.items():
            lo, hi = knob.interval_95 if knob.interval_95 is not None else (-np.inf, np.inf)
            ok = lo <= true[name] <= hi
            inside &= ok
            print(f"     {name:<26} true {true[name]:.5g}, fitted {knob.fitted:.5g}, 95 % [{lo:.4g}, {hi:.4g}] "
                  f"({knob.method}): {'inside' if ok else 'OUTSIDE'}")
        for name, knob in result.nuisance.items():
            sid = name.split(".")[1]
            truth = kicks.get(sid) if name.endswith(KICK_KEY) else None
            print(f"     {name:<46} fitted {knob.fitted:+.4f}{'' if truth is None else f' (true {truth:+.4f})'}")
        # Is a miss the optimiser's (a local minimum) or the data's? The criterion at the true values tells.
        spec = build_spec(reference, [s for s in ids if s in reference], ["pole_angle_rad", "cart_pos_m"])
        at_truth = {**true, **{f"scenario.{sid}.{KICK_KEY}": k for sid, k in kicks.items()},
                    SHARED_TIME_OFFSET: suite.global_settings.control_period_s}
        sim_twin = make_twin("webots", robot, suite.global_settings.control_period_s)
        r_truth = residuals(spec, simulate_twin(robot, sim_twin, SUITE, at_truth))
        sim_twin.close()
        r_fit = residuals(spec, sim)
        print(f"     least-squares criterion |r|²: fitted {float(r_fit @ r_fit):.3g}, at the true values "
              f"{float(r_truth @ r_truth):.3g}")
        # The fit's own criterion (its scenarios, channels and weights) at its end and at the true values.
        own = result.residual_after
        at_true = fit_criterion_at(folder / f"fit_{len(patterns)}", at_truth, robot, suite)
        print(f"     the fit's own criterion: at its end {own:.4g}, at the true values {at_true:.4g} "
              f"(goal: end <= truth: {own <= at_true * (1 + 1e-9)})")
        # Is the truth the bottom of a basin the search missed, or a needle? The same criterion with each
        # physics knob moved by 0.2 % of its range from the truth (far below any search's resolution).
        needle = truth_neighbourhood(folder / f"fit_{len(patterns)}", at_truth, robot, suite, bounds)
        print(f"     around the truth (each physics knob ±0.2 % of its range): criterion {min(needle):.4g} to "
              f"{max(needle):.4g}; the fit's end is {'below' if own <= min(needle) else 'within' if own <= max(needle) else 'above'} "
              "that range")
        results[label] = {"crossing_error_s": cross_err, "speeds_ok": speeds_ok, "knobs_inside": inside,
                          "criterion_fit": own, "criterion_truth": at_true, "criterion_near_truth": needle}
        print(f"     goals: crossing {cross_err <= 0.05}, cart speed {speeds_ok}, knobs inside 95 % {inside}")
    return results


def truth_neighbourhood(fit_dir: Path, at_truth: dict[str, float], robot: RobotBinding, suite: Any,
                        bounds: dict[str, tuple[float, float]]) -> list[float]:
    """The fit's criterion with each physics knob moved from its true value by ±0.2 % of its bounds' range."""
    out = []
    for name, (lo, hi) in bounds.items():
        for sign in (-1.0, 1.0):
            moved = {**at_truth, name: at_truth[name] + sign * 0.002 * (hi - lo)}
            out.append(fit_criterion_at(fit_dir, moved, robot, suite))
    return out


def fit_criterion_at(fit_dir: Path, values: dict[str, float], robot: RobotBinding, suite: Any) -> float:
    """The residual norm² a fit minimised (its own training scenarios and channels), at knob values ``values``
    (only the knobs the fit had; the others at nominal)."""
    record = json.loads((fit_dir / "align_record.json").read_text())
    names = {s["name"] for s in record["knob_specs"]}
    chosen = {k: v for k, v in values.items() if k in names}
    reference = load_traces(Path(record["inputs"]["reference"]["path"]))
    train = [s for s in reference if s not in record["config"]["holdout"]]
    spec = build_spec(reference, train, record["config"]["channels"])
    twin = make_twin("webots", robot, suite.global_settings.control_period_s)
    try:
        r = residuals(spec, simulate_twin(robot, twin, SUITE, chosen))
    finally:
        twin.close()
    return float(r @ r)


def main(parts: list[str] | None = None, seeds: tuple[int, ...] = (FIRST_SEED,), control: bool = True
         ) -> dict[str, object]:
    parts = parts or ["floor", "paper", "recording"]
    results: dict[str, object] = {}
    with output_folder("DUALTWIN_BENCH_ALIGN_GOALS_OUT", "align-goals") as (root, _):
        print("== alignment goals (issue 15): reproducibility floor, ensembles, a recording ==")
        reference = root / "webots_ensemble"
        if {"floor", "paper"} & set(parts) and not (reference / "manifest.json").is_file():
            ensemble_reference(load_binding(BINDING), reference)
        if "floor" in parts:
            results["floor"] = part_floor(root, reference)
        if "paper" in parts:
            results["paper"] = part_paper(root, reference)
        if "recording" in parts:
            for seed in seeds:
                results[f"recording seed {seed}"] = part_recording(root, seed, control)
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--parts", default="floor,paper,recording")
    parser.add_argument("--seeds", default=str(FIRST_SEED),
                        help=f"recording seeds, comma-separated ({FIRST_SEED}: issue 15's truth; others draw the true "
                        "damping in [0.01, 0.06] and pole mass x[0.8, 1.5])")
    parser.add_argument("--no-control", action="store_true", help="recording: skip the physics-only control fit")
    args = parser.parse_args()
    chosen = [p.strip() for p in args.parts.split(",") if p.strip()]
    unknown = sorted(set(chosen) - {"floor", "paper", "recording"})
    if unknown:
        print(f"error: unknown parts {unknown}", file=sys.stderr)
        sys.exit(2)
    try:
        seed_list = tuple(int(x) for x in args.seeds.split(",") if x.strip())
    except ValueError:
        print(f"error: --seeds takes comma-separated integers, got {args.seeds!r}", file=sys.stderr)
        sys.exit(2)
    main(chosen, seed_list or (FIRST_SEED,), not args.no_control)
