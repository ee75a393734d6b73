"""Pioneer 3-AT-like dual twin: forward displacement and lateral drift, before and after alignment.

Run: ``python bench/bench_pioneer.py`` (or ``make bench``). Goals (issue 8), on held-out scenarios after
alignment: forward-displacement difference <= 1 % and lateral-drift difference <= 0.3 cm (the paper: 8.7 %
before, 3.2 % after; drift 1.8 vs 0.5 cm before, 0.9 vs 0.6 cm after).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np

from dualtwin.align import AlignConfig, run_align
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun

ROBOT = BUNDLED / "pioneer3at" / "binding.yaml"
SUITE = BUNDLED / "pioneer3at" / "suite.json"
HOLDOUT = ["03_Arc", "05_Reverse_Arc", "06_Slope"]
# Wheel radius, wheel friction, floor softness and friction "hardness" (slip): the knobs of issue 8.
KNOBS = ["geom.*WHEEL_SOLID.radius", "geom.*WHEEL_SOLID.friction", "geom.floor.solref_timeconst", "option.impratio"]


def endpoint(run: Path, scenario: str, start: tuple[float, float]) -> tuple[float, float, float]:
    """(distance travelled from the start, lateral drift in m, heading in rad) at the end of a scenario."""
    data = np.loadtxt(run / "scenarios" / scenario / "ground_truth.tsv", skiprows=1, ndmin=2)
    x, y = float(data[-1, 1]) - start[0], float(data[-1, 2]) - start[1]
    return math.hypot(x, y), y, float(data[-1, 3])


def starts(suite: Path) -> dict[str, tuple[float, float]]:
    """Each scenario's start position (the binding's initial_x/initial_y, 0 when not given), by scenario id."""
    scenarios = json.loads(suite.read_text())["scenarios"]
    return {f"{i:02d}_{s['name']}": (float(s.get("initial_x", 0.0)), float(s.get("initial_y", 0.0)))
            for i, s in enumerate(scenarios)}


def main() -> dict[str, float]:
    tmp = Path(tempfile.mkdtemp(prefix="dualtwin-bench-pioneer-"))
    try:
        robot = load_binding(ROBOT)
        reference = tmp / "webots"
        SuiteRun(SUITE, "webots", robot, reference).run()
        result = run_align(AlignConfig(reference=str(reference), target="mujoco", robot=str(robot.path),
                                       suite=str(SUITE), knobs=list(KNOBS), optimizer="lsq", budget=150,
                                       holdout=HOLDOUT), tmp / "align")
        print("== Pioneer 3-AT-like: MuJoCo twin aligned to the Webots twin (least squares) ==")
        print(f"   {result.evaluations} simulations, {result.wall_time_s:.1f} s; held out: {', '.join(HOLDOUT)}")
        print(f"   objective {result.objective_before:.4g} -> {result.objective_after:.4g}, held out "
              f"{result.holdout_before:.4g} -> {result.holdout_after:.4g} ({result.stop_reason})")
        print("   fitted: " + ", ".join(f"{k} = {v:.5g}" for k, v in result.fitted.items()))
        worst: dict[str, float] = {"displacement_pct": 0.0, "drift_cm": 0.0}
        origin = starts(SUITE)
        for scenario in [s["id"] for s in json.loads((reference / "manifest.json").read_text())["scenarios"]]:
            ref_d, ref_y, ref_yaw = endpoint(reference, scenario, origin[scenario])
            row = []
            for label in ("before", "after"):
                d, y, yaw = endpoint(tmp / "align" / "runs" / label, scenario, origin[scenario])
                pct = 100 * (d - ref_d) / ref_d if ref_d > 0.05 else float("nan")
                row.append(f"{label}: {d:.3f} m ({pct:+.2f} %), drift {100 * y:+.2f} cm (Δ {100 * (y - ref_y):+.2f}), "
                           f"heading {yaw:+.3f} rad")
                if label == "after" and scenario in HOLDOUT:
                    worst["displacement_pct"] = max(worst["displacement_pct"], abs(pct))
                    worst["drift_cm"] = max(worst["drift_cm"], abs(100 * (y - ref_y)))
            tag = " [held out]" if scenario in HOLDOUT else ""
            print(f"   {scenario}{tag}: Webots {ref_d:.3f} m, drift {100 * ref_y:+.2f} cm, heading {ref_yaw:+.3f} rad")
            print(f"      MuJoCo {row[0]}\n      MuJoCo {row[1]}")
        print(f"   held-out worst after alignment: displacement {worst['displacement_pct']:.2f} % (goal <= 1 %), "
              f"drift difference {worst['drift_cm']:.2f} cm (goal <= 0.3 cm)")
        return worst
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
