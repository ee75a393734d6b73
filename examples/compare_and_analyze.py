"""Compare the two CartPole twins and explain where they diverge: the Python side of ``dualtwin compare`` and
``dualtwin analyze``.

    python examples/compare_and_analyze.py [OUT_DIR]

Runs the bundled suite on both twins, compares the runs scenario by scenario (MSE, DTW, event times, lag,
scale and sign per channel), saves the comparison as JSON, then prints the pairs that dominate the divergence
and the analysis' findings in plain words. Without OUT_DIR everything goes into a temporary folder.
(``dualtwin.divergence.write_report(comparison, folder)`` also writes the HTML report with its plots, which
takes several seconds more; ``dualtwin compare`` does that.)
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from dualtwin.align import analyze_runs
from dualtwin.artifacts import write_json
from dualtwin.divergence import compare_runs
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.loader import BUNDLED_SUITES
from dualtwin.suite.runner import SuiteRun


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tmp)
        robot = resolve_robot("cartpole")
        suite = BUNDLED_SUITES / "cartpole" / "suite.json"
        # Webots is the reference (the twin closest to the deployed scene); MuJoCo is the one to explain.
        SuiteRun(suite, "webots", robot, out / "webots", seed=0).run()
        SuiteRun(suite, "mujoco", robot, out / "mujoco", seed=0).run()

        comparison = compare_runs(out / "webots", out / "mujoco")
        write_json(out / "comparison.json", comparison.to_dict())  # atomic, like every dualtwin output
        print(f"summary score {comparison.summary_score:.4f} over {len(comparison.scenarios)} scenarios")
        print("dominant scenario x channel pairs:")
        for c in comparison.contributions()[:3]:
            print(f"  {c.scenario_id:<20} {c.channel:<24} {c.share:6.1%} of the score")

        # Deterministic analysis; with robot=..., twin_b=... and knobs=[...] it also re-simulates knob
        # sensitivities (slower), as `dualtwin analyze --robot --target --knobs` does.
        analysis = analyze_runs(out / "webots", out / "mujoco")
        print(f"{len(analysis.findings)} findings")
        for finding in analysis.findings[:5]:
            print(f"  [{finding.kind}] {finding.message}")
        for note in analysis.notes:
            print(f"  note: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
