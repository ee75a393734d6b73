"""Real runs of a short suite on both twins, shared by the output tests (a few seconds per session)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

#: Long scenario names: a table that cuts them (or its numbers) fails these tests.
SUITE = {
    "suite_name": "output_test",
    "global_settings": {"TIME_STEP": 32},
    "scenarios": [
        {"name": "a_rather_long_scenario_name_that_tables_must_keep_whole", "duration_s": 1.0, "initial_angle": 0.2},
        {"name": "drive", "duration_s": 1.0, "initial_angle": 0.05, "wheel_velocity": 4.0},
    ],
}


@pytest.fixture(scope="session")
def suite_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("suite") / "suite.json"
    path.write_text(json.dumps(SUITE), encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def twin_runs(tmp_path_factory: pytest.TempPathFactory, suite_file: Path) -> tuple[Path, Path]:
    """Webots-twin and MuJoCo-twin runs in folders with the same name (``run``), as users often have."""
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.suite.runner import SuiteRun

    root = tmp_path_factory.mktemp("runs")
    robot = resolve_robot("cartpole")
    out = []
    for twin in ("webots", "mujoco"):
        folder = root / twin / "run"
        SuiteRun(suite_file, twin, robot, folder, seed=0).run()
        out.append(folder)
    return out[0], out[1]
