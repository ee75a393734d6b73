"""The alignment tests' short cart-pole suite and how they record reference runs."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

# Three 1.5 s scenarios: a free fall, a sine drive and a constant drive (all end with the pole down).
SUITE3 = {
    "suite_name": "align_test",
    "global_settings": {"TIME_STEP": 32},
    "scenarios": [
        {"name": "fall", "duration_s": 1.5, "initial_angle": 0.2},
        {"name": "sine", "duration_s": 1.5, "initial_angle": -0.1,
         "wheel_velocity": {"kind": "sine", "amplitude": 6.0, "frequency_hz": 0.7}},
        {"name": "drive", "duration_s": 1.5, "initial_angle": 0.05, "wheel_velocity": 4.0},
    ],
}
SUITE3_IDS = ["00_fall", "01_sine", "02_drive"]
TRUE_DAMPING = 0.05


def write_suite(path: Path, suite: Mapping[str, object]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(suite), encoding="utf-8")
    return path


def record(robot: RobotBinding, suite: Path, out: Path, knobs: Mapping[str, float] | None = None,
           twin: str = "mujoco") -> Path:
    """Run ``suite`` on a twin with ``knobs`` applied and return the run directory."""
    instance = make_twin(twin, robot, 0.032)
    instance.set_knobs(dict(knobs or {}))
    SuiteRun(suite, twin, robot, out, twin=instance).run()
    return out


def count_batches(monkeypatch: Any) -> list[int]:
    """The size of every batch the alignment evaluators simulate from now on (the real Evaluator.map, counted)."""
    from dualtwin.align.simulate import Evaluator

    sizes: list[int] = []
    original = Evaluator.map

    def counting(self: Evaluator, jobs: Any) -> Any:
        jobs = list(jobs)
        sizes.append(len(jobs))
        return original(self, jobs)

    monkeypatch.setattr(Evaluator, "map", counting)
    return sizes
