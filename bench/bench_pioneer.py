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

from dualtwin.align import align
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun

ROBOT = BUNDLED / "pioneer3at" / "binding.yaml"
SUITE = BUNDLED / "pioneer3at" / "suite.json"
HOLDOUT = ["03_Arc", "05_Reverse_Arc"]
KNOBS = ["geom.*WHEEL_SOLID.friction", "geom.floor.solref_timeconst"]


def endpoint(run: Path, scenario: str) -> tuple[float, float]:
    """(distance travelled from the start, lateral position in m) at the end of a scenario."""
    data = np.loadtxt(run / "scenarios" / scenario / "ground_truth.tsv", skiprows=1, ndmin=2)
    x, y = float(data[-1, 1]), float(data[-1, 2])
    return math.hypot(x, y), y


def main() -> dict[str, float]:
    tmp = Path(tempfile.mkdtemp(prefix="dualtwin-bench-pioneer-"))
    try:
        robot = load_binding(ROBOT)
        reference = tmp / "webots"
        SuiteRun(SUITE, "webots", robot, reference).run()
        result = align(reference, "mujoco", robot, SUITE, KNOBS, tmp / "align", optimizer="lsq", budget=150,
                       holdout=HOLDOUT)
        print("== Pioneer 3-AT-like: MuJoCo twin aligned to the Webots twin (least squares) ==")
        print(f"   {result.evaluations} simulations, {result.wall_time_s:.1f} s; held out: {', '.join(HOLDOUT)}")
        worst: dict[str, float] = {"displacement_pct": 0.0, "drift_cm": 0.0}
        for scenario in [s["id"] for s in json.loads((reference / "manifest.json").read_text())["scenarios"]]:
            ref_d, ref_y = endpoint(reference, scenario)
            row = []
            for label in ("before", "after"):
                d, y = endpoint(tmp / "align" / "runs" / label, scenario)
                pct = 100 * (d - ref_d) / ref_d if ref_d > 0.05 else float("nan")
                row.append(f"{label}: {d:.3f} m ({pct:+.1f} %), drift {100 * y:+.2f} cm (Δ {100 * (y - ref_y):+.2f})")
                if label == "after" and scenario in HOLDOUT:
                    worst["displacement_pct"] = max(worst["displacement_pct"], abs(pct))
                    worst["drift_cm"] = max(worst["drift_cm"], abs(100 * (y - ref_y)))
            tag = " [held out]" if scenario in HOLDOUT else ""
            print(f"   {scenario}{tag}: Webots {ref_d:.3f} m, drift {100 * ref_y:+.2f} cm")
            print(f"      MuJoCo {row[0]}\n      MuJoCo {row[1]}")
        print(f"   held-out worst after alignment: displacement {worst['displacement_pct']:.1f} % (goal <= 1 %), "
              f"drift difference {worst['drift_cm']:.2f} cm (goal <= 0.3 cm)")
        return worst
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
