"""Run the bundled CartPole suite on both twins, the MuJoCo one and the Webots one (ODE), and print each
scenario's status and how far the pole got.

    python examples/run_suite_both_twins.py [OUT_DIR]

Without OUT_DIR the runs go into a temporary folder that is removed at the end. With one, OUT_DIR/mujoco and
OUT_DIR/webots are ordinary run folders (manifest.json, config/, scenarios/*/onboard.tsv and
ground_truth.tsv) that ``dualtwin compare`` reads.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from dualtwin.divergence.runs import load_run
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.loader import BUNDLED_SUITES
from dualtwin.suite.runner import SuiteRun


def run_both(out: Path) -> dict[str, Path]:
    """One run folder per twin; the same suite, binding and seed, so only the simulator differs."""
    robot = resolve_robot("cartpole")  # the bundled robot; a path to your own binding.yaml works too
    suite = BUNDLED_SUITES / "cartpole" / "suite.json"
    runs = {}
    for twin in ("mujoco", "webots"):
        runs[twin] = out / twin
        SuiteRun(suite, twin, robot, runs[twin], seed=0).run()
    return runs


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tmp)
        for twin, folder in run_both(out).items():
            run = load_run(folder)  # verifies every log against the manifest's row counts and SHA-256
            print(f"{twin}: {len(run.scenarios)} scenarios of {run.suite_name!r}")
            for scenario in run.scenarios:
                angle = run.series(scenario.id)["pole_angle_rad"].y
                print(f"  {scenario.id:<20} {scenario.status:<10} max |pole angle| {abs(angle).max():.3f} rad")
    return 0


if __name__ == "__main__":
    sys.exit(main())
