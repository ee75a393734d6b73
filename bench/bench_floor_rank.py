"""Reproducibility floor and ranking by physical significance (issue 15.4, 15.5).

Run: ``python bench/bench_floor_rank.py`` (``DUALTWIN_BENCH_OUT=folder`` keeps the runs). Prints:

* **Floors.** Each CartPole twin against itself on the pole-fall scenario (``00_Step_Response``, initial
  angle 0.001 rad), through the ensemble feature (``suite run --ensemble 5 --perturb initial_angle=EPS``) at
  EPS = 1 and 10 µrad: the mean pole-fall DTW of members 1-4 against member 0, the worst member's RMSE, and
  where the members stop being predictable. Then the bundled pair (Webots twin vs MuJoCo twin) judged
  against those floors: its floor ratio.
* **Ranking goals.** (1) An injected 0.3 s delay of the CartPole's pole fall (the MuJoCo run's fall
  scenario logs delayed by 0.3 s) ranks first among the CartPole's divergences. (2) On the Pioneer the arcs
  rank above the straight runs. (3) No sign, scale, lag or endpoint finding is raised on a difference at or
  below the channel's resolution. Each is printed next to the old ranking (score shares, where each
  channel's score is divided by its own range) as the control.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

from _common import output_folder
from dualtwin.align.analyze import analyze_runs
from dualtwin.artifacts import log_record
from dualtwin.divergence import compare_runs
from dualtwin.divergence.comparison import RunComparison
from dualtwin.divergence.metrics import compare_channel
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.ensemble import EnsembleRun, make_spec
from dualtwin.suite.runner import SuiteRun

FALL = "00_Step_Response"
DELAY_S = 0.3
EPSILONS = (1e-6, 1e-5)
MEMBERS = 5
STRAIGHT = ("00_Constant_Velocity_3s", "01_Full_Speed", "04_Speed_Steps")
ARCS = ("03_Arc", "05_Reverse_Arc")


def old_ranking(comparison: RunComparison) -> list[tuple[str, str, float]]:
    """The ranking before issue 15.5: shares of the summary score, each channel scaled by its own range."""
    scored = [s for s in comparison.scenarios if s.score is not None and s.channels]
    total = sum(s.score or 0.0 for s in scored) / len(scored)
    out = [(s.id, name, ch.score / len(s.channels) / len(scored) / total)
           for s in scored for name, ch in s.channels.items()]
    return sorted(out, key=lambda r: -r[2])


def delayed_copy(run: Path, out: Path, scenario: str, delay_s: float) -> Path:
    """A copy of ``run`` whose ``scenario`` logs show everything ``delay_s`` later (values held at the start)."""
    shutil.copytree(run, out)
    manifest = json.loads((out / "manifest.json").read_text())
    for source in ("onboard", "ground_truth"):
        path = out / "scenarios" / scenario / f"{source}.tsv"
        lines = path.read_text().splitlines()
        data = np.array([[float(c) for c in line.split("\t")] for line in lines[1:]])
        t = data[:, 0]
        shifted = np.column_stack([t] + [np.interp(t - delay_s, t, data[:, j]) for j in range(1, data.shape[1])])
        path.write_text("\n".join([lines[0], *("\t".join(map(repr, map(float, row))) for row in shifted)]) + "\n")
        rel = f"scenarios/{scenario}/{source}.tsv"
        if "logs" in manifest and rel in manifest["logs"]:
            manifest["logs"][rel] = log_record(path)
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out


def significance_rank(comparison: RunComparison) -> list[tuple[str, str | None, float, float]]:
    return [(c.scenario_id, c.channel, c.contribution, c.share) for c in comparison.contributions()]


def scenario_significance(comparison: RunComparison) -> dict[str, float]:
    return {s.id: max((ch.significance or 0.0 for ch in s.channels.values()), default=0.0)
            for s in comparison.scenarios}


def below_resolution_findings(a: Path, b: Path) -> tuple[int, int]:
    """(findings checked, findings on a pair at or below its resolution): the second must be 0."""
    analysis = analyze_runs(a, b)
    checked = bad = 0
    by_id = {s.id: s for s in analysis.comparison.scenarios}
    for finding in analysis.findings:
        if finding.kind not in ("sign_inversion", "scale_mismatch", "lag", "endpoint") or finding.channel is None:
            continue
        for sid in finding.scenarios:
            ch = by_id[sid].channels[finding.channel]
            checked += 1
            bad += int(ch.rmse <= (ch.resolution or 0.0) or (ch.significance or 0.0) <= 1.0)
    return checked, bad


def unresolved_sign_flags(comparison: RunComparison) -> list[str]:
    """The control: pairs that the metrics without a resolution call sign-inverted though they differ by
    less than the channel's resolution (what the old analysis reported, e.g. a 13 µm cart RMSE)."""
    out = []
    for sc in comparison.scenarios:
        for name, ch in sc.channels.items():
            sa, sb = sc.series_a[name], sc.series_b[name]
            plain = compare_channel(sa.t, sa.y, sb.t, sb.y, channel=name)
            if plain.sign_inverted and ch.rmse <= (ch.resolution or 0.0):
                out.append(f"{sc.id}/{name} (rmse {ch.rmse:.2g})")
    return out


