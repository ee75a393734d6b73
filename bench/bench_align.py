"""Alignment benchmark: align the MuJoCo CartPole to the Webots twin and report before and after.

Run: ``python bench/bench_align.py`` (or ``make bench``). Goals (issue 4): pole-fall DTW cut by >= 90 %,
crossing-time error <= 0.05 s, every held-out scenario improved, <= 120 s wall on 2 cores.

Two cases, each fitted by least squares on the pole angle (the paper's metric) of five scenarios, with
``05_Sine_Drive`` held out (its score over every channel must improve):

* ``bundled``: the bundled MuJoCo model, written to match the Webots world, so it starts close;
* ``paper-like``: the same model with the kind of errors the paper's LLM conversion had (pole-hinge damping
  0.08 N·m·s/rad instead of 0, contact friction ×0.8), so the pole falls ~0.3 s late as in the paper.

The fitted pole-fall DTW is also split at the Webots pole's first impact on its stop (its 0.99 rad crossing):
the fall itself, and the impacts that follow, where the residual is (see README, Alignment).

The benchmark also measures the scenario's own reproducibility floor: each twin against itself with the
pole's initial angle (0.001 rad) moved by 1 and 10 µrad. The pole starts at an unstable equilibrium and lands
on a hard stop within one 8 ms ODE step, so where inside a step the impact falls decides the kick to the cart
and the bounces that follow. A second engine agreeing with Webots more closely than either engine agrees with
itself under a perturbation far below any modelling error would be luck, not alignment.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import yaml

from dualtwin.align import AlignConfig, run_align
from dualtwin.demo import CHANNELS, HOLDOUT, KNOBS
from dualtwin.divergence import compare_runs
from dualtwin.divergence.metrics import dtw_distance
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

SUITE = BUNDLED / "cartpole" / "suite.json"
FALL = "00_Step_Response"
PAPER = {"dtw": (0.184, 0.061), "mse": (0.029, 0.009), "fall_s": (2.06, 1.61), "webots_fall_s": 1.52}


def paper_like_robot(folder: Path) -> Path:
    """A copy of the CartPole binding whose MuJoCo model carries paper-like modelling errors."""
    spec = mujoco.MjSpec.from_file(str(BUNDLED / "cartpole" / "cartpole.xml"))
    spec.joint("pole_hinge").damping[0] = 0.08
    for geom in spec.geoms:
        geom.friction[0] = 0.8
    (folder / "cartpole_paper_like.xml").write_text(spec.to_xml())
    binding = yaml.safe_load((BUNDLED / "cartpole" / "binding.yaml").read_text())
    binding["twins"]["mujoco"]["model"] = "cartpole_paper_like.xml"
    binding["twins"]["webots"]["model"] = str(BUNDLED / "cartpole" / "cartpole.wbt")
    path = folder / "binding.yaml"
    path.write_text(yaml.safe_dump(binding, sort_keys=False))
    return path


def fall_metrics(reference: Path, run: Path) -> dict[str, float]:
    comparison = compare_runs(reference, run)
    scenario = next(s for s in comparison.scenarios if s.id == FALL)
    pole = scenario.channels["pole_angle_rad"]
    held = {s.id: s.score for s in comparison.scenarios if s.id in HOLDOUT}
    return {"dtw": pole.dtw, "dtw_rms": pole.dtw_rms, "mse": pole.mse,
            "crossing_error_s": abs(pole.crossing_diff_s or float("nan")),
            "fall_s": pole.crossing_b_s or float("nan"), "webots_fall_s": pole.crossing_a_s or float("nan"),
            **{f"holdout:{k}": v for k, v in held.items()}}


def scenario_dtw(reference: Path, out: Path) -> dict[str, tuple[float, float]]:
    """Pole-angle DTW of every scenario, before and after the fit."""
    before, after = (compare_runs(reference, out / "runs" / phase) for phase in ("before", "after"))
    return {b.id: (b.channels["pole_angle_rad"].dtw, a.channels["pole_angle_rad"].dtw)
            for b, a in zip(before.scenarios, after.scenarios, strict=True)}


def pole(run: Path) -> tuple[np.ndarray, np.ndarray]:
    table = np.genfromtxt(run / "scenarios" / FALL / "ground_truth.tsv", names=True, delimiter="\t")
    return table["time_s"], table["pole_angle_rad"]


def phase_dtw(reference: Path, run: Path, impact_s: float) -> tuple[float, float]:
    """Pole-fall DTW of the fall (before ``impact_s``) and of what follows the first stop impact."""
    t, a = pole(reference)
    _, b = pole(run)
    fall = t < impact_s
    return dtw_distance(a[fall], b[fall]).distance, dtw_distance(a[~fall], b[~fall]).distance


def reproducibility_floor(twin: str, folder: Path) -> dict[float, float]:
    """Pole-fall DTW of one twin against itself with the initial angle moved slightly."""
    robot = load_binding(BUNDLED / "cartpole" / "binding.yaml")
    suite = json.loads(SUITE.read_text())
    fall = next(s for s in suite["scenarios"] if s["name"] == FALL.split("_", 1)[1])
    nominal = float(fall["initial_angle"])
    floor = {}
    for shift in (0.0, 1e-6, -1e-6, 1e-5, -1e-5):
        fall["initial_angle"] = nominal + shift
        path = folder / "suite.json"
        path.write_text(json.dumps(suite))
        run = folder / f"{twin}_{shift:+g}"
        SuiteRun(path, twin, robot, run).run()
        if shift:
            floor[shift] = fall_metrics(folder / f"{twin}_+0", run)["dtw"]
    print(f"   the {twin} twin against itself, pole-fall DTW with the initial angle {nominal:g} rad moved by "
          + ", ".join(f"{1e6 * k:+.0f} µrad: {v:.4f}" for k, v in floor.items()))
    return floor


def run_case(name: str, binding_path: Path, reference: Path, out: Path, floor: float) -> dict[str, float]:
    robot = load_binding(binding_path)
    start = time.perf_counter()
    result = run_align(AlignConfig(reference=str(reference), target="mujoco", robot=str(robot.path),
                                   suite=str(SUITE), knobs=list(KNOBS), optimizer="lsq", budget=300,
                                   holdout=HOLDOUT, channels=CHANNELS), out)
    wall = time.perf_counter() - start
    before = fall_metrics(reference, out / "runs" / "before")
    after = fall_metrics(reference, out / "runs" / "after")
    cut = 1 - after["dtw"] / before["dtw"] if before["dtw"] > 0 else 0.0
    held_ok = all(after[k] < before[k] for k in before if k.startswith("holdout:"))
    print(f"-- {name}: {result.evaluations} simulations, {wall:.1f} s wall (goal <= 120 s)")
    print(f"   pole-fall DTW       {before['dtw']:.4f} -> {after['dtw']:.4f}   cut {cut:.0%} (goal >= 90 %; "
          f"paper {PAPER['dtw'][0]} -> {PAPER['dtw'][1]}, 67 %)")
    print(f"     the goal asks for <= {0.1 * before['dtw']:.4f}; neither twin reproduces itself better than "
          f"{floor:.4f} under a 1 µrad change of the initial angle")
    # Split where the Webots pole first reaches its stop; the parts add in quadrature when the fall times agree
    # (after the fit), not before it, when one fall lags the other across the cut.
    fall_part, impact_part = phase_dtw(reference, out / "runs" / "after", before["webots_fall_s"])
    print(f"     after the fit: fall {fall_part:.4f}, from the first stop impact on {impact_part:.4f}")
    print(f"   pole-fall MSE       {before['mse']:.5f} -> {after['mse']:.5f}   (paper {PAPER['mse'][0]} -> "
          f"{PAPER['mse'][1]})")
    print(f"   fall time (0.99 rad) {before['fall_s']:.3f} -> {after['fall_s']:.3f} s vs Webots twin "
          f"{after['webots_fall_s']:.3f} s; error {before['crossing_error_s']:.3f} -> "
          f"{after['crossing_error_s']:.3f} s (goal <= 0.05 s; paper 2.06 -> 1.61 vs 1.52)")
    for key in before:
        if key.startswith("holdout:"):
            print(f"   held-out {key[8:]:<14} score {before[key]:.4f} -> {after[key]:.4f}")
    print(f"   every held-out scenario improved: {held_ok}")
    print("   pole-angle DTW per scenario (fitted on all but the held-out):")
    for sid, (b, a) in scenario_dtw(reference, out).items():
        print(f"     {sid:<20} {b:.4f} -> {a:.4f}")
    for knob, fit in result.knobs.items():
        print(f"   {knob:<32} {fit.nominal:.5g} -> {fit.fitted:.5g}")
    return {"dtw_cut": cut, "crossing_error_s": after["crossing_error_s"], "wall_s": wall,
            "holdout_improved": float(held_ok)}


def impact_events(twin_name: str, knobs: dict[str, float] | None = None) -> dict[str, float]:
    """Step ``00_Step_Response`` every 8 ms and measure the stop impact and the cart's landing."""
    robot = load_binding(BUNDLED / "cartpole" / "binding.yaml")
    twin = make_twin(twin_name, robot, 0.008)
    twin.set_knobs(dict(knobs or {}))
    twin.reset(0)
    twin.set_joint_state("pole_hinge", position=0.001)
    rows = []
    while twin.time < 3.5 - 1e-9:
        twin.step()
        r = twin.body_orientation("cart")
        rows.append((twin.time, twin.joint_position("pole_hinge"), twin.joint_velocity("pole_hinge"),
                     float(np.arctan2(r[0, 2], r[2, 2])), float(twin.body_position("cart")[2])))
    twin.close()
    t, angle, rate, pitch, z = (np.array(c) for c in zip(*rows, strict=True))
    hit = int(np.argmax(angle >= 0.99))
    land = hit + int(np.argmax(pitch[hit:] <= 0.0))
    window = slice(hit, hit + 15)
    return {"impact_s": float(t[hit]), "impact_rate": float(rate[hit - 1]),
            "overshoot_rad": float(angle[window].max()), "rest_rad": float(angle[land - 5]),
            "max_pitch_rad": float(pitch.max()), "max_rise_mm": 1000 * float(z.max() - z[hit - 1]),
            "landing_s": float(t[land]), "rebound_rate": float(rate[land:land + 4].min())}


