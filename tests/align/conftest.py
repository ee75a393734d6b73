"""Fixtures for the alignment tests: a short cart-pole suite and recorded reference runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.robots.binding import RobotBinding, resolve_robot
from tests.support.align_runs import SUITE3, TRUE_DAMPING, record, write_suite


@pytest.fixture(scope="session")
def robot() -> RobotBinding:
    return resolve_robot("cartpole")


@pytest.fixture(scope="session")
def suite3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_suite(tmp_path_factory.mktemp("suite") / "suite3.json", SUITE3)


@pytest.fixture(scope="session")
def damped_ref(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding, suite3: Path) -> Path:
    """The reference: the MuJoCo twin with a known pole damping."""
    return record(robot, suite3, tmp_path_factory.mktemp("ref") / "damped",
                  {"joint.pole_hinge.damping": TRUE_DAMPING})


@pytest.fixture(scope="session")
def nominal_run(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding, suite3: Path) -> Path:
    return record(robot, suite3, tmp_path_factory.mktemp("nominal") / "nominal")
