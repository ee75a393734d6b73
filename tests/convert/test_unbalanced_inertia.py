"""A Physics ``inertiaMatrix`` that Webots accepts but MuJoCo cannot simulate still converts.

Webots takes a custom inertia matrix when it is positive definite with a positive diagonal (webots-on-ode §3.2,
CUSTOM_INERTIA_MATRIX), and ODE simulates it as given; MuJoCo refuses any inertia whose principal moments break
the triangle inequality A + B >= C (no rigid body has one), so the converted model did not even compile
("inertia must satisfy A + B >= C") and the MuJoCo twin could not be built for a world the Webots twin runs.
Found by the dual-twin fuzz with random inertia matrices. The converter now writes MuJoCo's own repair
(``balanceinertia``: the three principal moments set to their mean) and says so in a warning.

Hand computation: diag(0.01, 0.01, 0.03) is positive definite, 0.01 + 0.01 < 0.03; the mean is 0.05/3.
"""

from __future__ import annotations

import pytest

from dualtwin.convert import Conversion, convert_world_text
from tests.support.converted_twins import world_text

ROBOT = ('DEF R Robot {{ controller "<extern>" children [ GPS {{ name "gps" }} ] boundingObject Sphere {{ radius 0.1 }} '
         "physics Physics {{ density -1 mass 2 centerOfMass [ 0 0 0 ] inertiaMatrix [ {inertia} ] }} }}")


def _convert(inertia: str) -> Conversion:
    return convert_world_text(world_text(ROBOT.format(inertia=inertia), "gravity 0"), "inertia.wbt")


def test_an_unbalanced_inertia_converts_to_its_mean_with_a_warning() -> None:
    conv = _convert("0.01 0.01 0.03, 0 0 0")
    model = conv.compile()
    assert list(model.body("R").inertia) == pytest.approx([0.05 / 3] * 3, rel=1e-9)
    notes = [w for w in conv.warnings if "inertiaMatrix" in w]
    assert len(notes) == 1 and "A + B >= C" in notes[0] and "0.0166667" in notes[0], conv.warnings


def test_a_rotated_unbalanced_inertia_too() -> None:
    # Products of inertia do not hide it: [[0.02, 0.01, 0], [0.01, 0.02, 0], [0, 0, 0.045]] has principal moments
    # 0.01, 0.03 (about (1, ±1, 0)/√2) and 0.045 > 0.01 + 0.03; their mean is 0.085/3.
    model = _convert("0.02 0.02 0.045, 0.01 0 0").compile()
    assert list(model.body("R").inertia) == pytest.approx([0.085 / 3] * 3, rel=1e-9)


def test_control_a_physical_inertia_is_written_as_given() -> None:
    conv = _convert("0.01 0.02 0.025, 0 0 0")
    assert sorted(conv.compile().body("R").inertia) == pytest.approx([0.01, 0.02, 0.025], rel=1e-9)
    assert not [w for w in conv.warnings if "inertiaMatrix" in w]
