"""Do the two twins of a generated robot move alike? The second half of a generated robot's smoke test.

MuJoCo's own smoke test (:func:`dualtwin.convert.checks.smoke_test`) only proves that one model steps without
warnings. A robot can pass it while its twins disagree completely: a wheeled robot welded to the world spins its
wheels in Webots and holds them still in MuJoCo, where the welded wheels press into the floor. So the robot's
generated suite runs on both twins for a short while, and every channel that moves clearly in one twin while it
stays (nearly) still in the other is named. Subtler differences are what ``compare`` and ``align`` are for; this
check only catches a model the twins cannot share.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualtwin.divergence.runs import load_run
from dualtwin.robots.binding import load_binding
from dualtwin.suite.runner import SuiteRun

#: A channel "moves" when its range exceeds this many resolutions ...
MOVES_RESOLUTIONS = 20.0
#: ... and "stays still" in the other twin when its range is under this fraction of the moving one's.
STILL_FRACTION = 0.1
#: Simulated seconds of each scenario the check runs (the generated scenarios drive from 0.2 s on).
CHECK_DURATION_S = 1.0


@dataclass(frozen=True)
class MotionDisagreement:
    """One channel of one scenario that moves in one twin and stays still in the other."""

    scenario: str
    channel: str
    unit: str
    webots_range: float
    mujoco_range: float

    def __str__(self) -> str:
        return (f"{self.scenario}: {self.channel} moves {self.webots_range:.3g} {self.unit} in Webots but "
                f"{self.mujoco_range:.3g} {self.unit} in MuJoCo")


def _short_suite(suite_path: Path, out: Path) -> Path:
    suite = json.loads(suite_path.read_text(encoding="utf-8"))
    for scenario in suite.get("scenarios", []):
        scenario["duration_s"] = min(float(scenario.get("duration_s", CHECK_DURATION_S)), CHECK_DURATION_S)
    out.write_text(json.dumps(suite), encoding="utf-8")
    return out


def motion_disagreements(binding_path: Path, suite_path: Path) -> list[MotionDisagreement]:
    """Run the first second of every scenario of ``suite_path`` on both twins; list the channels one twin moves
    and the other does not (see the module docstring). Runs in a temporary folder; writes nothing else."""
    binding = load_binding(binding_path)
    found: list[MotionDisagreement] = []
    with tempfile.TemporaryDirectory(prefix="dualtwin-agreement-") as tmp:
        root = Path(tmp)
        suite = _short_suite(suite_path, root / "suite.json")
        runs = {}
        for twin in ("webots", "mujoco"):
            SuiteRun(suite, twin, binding, root / twin).run()
            runs[twin] = load_run(root / twin)
        webots, mujoco = runs["webots"], runs["mujoco"]
        for entry in webots.scenarios:
            if entry.status != "completed" or mujoco.scenario(entry.id).status != "completed":
                continue  # an unstable scenario is reported by the suite run itself
            series_w, series_m = webots.series(entry.id), mujoco.series(entry.id)
            for name, info in webots.channels.items():
                if name not in series_w or name not in series_m:
                    continue
                range_w = float(np.ptp(series_w[name].y)) if series_w[name].y.size else 0.0
                range_m = float(np.ptp(series_m[name].y)) if series_m[name].y.size else 0.0
                big, small = max(range_w, range_m), min(range_w, range_m)
                if big > MOVES_RESOLUTIONS * info.resolved_resolution and small < STILL_FRACTION * big:
                    found.append(MotionDisagreement(entry.name, name, info.unit, range_w, range_m))
    return found
