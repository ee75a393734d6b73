"""Re-seating every control period is never worse than free-running, at rest too (issue 14).

The published suite's 1 s scenario where nothing moves was the counterexample: each engine rests at its own
contact depth, and re-seating the secondary at the primary's depth made it bounce every period.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.robots.binding import BUNDLED, RobotBinding
from dualtwin.sync import run_lockstep
from dualtwin.sync.lockstep import calibrate_rest
from dualtwin.twins import make_twin

SUITE = BUNDLED / "cartpole" / "suite.json"


@pytest.mark.parametrize(("primary", "secondary"), [("webots", "mujoco"), ("mujoco", "webots")])
def test_every_period_resync_is_never_worse_than_free_running(
        tmp_path: Path, cartpole: RobotBinding, primary: str, secondary: str) -> None:
    free = run_lockstep(primary, secondary, cartpole, suite=SUITE, out_dir=tmp_path / "never", resync="never")
    seated = run_lockstep(primary, secondary, cartpole, suite=SUITE, out_dir=tmp_path / "every",
                          resync="every:1")
    assert [e.id for e in free.episodes] == [e.id for e in seated.episodes]
    for f, s in zip(free.episodes, seated.episodes, strict=True):
        assert s.resyncs == s.steps, s.id
        assert s.mean_error <= f.mean_error, (s.id, s.mean_error, f.mean_error)
    assert seated.manifest["rest_calibration"] is not None
    assert free.manifest["rest_calibration"] is None


def test_rest_calibration_measures_the_contact_depths(cartpole: RobotBinding) -> None:
    webots, mujoco = make_twin("webots", cartpole, 0.032), make_twin("mujoco", cartpole, 0.032)
    try:
        into_mujoco = calibrate_rest(webots, mujoco)
        # MuJoCo's soft contacts rest deeper than ODE's under the same weight.
        assert into_mujoco.depth_ratio is not None and 1.2 < into_mujoco.depth_ratio < 4.0
        into_webots = calibrate_rest(mujoco, webots)
        assert into_webots.depth_ratio is None
        assert 0 < into_webots.height_offset["cart"] < 1e-3  # Webots rests higher
        # The same twin on both sides: nothing to correct.
        assert calibrate_rest(mujoco, make_twin("mujoco", cartpole, 0.032)).depth_ratio is None
    finally:
        webots.close()
        mujoco.close()