def overlay() -> None:
    """What happens at the pole's stop in each twin (README, Alignment): ``--overlay``."""
    cases = {"Webots twin": ("webots", None), "MuJoCo, nominal": ("mujoco", None),
             "MuJoCo, 8 ms steps": ("mujoco", {"physics.substeps": 1})}
    print(f"{'':<28}{'impact s':>9}{'rad/s':>7}{'max rad':>9}{'rest rad':>9}{'pitch':>7}{'rise mm':>8}"
          f"{'landing s':>10}{'rebound':>8}")
    for label, (name, knobs) in cases.items():
        e = impact_events(name, knobs)
        print(f"{label:<28}{e['impact_s']:9.3f}{e['impact_rate']:7.2f}{e['overshoot_rad']:9.4f}{e['rest_rad']:9.4f}"
              f"{e['max_pitch_rad']:7.3f}{e['max_rise_mm']:8.1f}{e['landing_s']:10.3f}{e['rebound_rate']:8.2f}")


def main() -> dict[str, dict[str, float]]:
    tmp = Path(tempfile.mkdtemp(prefix="dualtwin-bench-align-"))
    try:
        print("== alignment: MuJoCo CartPole aligned to the Webots twin ==")
        overlay()
        reference = tmp / "webots"
        SuiteRun(SUITE, "webots", load_binding(BUNDLED / "cartpole" / "binding.yaml"), reference).run()
        (tmp / "floor").mkdir()
        print("-- reproducibility floor of the fall scenario")
        floor = min(min(reproducibility_floor(twin, tmp / "floor").values()) for twin in ("webots", "mujoco"))
        results = {"bundled": run_case("bundled pair", BUNDLED / "cartpole" / "binding.yaml", reference,
                                       tmp / "bundled", floor)}
        paper_dir = tmp / "paper_like"
        paper_dir.mkdir()
        results["paper-like"] = run_case("paper-like mismatch", paper_like_robot(paper_dir), reference,
                                         tmp / "paper_like_fit", floor)
        return results
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
