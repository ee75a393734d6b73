"""Coverage of alignment's 95 % intervals (issue 24): how often they contain the truth, per knob family and method.

Run: ``python bench/bench_align_coverage.py`` (both parts), ``--parts fast`` (100 fits, 2 processes; or
``--fits 20 --processes 1``) or ``--parts cartpole`` (``--cartpole-fits 20 --cartpole-budget 300``).
Set ``DUALTWIN_BENCH_ALIGN_COVERAGE_OUT=DIR`` to keep the runs and ``coverage.json``.

Part ``fast``: each fit is a known-truth recording of the fake twin (tests/support/fake_twin.py: damped springs driven by
motors, milliseconds per suite run): random true values of three physics knobs (a damping, a mass, a
stiffness, each 0.6-1.6 × nominal), a random initial kick of the first released spring (a nuisance knob,
±0.3 rad/s) and a random logging delay (the shared time offset, ±10 ms). The reference run's logs are then
degraded like a real logger's: Gaussian noise (1 % of each channel's range), rounding to 3 decimals and ±2 ms
jitter on every time stamp. The fake twin at nominal is aligned to it by least squares (basin search, the
default) with the physics and both nuisance knobs, and every knob's 95 % interval is checked against its
truth. The control column is the textbook i.i.d. Jacobian interval of the same fit (what alignment reported
before the effective-sample correction), rescaled from the record.

Part ``cartpole``: the same study on the bundled CartPole, fits alternating between the MuJoCo twin and the
Webots twin (each aligned to its own known-truth recording). Random true pole damping (0.005-0.06 N·m·s/rad,
nominal 0) and pole mass (0.6-1.6 × 0.2 kg), a random initial pole rate in the free fall (±0.3 rad/s, nuisance)
and a random logging delay (±10 ms, nuisance). The suite is the CartPole suite's three scenarios where the pole
moves freely (the fall and the sine drive, their first 2.5 and 3 s), to keep a fit near a minute unloaded; the logs are degraded as in
part ``fast`` and the fit uses the pole angle and the cart position, like the paper's logs.

Goal: 90-99 % coverage for every knob family.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from _common import output_folder
from dualtwin.align import AlignConfig, run_align
from dualtwin.align import run as align_run
from dualtwin.align.objective import build_spec, residuals
from dualtwin.align.simulate import load_traces, simulate_twin
from dualtwin.artifacts import sha256_file, write_json
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.loader import load_suite
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered  # noqa: E402

PHYSICS = {"joint.j1.damping": "damping", "joint.j1.mass": "mass", "joint.j2.stiffness": "stiffness"}
KICK = "scenario.00_release_1.initial_qd1"
OFFSET = "scenario.*.time_offset"
FAMILY = {**PHYSICS, KICK: "nuisance: kick", OFFSET: "nuisance: time offset"}
NOISE, JITTER_S, DECIMALS = 0.01, 0.002, 3


def degrade(run: Path, rng: np.random.Generator, offset_s: float) -> None:
    """Noise, rounding, time-stamp jitter and a logging delay on every log of ``run`` (manifest hashes updated)."""
    manifest = json.loads((run / "manifest.json").read_text())
    for rel, entry in manifest["logs"].items():
        path = run / rel
        lines = path.read_text().splitlines()
        header, rows = lines[0], np.array([[float(x) for x in line.split("\t")] for line in lines[1:]])
        t = rows[:, 0] - offset_s + rng.uniform(-JITTER_S, JITTER_S, rows.shape[0])
        values = rows[:, 1:]
        span = np.ptp(values, axis=0)
        values = values + rng.normal(0.0, 1.0, values.shape) * NOISE * np.where(span > 0, span, 1e-3)
        text = header + "\n" + "\n".join("\t".join([f"{ti:.4f}", *(f"{v:.{DECIMALS}f}" for v in row)])
                                         for ti, row in zip(t, values, strict=True)) + "\n"
        path.write_text(text)
        entry.update({"bytes": path.stat().st_size, "sha256": sha256_file(path)})
    write_json(run / "manifest.json", manifest)


def no_report(*_: object, **__: object) -> Path:
    """The HTML report is not written in this study: its plots cost more than the fit (and say nothing here)."""
    return Path("report.html")


def one_fit(args: tuple[int, str]) -> dict[str, Any]:
    index, root_text = args
    align_run.write_align_report = no_report  # type: ignore[assignment]
    root = Path(root_text) / f"fit_{index:03d}"
    rng = np.random.default_rng(1000 + index)
    with registered():
        robot = load_binding(ROBOT)
        twin = make_twin(NAME, robot, 0.02)
        nominal = {k: twin.knobs()[k].nominal for k in PHYSICS}
        truth = {k: float(v * rng.uniform(0.6, 1.6)) for k, v in nominal.items()}
        kick, offset = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.01, 0.01))
        doc = json.loads(SUITE.read_text())
        doc["scenarios"][0]["initial_qd1"] = kick
        root.mkdir(parents=True, exist_ok=True)
        suite = root / "suite_kicked.json"
        suite.write_text(json.dumps(doc))
        twin.set_knobs(truth)
        SuiteRun(suite, NAME, robot, root / "recording", twin=twin).run()
        twin.close()
        degrade(root / "recording", rng, offset)
        start = time.perf_counter()
        config = AlignConfig(reference=str(root / "recording"), target=NAME, robot=str(ROBOT), suite=str(SUITE),
                             knobs=[*PHYSICS, KICK, OFFSET], optimizer="lsq", budget=160, executor="serial",
                             seed=index)
        result = run_align(config, root / "fit")
        wall = time.perf_counter() - start
    truths = {**truth, KICK: kick, OFFSET: offset}
    return {"index": index, "wall_s": wall, "stop": result.stop_reason,
            "rows": coverage_rows(result, root / "fit", truths, FAMILY), "criterion": result.residual_after}


def coverage_rows(result: Any, fit_dir: Path, truths: dict[str, float], family: dict[str, str]) -> list[dict[str, Any]]:
    """One row per fitted knob: its truth, fitted value, interval and method, and whether the interval holds the
    truth (and whether the textbook i.i.d. Jacobian interval would have)."""
    record = json.loads((fit_dir / "align_record.json").read_text())
    noise = record["result"]["identifiability"]["after"]["noise"]
    p = len(truths)
    t_iid = float(stats.t.ppf(0.975, max(noise["samples"] - p, 1)))
    t_neff = float(stats.t.ppf(0.975, max(noise["dof"], 1)))
    rows = []
    for name, fit in {**result.knobs, **result.nuisance}.items():
        lo, hi = fit.interval_95 if fit.interval_95 is not None else (-math.inf, math.inf)
        truth_v = truths[name]
        row = {"knob": name, "family": family[name], "truth": truth_v, "fitted": fit.fitted, "method": fit.method,
               "interval": [lo, hi], "covered": bool(lo <= truth_v <= hi)}
        if fit.method and fit.method.startswith("jacobian") and fit.half_width_95 is not None:
            iid = fit.half_width_95 * t_iid / t_neff / math.sqrt(noise["inflation"])
            row["covered_iid"] = bool(abs(fit.fitted - truth_v) <= iid)
        rows.append(row)
    return rows


# ------------------------------------------------------------------ cartpole
CARTPOLE = BUNDLED / "cartpole"
#: Two of the CartPole suite's scenarios where the pole moves freely (the others rest it on its stop at 1 rad),
#: cut to their first seconds (the fall reaches the stop within 2 s): a fit costs about a minute unloaded.
CARTPOLE_SCENARIOS = {"00_Step_Response": 2.5, "05_Sine_Drive": 3.0}
POLE_DAMPING, POLE_MASS = "joint.pole_hinge.damping", "body.pole.mass"
CARTPOLE_KICK = "scenario.00_Step_Response.initial_angular_velocity"
CARTPOLE_FAMILY = {POLE_DAMPING: "damping", POLE_MASS: "mass", CARTPOLE_KICK: "nuisance: kick",
                   OFFSET: "nuisance: time offset"}
CARTPOLE_TWINS = ("mujoco", "webots")
#: Simulations per CartPole fit. The fall from upright makes the truth a narrow, curved valley in (kick, time
#: offset, mass, damping): least squares from the best screened start needs 150-200 runs to reach its floor
#: (4 knobs: 5 runs per iteration), so a budget of 100 measured where the budget ran out, not the intervals.
CARTPOLE_BUDGET = 300


def cartpole_suite(folder: Path, kick: float | None) -> Path:
    """The free-pole scenarios of the CartPole suite (with ``kick`` as the fall's initial pole rate)."""
    doc = json.loads((CARTPOLE / "suite.json").read_text())
    ids = load_suite(CARTPOLE / "suite.json").scenario_ids()
    doc["scenarios"] = [{**s, "duration_s": CARTPOLE_SCENARIOS[sid]}
                        for sid, s in zip(ids, doc["scenarios"], strict=True) if sid in CARTPOLE_SCENARIOS]
    if kick is not None:
        doc["scenarios"][0]["initial_angular_velocity"] = kick
    path = folder / ("suite.json" if kick is None else "suite_kicked.json")
    path.write_text(json.dumps(doc))
    return path


def criterion_at(fit_dir: Path, values: dict[str, float], twin_name: str) -> float:
    """The least-squares criterion |r|² the fit minimised (its scenarios, channels, weights) at ``values``: a
    miss where the truth scores lower than the fit's end is the optimiser's (it stopped short of the minimum),
    not the interval's."""
    record = json.loads((fit_dir / "align_record.json").read_text())
    reference = load_traces(Path(record["inputs"]["reference"]["path"]))
    spec = build_spec(reference, [s for s in reference if s not in record["config"]["holdout"]],
                      record["config"]["channels"])
    robot = load_binding(CARTPOLE / "binding.yaml")
    suite = Path(record["config"]["suite"])
    twin = make_twin(twin_name, robot, load_suite(suite).global_settings.control_period_s)
    try:
        r = residuals(spec, simulate_twin(robot, twin, suite, values))
    finally:
        twin.close()
    return float(r @ r)


def explain(fits: list[dict[str, Any]]) -> None:
    """Split the intervals that miss into fits that ended short of the minimum and fits that did not.

    The criterion is rough (the pole's bounces on its stop): it jitters by about the ``jitter`` the intervals
    measure around the fit's end, so an end within that of the truth's criterion is in the truth's basin
    even when the truth scores a little lower."""
    short = [f for f in fits if f["criterion_truth"] < f["criterion"]]
    far = [f for f in short if f["criterion"] - f["criterion_truth"] > f.get("jitter", 0.0)]
    print(f"\n   {len(short)} of {len(fits)} fits ended where the truth scores lower, {len(far)} of them by more than "
          "the criterion's jitter (the optimiser stopped short of the minimum's basin); the intervals of those "
          f"{len(far)} hold {sum(r['covered'] for f in far for r in f['rows'])} of "
          f"{sum(len(f['rows']) for f in far)} truths; the other fits' hold "
          f"{sum(r['covered'] for f in fits if f not in far for r in f['rows'])} of "
          f"{sum(len(f['rows']) for f in fits if f not in far)}")
    for f in fits:
        print(f"     fit {f['index']:>3} {f['twin']:<7} criterion at the end {f['criterion']:.4g}, at the truth "
              f"{f['criterion_truth']:.4g} (jitter {f.get('jitter', 0.0):.2g}); "
              f"{sum(r['covered'] for r in f['rows'])} of {len(f['rows'])} covered; stop: {f['stop'].split('; ')[-1]}")


def one_cartpole_fit(args: tuple[int, str, int]) -> dict[str, Any]:
    index, root_text, budget = args
    align_run.write_align_report = no_report  # type: ignore[assignment]
    twin_name = CARTPOLE_TWINS[index % len(CARTPOLE_TWINS)]
    root = Path(root_text) / f"cartpole_{index:03d}_{twin_name}"
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2000 + index)
    robot = load_binding(CARTPOLE / "binding.yaml")
    truth = {POLE_DAMPING: float(rng.uniform(0.005, 0.06)), POLE_MASS: float(0.2 * rng.uniform(0.6, 1.6))}
    kick, offset = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.01, 0.01))
    suite = cartpole_suite(root, None)
    twin = make_twin(twin_name, robot, load_suite(suite).global_settings.control_period_s)
    twin.set_knobs(truth)
    SuiteRun(cartpole_suite(root, kick), twin_name, robot, root / "recording", twin=twin).run()
    twin.close()
    degrade(root / "recording", rng, offset)
    start = time.perf_counter()
    config = AlignConfig(reference=str(root / "recording"), target=twin_name, robot=str(robot.path),
                         suite=str(suite), knobs=[*truth, CARTPOLE_KICK, OFFSET],
                         channels=["pole_angle_rad", "cart_pos_m"], optimizer="lsq", budget=budget,
                         bounds={POLE_DAMPING: (0.0, 0.1), POLE_MASS: (0.1, 0.4)}, executor="serial", seed=index)
    result = run_align(config, root / "fit")
    wall = time.perf_counter() - start
    truths = {**truth, CARTPOLE_KICK: kick, OFFSET: offset}
    rows = coverage_rows(result, root / "fit", truths, CARTPOLE_FAMILY)
    fitted = {name: fit.fitted for name, fit in {**result.knobs, **result.nuisance}.items()}
    at_fit, at_truth = (criterion_at(root / "fit", v, twin_name) for v in (fitted, truths))
    for row in rows:
        row["family"] = f"{row['family']} ({twin_name})"
    print(f"   fit {index:>3} {twin_name:<7} {wall:5.0f} s, {result.evaluations} runs, stop: {result.stop_reason}; "
          + ", ".join(f"{r['knob'].split('.')[-1]} {r['fitted']:.4g} (true {r['truth']:.4g}) "
                      f"{'in' if r['covered'] else 'OUT'}" for r in rows), flush=True)
    record = json.loads((root / "fit" / "align_record.json").read_text())
    jitter = record["result"]["identifiability"]["after"]["noise"].get("jitter", 0.0)
    out = {"index": index, "twin": twin_name, "wall_s": wall, "stop": result.stop_reason, "rows": rows,
           "criterion": at_fit, "criterion_truth": at_truth, "jitter": jitter, "evaluations": result.evaluations}
    write_json(root / "coverage_fit.json", out)  # each fit as it ends: a long study can be read before it ends
    return out


