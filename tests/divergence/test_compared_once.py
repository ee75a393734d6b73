"""A channel comparison is computed once per process for the same inputs and settings (issue 25): an on-board
channel that logs its ground-truth twin's values, and a run compared again (an alignment's after run equal to
its before run), reuse it; the result is what a fresh computation gives, under the caller's channel name.

The lag search (``best_lag``, the costliest metric) is counted where it is called (wrapped, not replaced).
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.divergence import metrics
from dualtwin.divergence.comparison import compare_runs
from dualtwin.divergence.metrics import compare_channel
from dualtwin.robots.binding import resolve_robot
from tests.support.align_runs import SUITE3, record, write_suite

T = np.linspace(0.0, 2.0, 101)


def forget() -> None:
    """Empty the process's comparisons (a fresh computation follows)."""
    getattr(metrics, "_COMPARED", {}).clear()


@pytest.fixture()
def lags(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    original = metrics.best_lag

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(metrics, "best_lag", counting)
    forget()
    return calls


def test_the_same_channel_pair_is_compared_once(lags: list[int]) -> None:
    a, b = np.sin(3 * T), np.sin(3 * T - 0.2)
    first = compare_channel(T, a, T, b, channel="angle", threshold=0.5, resolution=1e-3)
    again = compare_channel(T.copy(), a.copy(), T.copy(), b.copy(), channel="onboard/angle", threshold=0.5,
                            resolution=1e-3)
    assert len(lags) == 1
    assert again.channel == "onboard/angle" and first.channel == "angle"
    assert again.to_dict() == {**first.to_dict(), "channel": "onboard/angle"}
    forget()
    fresh = compare_channel(T, a, T, b, channel="angle", threshold=0.5, resolution=1e-3)
    assert len(lags) == 2 and fresh.to_dict() == first.to_dict()
    # Other settings or other values are compared anew.
    compare_channel(T, a, T, b, channel="angle", threshold=0.5, resolution=2e-3)
    compare_channel(T, a, T, b, channel="angle", threshold=0.6, resolution=1e-3)
    compare_channel(T, a, T, np.nextafter(b, 2.0), channel="angle", threshold=0.5, resolution=1e-3)
    assert len(lags) == 5


def test_a_run_compared_again_reuses_its_channel_comparisons(tmp_path: Path, lags: list[int]) -> None:
    robot = resolve_robot("cartpole")
    suite = write_suite(tmp_path / "suite.json", SUITE3)
    ref = record(robot, suite, tmp_path / "ref", {"joint.pole_hinge.damping": 0.05})
    before = record(robot, suite, tmp_path / "before")
    after = tmp_path / "after"
    shutil.copytree(before, after)
    first = compare_runs(ref, before)
    pairs = sum(len(s.channels) for s in first.scenarios)
    # onboard/pole_angle_rad logs the same values as pole_angle_rad in both runs: compared once per scenario.
    assert len(lags) == pairs - len(first.scenarios), (len(lags), pairs)
    second = compare_runs(ref, after)
    assert len(lags) == pairs - len(first.scenarios)
    assert [s.to_dict() for s in second.scenarios] == [s.to_dict() for s in first.scenarios]
    forget()
    fresh = compare_runs(ref, after)
    assert [s.to_dict() for s in fresh.scenarios] == [s.to_dict() for s in first.scenarios]
