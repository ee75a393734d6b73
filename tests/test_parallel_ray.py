"""dualtwin.parallel's Ray backend against a real local Ray instance."""

from __future__ import annotations

import importlib.util

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                                reason="Ray is not installed (pip install 'dualtwin[ray]')")


def _worker_niceness() -> int:
    import os

    return os.nice(0)


def test_the_local_instance_dualtwin_starts_runs_workers_at_the_drivers_priority() -> None:
    """Ray lowers workers by 15 niceness levels by default, which on a busy machine made the Ray executor
    slower than one process; the local instance dualtwin starts itself keeps them at the driver's level."""
    import os

    import ray

    from dualtwin.parallel import ray_backend

    if ray.is_initialized() or os.environ.get("RAY_ADDRESS"):
        pytest.skip("a Ray instance is already running or configured in this process")
    backend = ray_backend(None)
    try:
        assert backend.get(backend.remote(_worker_niceness).remote()) == os.nice(0)
    finally:
        backend.shutdown()