def floors(root: Path) -> dict[str, Path]:
    robot = load_binding(BUNDLED / "cartpole" / "binding.yaml")
    suite = json.loads((BUNDLED / "cartpole" / "suite.json").read_text())
    suite["scenarios"] = suite["scenarios"][:1]  # the pole fall
    path = root / "fall_suite.json"
    path.write_text(json.dumps(suite))
    print("-- reproducibility floor of the pole fall (00_Step_Response, initial angle 0.001 rad), "
          f"{MEMBERS}-member ensembles (member 0 unperturbed)")
    runs: dict[str, Path] = {}
    for eps in EPSILONS:
        for twin in ("webots", "mujoco"):
            out = root / f"floor_{twin}_{eps:g}"
            start = time.perf_counter()
            spec = make_spec(MEMBERS, {"initial_angle": eps}, robot)
            EnsembleRun(path, twin, robot, out, spec, executor="process", workers=2).run()
            wall = time.perf_counter() - start
            runs[f"{twin}@{eps:g}"] = out
            own = compare_runs(out, out).scenarios[0].floors["pole_angle_rad"].floor_a
            assert own is not None
            horizon = "never" if own.horizon_s is None else f"{own.horizon_s:.2f} s"
            print(f"   {twin:<7} ±{eps * 1e6:>4.0f} µrad: pole-fall DTW floor {own.dtw:.4f} (mean of members 1-4; "
                  f"dtw_rms {own.dtw_rms:.5f} rad), worst member RMSE {own.rmse_max:.4f} rad, members stop being "
                  f"predictable at {horizon}, crossing-time spread {own.crossing_spread_s or 0.0:.3f} s "
                  f"({wall:.1f} s wall)")
        pair = compare_runs(runs[f"webots@{eps:g}"], runs[f"mujoco@{eps:g}"]).scenarios[0]
        judged = pair.floors["pole_angle_rad"]
        print(f"   bundled pair at ±{eps * 1e6:.0f} µrad: pole-fall DTW {pair.channels['pole_angle_rad'].dtw:.4f} "
              f"vs larger floor {judged.floor_dtw:.4f}: ratio {judged.ratio or float('nan'):.2f} -> {judged.verdict}")
    return runs


