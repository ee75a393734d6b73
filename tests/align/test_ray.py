"""The Ray executor against a real local Ray instance: same seed, same fit as the process pool."""

from __future__ import annotations

import importlib.util
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dualtwin.align import AlignConfig, run_align
from dualtwin.robots.binding import RobotBinding

pytestmark = pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                                reason="Ray is not installed (pip install 'dualtwin[ray]')")

DAMPING = "joint.pole_hinge.damping"


@pytest.fixture(scope="module")
def local_ray() -> Iterator[Any]:
    import ray

    # One CPU and no dashboard keep the local instance small; align() joins it instead of starting its own.
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        yield ray
    finally:
        ray.shutdown()


def test_ray_executor_matches_the_process_pool(local_ray: Any, tmp_path: Path, robot: RobotBinding,
                                                suite3: Path, damped_ref: Path) -> None:
    kwargs: dict[str, Any] = {"optimizer": "cma", "seed": 5, "budget": 8, "popsize": 4}
    on_ray = run_align(AlignConfig(reference=str(damped_ref), target="mujoco", robot=str(robot.path),
                                   suite=str(suite3), knobs=[DAMPING], executor="ray", ray_address=None,
                                   **kwargs), tmp_path / "ray")
    in_pool = run_align(AlignConfig(reference=str(damped_ref), target="mujoco", robot=str(robot.path),
                                    suite=str(suite3), knobs=[DAMPING], executor="process", **kwargs),
                        tmp_path / "pool")
    assert local_ray.is_initialized()
    # The fit's own simulations, within its budget of 8 (the interval checks after it are not counted):
    # at least the nominal run and one CMA generation of 4, the same on both executors.
    assert on_ray.evaluations == in_pool.evaluations
    assert 4 < in_pool.evaluations <= 8
    assert on_ray.iterations == in_pool.iterations >= 1
    assert on_ray.fitted == in_pool.fitted
    assert on_ray.fitted[DAMPING] != 0.0  # the fit moved: the comparison is not between two nominal runs
    record = (tmp_path / "ray" / "align_record.json").read_text()
    assert '"ray"' in record
