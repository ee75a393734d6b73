"""A supervisor's write of WorldInfo ERP or CFM out of range is reset to the default, as at load and as Webots'
WorldInfo does (it resets a value out of range to its default with a warning); before, an ERP of -1e308 written at
run time reached ODE, which stopped inside its step (found by fuzzing the API with hostile values)."""

from __future__ import annotations

import warnings

import pytest

from tests.support.kicks import supervisor_in

PENDULUM = """
Solid {
  children [
    HingeJoint {
      jointParameters HingeJointParameters { anchor 0 0 1 axis 0 1 0 }
      endPoint Solid {
        translation 0.3 0 1
        children [ Shape { geometry DEF B Sphere { radius 0.05 } } ]
        boundingObject USE B
        physics Physics { density -1 mass 1 }
      }
    }
  ]
}
"""


@pytest.mark.parametrize(("field", "bad", "default"), [("ERP", -1e308, 0.2), ("ERP", 1.5, 0.2), ("CFM", -1.0, 1e-5),
                                                       ("CFM", 0.0, 1e-5)])
def test_an_out_of_range_value_is_reset_to_the_default_with_a_warning(field: str, bad: float,
                                                                      default: float) -> None:
    sup = supervisor_in(PENDULUM, 8, gravity=9.81)
    info = sup.getRoot().getField("children").getMFNode(0)
    assert info.getTypeName() == "WorldInfo"
    with pytest.warns(UserWarning, match=rf"WorldInfo.{field} .* is out of range .*; reset to {default:g}"):
        info.getField(field).setSFFloat(bad)
        for _ in range(20):
            assert sup.step(8) == 0  # (before: SimulationUnstable for ERP -1e308)
    assert info.getField(field).getSFFloat() == default


def test_control_a_value_in_range_is_kept_without_a_warning() -> None:
    sup = supervisor_in(PENDULUM, 8, gravity=9.81)
    info = sup.getRoot().getField("children").getMFNode(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        info.getField("ERP").setSFFloat(0.5)
        info.getField("CFM").setSFFloat(1e-4)
        sup.step(8)
    assert info.getField("ERP").getSFFloat() == 0.5 and info.getField("CFM").getSFFloat() == 1e-4
