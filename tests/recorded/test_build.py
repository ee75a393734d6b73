"""The run writer's fast TSV formatting and unit conversions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.recorded.build import quantum, tsv_text
from dualtwin.recorded.units import conversion_factor
from dualtwin.suite.runner import format_rows


def test_fast_tsv_is_the_runners_format_byte_for_byte() -> None:
    rng = np.random.default_rng(1)
    rows = np.column_stack([np.arange(1, 50) * 0.032, rng.normal(size=49) * 10.0 ** rng.integers(-12, 12, 49),
                            rng.normal(size=49)]).tolist()
    rows[3][1], rows[4][2], rows[5][1], rows[6][2] = math.nan, -0.0, math.inf, 1e-300
    assert tsv_text(["a", "b"], rows) == format_rows(["a", "b"], rows)
    assert tsv_text(["a"], []) == format_rows(["a"], [])


@pytest.mark.parametrize("unit, target, factor", [
    ("mm", "m", 1e-3), ("cm", "m", 1e-2), ("deg", "rad", math.pi / 180), ("rad", "deg", 180 / math.pi),
    ("deg/s", "rad/s", math.pi / 180), ("mm/s", "m/s", 1e-3), ("m/ms", "m/s", 1e3), ("N*m", "N*m", 1.0),
])
def test_known_units_convert(unit: str, target: str, factor: float) -> None:
    assert conversion_factor(unit, target, "here") == pytest.approx(factor)


@pytest.mark.parametrize("unit, target", [("deg", "m"), ("m/s", "m"), ("N", "N*m"), ("m", "")])
def test_other_units_are_an_error(unit: str, target: str) -> None:
    with pytest.raises(DualtwinError, match="here: unit"):
        conversion_factor(unit, target, "here")


def test_rounding_is_detected() -> None:
    assert quantum(np.array([0.123, 1.5, -2.001])) == pytest.approx(0.001)
    assert quantum(np.array([0.1234567891, 1.0])) is None


def test_mapping_examples_in_the_docs_are_valid() -> None:
    import re
    from textwrap import dedent

    import yaml

    from dualtwin.recorded import mapping

    table, bag = re.findall(r"::\n\n((?:    .*\n?)+)", mapping.__doc__ or "")
    assert mapping.TableMapping.model_validate(yaml.safe_load(dedent(table))).time.unit == "ms"
    assert mapping.BagMapping.model_validate(yaml.safe_load(dedent(bag))).channels[1].angle == "yaw"
