"""Fixtures for the divergence tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.support.rundirs import ScenarioData, fabricate_run


@pytest.fixture
def make_run(tmp_path: Path) -> Callable[..., Path]:
    """``make_run(name, data, **kwargs)`` fabricates a run directory under ``tmp_path``."""

    def make(name: str, data: ScenarioData, **kwargs: Any) -> Path:
        return fabricate_run(tmp_path / name, data, **kwargs)

    return make
