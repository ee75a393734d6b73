"""Fixtures for the synchronisation tests: short suites, a cart-pole with pole damping, tiny ONNX policies."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from dualtwin.robots.binding import BUNDLED, RobotBinding, load_binding, resolve_robot
from tests.support.sync_helpers import NOMINAL_DAMPING, SUITE, write_json


@pytest.fixture(scope="session")
def cartpole() -> RobotBinding:
    return resolve_robot("cartpole")


@pytest.fixture(scope="session")
def pioneer() -> RobotBinding:
    return resolve_robot("pioneer3at")


@pytest.fixture(scope="session")
def suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_json(tmp_path_factory.mktemp("suite") / "suite.json", SUITE)


@pytest.fixture(scope="session")
def damped_cartpole(tmp_path_factory: pytest.TempPathFactory) -> RobotBinding:
    """The cart-pole with a nominal pole damping of 0.05 N·m·s/rad in its MJCF (so 'x2' means something)."""
    folder = tmp_path_factory.mktemp("damped")
    source = BUNDLED / "cartpole"
    for name in ("binding.yaml", "cartpole.wbt"):
        shutil.copy(source / name, folder / name)
    xml = (source / "cartpole.xml").read_text(encoding="utf-8")
    xml, count = re.subn(r'(<joint name="pole_hinge"[^>]*?)damping="0"', rf'\1damping="{NOMINAL_DAMPING}"', xml)
    assert count == 1
    (folder / "cartpole.xml").write_text(xml, encoding="utf-8")
    return load_binding(folder / "binding.yaml")