def main() -> None:
    with output_folder("DUALTWIN_BENCH_OUT", "floor-rank") as (root, kept):
        start = time.perf_counter()
        floors(root)

        print("-- ranking goal 1: an injected 0.3 s delay of the CartPole's pole fall ranks first")
        cartpole = load_binding(BUNDLED / "cartpole" / "binding.yaml")
        suite = BUNDLED / "cartpole" / "suite.json"
        runs = {twin: root / f"cartpole_{twin}" for twin in ("webots", "mujoco")}
        for twin, out in runs.items():
            SuiteRun(suite, twin, cartpole, out).run()
        delayed = delayed_copy(runs["mujoco"], root / "cartpole_mujoco_delayed", FALL, DELAY_S)
        comparison = compare_runs(runs["webots"], delayed)
        pole = comparison.scenarios[0].channels["pole_angle_rad"]
        print(f"   pole fall (0.99 rad) Webots {pole.crossing_a_s:.3f} s, delayed MuJoCo {pole.crossing_b_s:.3f} s")
        new = significance_rank(comparison)
        old = old_ranking(comparison)
        for label, rows in (("new (significance)", [(s, c, sh) for s, c, _, sh in new]), ("old (score share)", old)):
            print(f"   {label}: " + "; ".join(f"{s}/{c} {100 * sh:.1f} %" for s, c, sh in rows[:4]))
        first = new[0]
        fall_first = first[0] == FALL and (first[1] or "").removeprefix("onboard/") == "pole_angle_rad"
        old_fall = next(i for i, r in enumerate(old) if r[0] == FALL and r[1] == "pole_angle_rad")
        print(f"   goal met: {fall_first} (the delayed pole fall ranks first with significance {first[2]:.0f}, "
              f"{100 * first[3]:.0f} % of the divergence; the old ranking put it at #{old_fall + 1}, "
              f"{100 * old[old_fall][2]:.1f} %)")
        analysis = analyze_runs(runs["webots"], delayed)
        print("   analyze's first findings: " + "; ".join(f"{f.kind} {f.channel} ({100 * f.share:.0f} %)"
                                                     for f in analysis.findings[:3]))

        print("-- ranking goal 2: on the Pioneer the arcs rank above the straight runs")
        pioneer = load_binding(BUNDLED / "pioneer3at" / "binding.yaml")
        p_suite = BUNDLED / "pioneer3at" / "suite.json"
        p_runs = {twin: root / f"pioneer_{twin}" for twin in ("webots", "mujoco")}
        for twin, out in p_runs.items():
            SuiteRun(p_suite, twin, pioneer, out).run()
        p_comp = compare_runs(p_runs["webots"], p_runs["mujoco"])
        per = scenario_significance(p_comp)
        old_score = {s.id: s.score or 0.0 for s in p_comp.scenarios}
        for sid in sorted(per, key=lambda k: -per[k]):
            worst = max(p_comp.scenarios[[s.id for s in p_comp.scenarios].index(sid)].channels.items(),
                        key=lambda kv: kv[1].significance or 0.0)
            print(f"   {sid:<26} significance {per[sid]:8.2f} (largest: {worst[0]}, rmse {worst[1].rmse:.5f}); "
                  f"old score {old_score[sid]:.4f}")
        arcs_above = min(per[a] for a in ARCS) > max(per[s] for s in STRAIGHT)
        old_above = min(old_score[a] for a in ARCS) > max(old_score[s] for s in STRAIGHT)
        print(f"   goal met: {arcs_above} (arcs {', '.join(ARCS)} above straight runs {', '.join(STRAIGHT)}; "
              f"with the old score: {old_above})")

        print("-- ranking goal 3: no finding on a difference at or below the channel's resolution")
        for label, (a, b) in {"CartPole webots vs mujoco": (runs["webots"], runs["mujoco"]),
                              "CartPole webots vs delayed": (runs["webots"], delayed),
                              "Pioneer webots vs mujoco": (p_runs["webots"], p_runs["mujoco"])}.items():
            checked, bad = below_resolution_findings(a, b)
            control = unresolved_sign_flags(compare_runs(a, b))
            print(f"   {label}: {checked} finding × scenario pairs checked, {bad} at or below resolution "
                  f"(goal: 0) -> {'met' if bad == 0 else 'NOT met'}; without resolutions the metrics would "
                  f"flag {len(control)} sign inversion(s) below it" + (f": {', '.join(control[:3])}" if control else ""))
        print(f"total wall {time.perf_counter() - start:.0f} s" + (f"; runs kept in {root}" if kept else ""))


if __name__ == "__main__":
    main()