def table(fits: list[dict[str, Any]]) -> dict[str, Any]:
    groups: dict[tuple[str, str], list[bool]] = {}
    iid: dict[str, list[bool]] = {}
    family: dict[str, list[bool]] = {}
    for f in fits:
        for row in f["rows"]:
            method = (row["method"] or "none").split(" (")[0] if not row["method"].startswith("jacobian") else row["method"]
            groups.setdefault((row["family"], method), []).append(row["covered"])
            family.setdefault(row["family"], []).append(row["covered"])
            if "covered_iid" in row:
                iid.setdefault(row["family"], []).append(row["covered_iid"])
    print(f"\n{'knob family':<24}{'method':<22}{'fits':>6}{'coverage':>10}")
    out: dict[str, Any] = {"by_family_method": {}, "by_family": {}, "iid_control": {}}
    for (fam, method), hits in sorted(groups.items()):
        share = sum(hits) / len(hits)
        out["by_family_method"][f"{fam} / {method}"] = {"n": len(hits), "coverage": share}
        print(f"{fam:<24}{method:<22}{len(hits):>6}{share:>10.1%}")
    print(f"\n{'knob family':<24}{'all methods':>12}{'i.i.d. Jacobian (control)':>28}")
    for fam, hits in sorted(family.items()):
        share = sum(hits) / len(hits)
        control = iid.get(fam, [])
        ctext = f"{sum(control) / len(control):.1%} of {len(control)}" if control else "–"
        out["by_family"][fam] = {"n": len(hits), "coverage": share}
        out["iid_control"][fam] = {"n": len(control), "coverage": sum(control) / len(control) if control else None}
        print(f"{fam:<24}{share:>12.1%}{ctext:>28}   goal 90-99 %: {'yes' if 0.9 <= share <= 0.99 else 'NO'}")
    return out


