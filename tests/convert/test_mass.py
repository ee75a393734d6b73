"""Masses and inertias follow Webots' rules (docs/reference/webots-on-ode.md §3.2), checked against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.convert import convert_world_text

HEADER = "#VRML_SIM R2023b utf8\n"


def robot_world(children: str = "", bounding: str = "", physics: str = "physics Physics { }") -> str:
    return HEADER + f"""
DEF R Robot {{
  children [ {children} ]
  boundingObject {bounding or 'NULL'}
  {physics}
}}
"""


def body(text: str, name: str = "R") -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, CoM, 3x3 inertia about the CoM in body axes) of a converted body."""
    conv = convert_world_text(text, "t.wbt")
    b = conv.spec.body(name)
    ixx, iyy, izz, ixy, ixz, iyz = (float(v) for v in b.fullinertia)
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    return float(b.mass), np.array(b.ipos, dtype=float), inertia


def test_box_with_mass_override_scales_the_density_1000_inertia() -> None:
    m, com, inertia = body(robot_world(bounding="Box { size 0.3 0.1 0.2 }", physics="physics Physics { density -1 mass 2 }"))
    assert m == pytest.approx(2.0)
    assert com == pytest.approx([0, 0, 0])
    # I = m/12 (b² + c²) ...
    assert np.diag(inertia) == pytest.approx([2 / 12 * (0.01 + 0.04), 2 / 12 * (0.09 + 0.04), 2 / 12 * (0.09 + 0.01)])


def test_default_density_gives_volume_times_1000() -> None:
    m, _, inertia = body(robot_world(bounding="Sphere { radius 0.1 }"))
    expected = 1000 * 4 / 3 * math.pi * 0.001
    assert m == pytest.approx(expected)
    assert np.diag(inertia) == pytest.approx([0.4 * expected * 0.01] * 3)


def test_density_scales_mass_and_inertia() -> None:
    m, _, inertia = body(robot_world(bounding="Cylinder { radius 0.1 height 0.2 }",
                                     physics="physics Physics { density 500 }"))
    expected = 500 * math.pi * 0.01 * 0.2
    assert m == pytest.approx(expected)
    assert inertia[2, 2] == pytest.approx(0.5 * expected * 0.01)
    assert inertia[0, 0] == pytest.approx(expected * (0.25 * 0.01 + 0.04 / 12))


def test_posed_primitives_in_a_group_sum_with_parallel_axes() -> None:
    # Two 1x1x1 boxes (1000 kg each at density 1000) at x = ±1, the second rotated (no effect on a cube).
    bounding = """Group { children [
      Pose { translation 1 0 0 children [ Box { size 1 1 1 } ] }
      Pose { translation -1 0 0 rotation 0 0 1 0.7 children [ Shape { geometry Box { size 1 1 1 } } ] }
    ] }"""
    m, com, inertia = body(robot_world(bounding=bounding))
    assert m == pytest.approx(2000.0)
    assert com == pytest.approx([0, 0, 0], abs=1e-12)
    cube = 1000 / 6  # m (a² + a²) / 12 with a = 1
    assert inertia[0, 0] == pytest.approx(2 * cube)
    assert inertia[1, 1] == pytest.approx(2 * cube + 2 * 1000 * 1.0)
    assert inertia[2, 2] == pytest.approx(2 * cube + 2 * 1000 * 1.0)


def test_rotated_box_inertia_is_rotated() -> None:
    bounding = "Pose { rotation 0 0 1 1.5707963267948966 children [ Box { size 0.4 0.1 0.1 } ] }"
    _, _, inertia = body(robot_world(bounding=bounding, physics="physics Physics { density -1 mass 1 }"))
    # After 90° about z the long side lies along y: Ixx = m (0.4² + 0.1²) / 12.
    assert inertia[0, 0] == pytest.approx((0.16 + 0.01) / 12)
    assert inertia[1, 1] == pytest.approx((0.01 + 0.01) / 12)


def test_center_of_mass_moves_the_distribution_rigidly() -> None:
    # The inverted pendulum's pole: Box 0.05 x 0.02 x 0.6, mass 0.05, centerOfMass 0 0.061 -0.27.
    m, com, inertia = body(robot_world(bounding="Box { size 0.05 0.02 0.6 }",
                                       physics="physics Physics { density -1 mass 0.05 centerOfMass [ 0 0.061 -0.27 ] }"))
    assert m == pytest.approx(0.05)
    assert com == pytest.approx([0, 0.061, -0.27])
    assert inertia[0, 0] == pytest.approx(0.05 / 12 * (0.0004 + 0.36))


def test_custom_inertia_matrix_is_used_as_is() -> None:
    physics = "physics Physics { density -1 mass 3 centerOfMass [ 0.1 0 0 ] inertiaMatrix [ 0.2 0.3 0.4, 0.01 0 0 ] }"
    m, com, inertia = body(robot_world(bounding="Box { size 1 1 1 }", physics=physics))
    assert m == pytest.approx(3.0)
    assert com == pytest.approx([0.1, 0, 0])
    assert inertia == pytest.approx(np.array([[0.2, 0.01, 0], [0.01, 0.3, 0], [0, 0, 0.4]]))


def test_physics_without_bounding_object_uses_identity_inertia() -> None:
    m, _, inertia = body(robot_world(physics="physics Physics { density -1 mass 4 }"))
    assert m == pytest.approx(4.0)
    assert inertia == pytest.approx(np.eye(3))
    conv = convert_world_text(robot_world(physics="physics Physics { }"), "t.wbt")
    assert float(conv.spec.body("R").mass) == pytest.approx(1.0)
    assert any("identity inertia" in w for w in conv.warnings)


def test_merged_child_solid_adds_its_mass_in_the_parent_frame() -> None:
    child = "Solid { translation 0 0 1 boundingObject Sphere { radius 0.1 } physics Physics { density -1 mass 1 } }"
    m, com, inertia = body(robot_world(children=child, bounding="Sphere { radius 0.1 }",
                                       physics="physics Physics { density -1 mass 1 }"))
    assert m == pytest.approx(2.0)
    assert com == pytest.approx([0, 0, 0.5])
    sphere = 0.4 * 1 * 0.01
    assert inertia[0, 0] == pytest.approx(2 * sphere + 2 * 1 * 0.25)
    assert inertia[2, 2] == pytest.approx(2 * sphere)


def test_capsule_and_mesh_formulas() -> None:
    m, _, inertia = body(robot_world(bounding="Capsule { radius 0.1 height 0.2 }"))
    m1, m2 = 1000 * math.pi * 0.01 * 0.2, 1000 * 4 / 3 * math.pi * 0.001
    assert m == pytest.approx(m1 + m2)
    assert inertia[2, 2] == pytest.approx((0.5 * m1 + 0.4 * m2) * 0.01)
    # A closed unit-cube mesh integrates like the Box formula (1000 kg, I = 1000/6). Centred on the Solid's
    # origin: off-centre meshes get ODE's dMassSetTrimesh inertia, see tests/convert/test_mass_agreement.py.
    points = ", ".join(f"{x} {y} {z}" for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5))
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    index = " ".join(f"{a} {b} {c} -1" for a, b, c in faces)
    mesh = f"IndexedFaceSet {{ coord Coordinate {{ point [ {points} ] }} coordIndex [ {index} ] }}"
    m, com, inertia = body(robot_world(bounding=mesh))
    assert m == pytest.approx(1000.0)
    assert com == pytest.approx([0, 0, 0], abs=1e-12)
    assert inertia == pytest.approx(np.eye(3) * 1000 / 6)
