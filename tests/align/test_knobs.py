"""Knob selection: names, globs, close matches, bounds and scales."""

from __future__ import annotations

import pytest

from dualtwin.align.knobs import check_values, match_knobs, select_knobs, unit_from_values, values_from_unit
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.twins import make_twin
from dualtwin.twins.base import Knob


@pytest.fixture(scope="module")
def registry(robot: RobotBinding) -> dict[str, Knob]:
    return make_twin("mujoco", robot, 0.032).knobs()


def test_names_and_globs_select_in_order_without_duplicates(registry: dict[str, Knob]) -> None:
    names = match_knobs(list(registry), ["joint.pole_hinge.damping", "joint.*.damping", "motor.wheel?.gain"])
    assert names[0] == "joint.pole_hinge.damping"
    assert names.count("joint.pole_hinge.damping") == 1
    assert {f"joint.wheel{i}_hinge.damping" for i in range(1, 5)} <= set(names)
    assert [n for n in names if n.startswith("motor.")] == [f"motor.wheel{i}.gain" for i in range(1, 5)]


def test_unknown_knob_lists_close_matches(registry: dict[str, Knob]) -> None:
    with pytest.raises(DualtwinError, match=r"'joint\.pole_hing\.damping'.*did you mean.*joint\.pole_hinge\.damping"):
        select_knobs(registry, ["joint.pole_hing.damping"])
    with pytest.raises(DualtwinError, match=r"knob pattern 'joint\.\*\.dampng'.*joint\.[a-z0-9_]+\.damping"):
        select_knobs(registry, ["joint.*.dampng"])
    with pytest.raises(DualtwinError, match="no knobs selected"):
        select_knobs(registry, [])


def test_bounds_excluding_nominal_or_empty_are_errors(registry: dict[str, Knob]) -> None:
    with pytest.raises(DualtwinError, match=r"bounds \[0\.1, 0\.5\] exclude its nominal value 0"):
        select_knobs(registry, ["joint.pole_hinge.damping"], {"joint.pole_hinge.damping": (0.1, 0.5)})
    with pytest.raises(DualtwinError, match="empty or not finite"):
        select_knobs(registry, ["joint.pole_hinge.damping"], {"joint.pole_hinge.damping": (0.5, 0.5)})
    with pytest.raises(DualtwinError, match="name no selected knob"):
        select_knobs(registry, ["joint.pole_hinge.damping"], {"body.pole.mass": (0.1, 1.0)})
    spec = select_knobs(registry, ["joint.*.damping"], {"joint.*.damping": (0.0, 0.2)})[0]
    assert (spec.lower, spec.upper) == (0.0, 0.2)


def test_scales_integer_knobs_and_unit_round_trip(registry: dict[str, Knob]) -> None:
    mass, damping, delay = select_knobs(registry, ["body.pole.mass", "joint.pole_hinge.damping",
                                                   "control.delay_periods"])
    assert mass.scale == "log" and damping.scale == "linear"
    assert delay.integer and delay.from_unit(0.26) == 3.0
    for spec, value in ((mass, 0.37), (damping, 0.05)):
        assert spec.from_unit(spec.to_unit(value)) == pytest.approx(value)
    u = unit_from_values([mass, damping], {"joint.pole_hinge.damping": 0.2})
    assert values_from_unit([mass, damping], u) == pytest.approx({"body.pole.mass": 0.2, "joint.pole_hinge.damping": 0.2})
    assert damping.at_bound(0.0) == "lower" and damping.at_bound(0.5) is None


def test_check_values(registry: dict[str, Knob]) -> None:
    assert check_values(registry, {"joint.pole_hinge.damping": 1}) == {"joint.pole_hinge.damping": 1.0}
    with pytest.raises(DualtwinError, match="did you mean"):
        check_values(registry, {"joint.pole.damping": 1.0})
    with pytest.raises(DualtwinError, match="not finite"):
        check_values(registry, {"joint.pole_hinge.damping": float("nan")})