def run_part(label: str, fn: Any, fits: int, processes: int, root: Path, *extra: Any) -> dict[str, Any]:
    start = time.perf_counter()
    jobs = [(i, str(root), *extra) for i in range(fits)]
    if processes > 1:
        with multiprocessing.get_context("fork").Pool(processes) as pool:
            results = pool.map(fn, jobs, chunksize=1)
    else:
        results = [fn(j) for j in jobs]
    total = time.perf_counter() - start
    print(f"   {fits} fits in {total:.0f} s (median {np.median([r['wall_s'] for r in results]):.1f} s per fit)")
    summary = table(results)
    if label == "cartpole":  # pooled over both twins as well as per twin
        pooled = [{**r, "rows": [{**row, "family": row["family"].split(" (")[0] + " (both twins)"}
                                 for row in r["rows"]]} for r in results]
        summary["both_twins"] = table(pooled)
        explain(results)
    summary["wall_s"] = total
    return {"fits": results, "summary": summary}


def main(fits: int, processes: int, parts: list[str] | None = None, cartpole_fits: int = 20,
         cartpole_budget: int = CARTPOLE_BUDGET) -> dict[str, Any]:
    parts = parts or ["fast", "cartpole"]
    out: dict[str, Any] = {}
    with output_folder("DUALTWIN_BENCH_ALIGN_COVERAGE_OUT", "align-coverage") as (root, _):
        if "fast" in parts:
            print(f"== coverage of 95 % intervals: {fits} known-truth fits of the fake twin (noise, rounding, "
                  "jitter, a kick and a logging delay) ==")
            out["fast"] = run_part("fast", one_fit, fits, processes, root)
        if "cartpole" in parts:
            print(f"== coverage of 95 % intervals: {cartpole_fits} known-truth fits of the CartPole, alternating "
                  f"{' and '.join(CARTPOLE_TWINS)} twins (noise, rounding, jitter, a kick and a logging delay) ==")
            out["cartpole"] = run_part("cartpole", one_cartpole_fit, cartpole_fits, processes, root, cartpole_budget)
        write_json(root / "coverage.json", out)
    return {part: result["summary"] for part, result in out.items()}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--parts", default="fast,cartpole", help="comma-separated: fast, cartpole")
    parser.add_argument("--fits", type=int, default=100, help="fits of the fast twin")
    parser.add_argument("--cartpole-fits", type=int, default=20, help="fits of the CartPole (alternating twins)")
    parser.add_argument("--cartpole-budget", type=int, default=CARTPOLE_BUDGET,
                        help="simulations per CartPole fit (align --budget)")
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    chosen = [p for p in args.parts.split(",") if p]
    unknown = sorted(set(chosen) - {"fast", "cartpole"})
    if unknown:
        parser.error(f"unknown part(s) {unknown}; choose from fast, cartpole")
    main(args.fits, args.processes, chosen, args.cartpole_fits, args.cartpole_budget)
