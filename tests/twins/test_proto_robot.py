"""A robot that is itself a PROTO instance (as the paper's Pioneer3at-based CartPole2): the Webots twin walks
the base node the PROTO expands to, not the PROTO's interface, which Webots' getField shows on such a node."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualtwin.divergence.runs import load_run
from dualtwin.robots.binding import load_binding
from dualtwin.suite.runner import SuiteRun

HERE = Path(__file__).resolve().parent / "proto_robot"


def test_the_webots_twin_finds_and_sets_a_joint_inside_a_proto_robot(tmp_path: Path) -> None:
    SuiteRun(HERE / "suite.json", "webots", load_binding(HERE / "binding.yaml"), tmp_path / "run").run()
    run = load_run(tmp_path / "run")
    entry = run.scenarios[0]
    assert entry.status == "completed", entry.failure
    series = run.series(entry.id)
    truth, sensor = series["pivot_rad"].y, series["onboard/pivot_rad"].y
    assert abs(truth[0] - 0.4) < 0.05  # the initial angle was set on the joint inside the PROTO
    assert truth[-1] > truth[0] + 0.05  # and the arm falls under gravity from there
    np.testing.assert_allclose(sensor, truth, atol=1e-3)


def test_the_knobs_of_a_proto_robots_parts_are_offered() -> None:
    """Knob discovery walks the same base nodes: the arm's mass and the hinge's damping are knobs."""
    from dualtwin.twins import make_twin

    twin = make_twin("webots", load_binding(HERE / "binding.yaml"), 0.032)
    try:
        names = set(twin.knobs())
    finally:
        twin.close()
    assert "body.ARM.mass" in names and any(n.startswith("joint.PIVOT.") for n in names), sorted(names)
