"""Same seed and inputs give byte-identical align run folders (the fake twin, tiny budgets, about a second each).

Each objective runs twice into the same path (the output path is an input: reference runs record it); the
first folder is moved aside before the second run. Wall-clock time is the one value that differs between
the runs, so no file of the folder may hold it: it is printed (terminal summary, ``align --json``) and kept
on the result. The control: the two runs' wall times are real measurements and were not made equal.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.align import AlignConfig, AlignResult, run_align
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered

TRUTH = {"joint.j1.damping": 0.9, "joint.j2.stiffness": 6.5}


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _twice(tmp_path: Path, settings: dict[str, object]) -> tuple[dict[str, bytes], dict[str, bytes],
                                                                  AlignResult, AlignResult]:
    config = AlignConfig.model_validate({"reference": NAME, "target": NAME, "robot": str(ROBOT), "suite": str(SUITE),
                                         "knobs": sorted(TRUTH), "reference_knobs": TRUTH, "executor": "serial",
                                         **settings})
    out = tmp_path / "run"
    first = run_align(config, out)
    shutil.move(out, tmp_path / "first")
    second = run_align(config, out)
    return _files(tmp_path / "first"), _files(out), first, second


@pytest.mark.parametrize("settings", [
    pytest.param({"optimizer": "cma", "budget": 16, "seed": 5}, id="trajectory-cma"),
    pytest.param({"optimizer": "lsq", "budget": 12, "seed": 5, "holdout": ["04_kick"]}, id="trajectory-lsq"),
    pytest.param({"objective": "prediction", "optimizer": "cma", "budget": 10, "seed": 5}, id="prediction"),
])
def test_two_identical_runs_write_identical_folders(tmp_path: Path, settings: dict[str, object]) -> None:
    first, second, a, b = _twice(tmp_path, settings)
    assert {"align_record.json", "knobs.json", "report.html"} <= set(first)
    assert sorted(first) == sorted(second)
    differing = [name for name in first if first[name] != second[name]]
    assert not differing, f"differ between two identical runs: {differing}"
    assert a.fitted == b.fitted
    # Wall time is printed, not written.
    assert a.wall_time_s > 0 and b.wall_time_s > 0
    record = json.loads(first["align_record.json"])
    assert "wall_time_s" not in record
    assert "wall time" not in first["report.html"].decode("utf-8")
