"""Webots' mass rules as the twin applies them (dualtwin.webots.mass_rules), on bodies built by Simulation."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation

HEADER = "#VRML_SIM R2023b utf8\nWorldInfo { }\n"


def body_of(bounding: str, physics: str = "Physics { }") -> tuple[float, tuple[float, ...], tuple[float, ...]]:
    """(mass, CoM in the Solid frame, inertia about the CoM) of a one-Solid body."""
    world = load_world_text(HEADER + f"Solid {{ boundingObject {bounding} physics {physics} }}\n", "t.wbt")
    sim = Simulation(world)
    try:
        (body,) = sim.bodies
        return body.mass, body.com, body.inertia
    finally:
        sim.close()


def test_transform_scale_in_a_bounding_object_scales_the_mass_like_the_geom() -> None:
    plain, _, _ = body_of("Box { size 0.1 0.2 0.3 }")
    scaled, _, inertia = body_of("Transform { scale 2 1 3 children [ Box { size 0.1 0.2 0.3 } ] }")
    assert plain == pytest.approx(6.0)
    assert scaled == pytest.approx(6.0 * 2 * 1 * 3)
    # a 0.2 x 0.2 x 0.9 box
    assert inertia[0] == pytest.approx(scaled * (0.04 + 0.81) / 12)
    # round primitives take the largest factor, as their geoms do; translations below a scale are scaled
    sphere, com, _ = body_of("Transform { scale 1 2 1 children [ Pose { translation 0.1 0 0 children [ "
                             "Sphere { radius 0.1 } ] } ] }")
    assert sphere == pytest.approx(1000 * 4 / 3 * math.pi * 0.2**3)
    assert com == pytest.approx((0.1, 0.0, 0.0))
    _, com, _ = body_of("Transform { translation 0.1 0 0 scale 3 3 3 children [ Sphere { radius 0.1 } ] }")
    assert com == pytest.approx((0.1, 0.0, 0.0))  # the Transform's own translation is not scaled by itself
    _, com, _ = body_of("Transform { scale 3 3 3 children [ Pose { translation 0.1 0 0 children [ "
                        "Sphere { radius 0.1 } ] } ] }")
    assert com == pytest.approx((0.3, 0.0, 0.0))  # a frame below the scaled one is


def test_odes_trimesh_inertia_of_an_off_centre_mesh() -> None:
    """ODE's dMassSetTrimesh, as linked here, reports an off-centre mesh's inertia with the parallel-axis term
    counted twice: about the centre of mass the twin then holds I_true + m(|d|²E − ddᵀ), d the offset. Webots
    calls the same function; whether its ODE fork does the same is UNVERIFIED. The converter writes the same
    numbers (tests/convert/test_mass_agreement.py), so both twins share the quirk."""
    points = ", ".join(f"{x + 2} {y} {z}" for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5))
    faces = ((0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3))
    index = " ".join(f"{a} {b} {c} -1" for a, b, c in faces)
    mesh = f"IndexedFaceSet {{ coord Coordinate {{ point [ {points} ] }} coordIndex [ {index} ] }}"
    mass, com, inertia = body_of(mesh)
    assert mass == pytest.approx(1000.0)
    assert com == pytest.approx((2.0, 0.0, 0.0))
    true = 1000 / 6
    assert (inertia[0], inertia[4], inertia[8]) == pytest.approx((true, true + 1000 * 4, true + 1000 * 4))
    # control: the same cube centred on the Solid's origin has the Box formula's inertia
    centred = mesh.replace(points, ", ".join(f"{x} {y} {z}" for x in (-0.5, 0.5) for y in (-0.5, 0.5)
                                             for z in (-0.5, 0.5)))
    _, _, inertia = body_of(centred)
    assert (inertia[0], inertia[4], inertia[8]) == pytest.approx((true, true, true))


@pytest.mark.parametrize(
    ("physics", "expected", "warning"),
    [
        ("Physics { density 500 }", 500 * 0.001, None),
        ("Physics { density 500 mass 2 }", 2.0, "both mass and density given, density ignored"),
        ("Physics { density -1 mass -1 }", 1.0, "Physics has neither mass nor density; using 1 kg"),
        ("Physics { density -1 mass 2 inertiaMatrix [ 1 1 1, 0 0 0 ] }", 2.0, "invalid inertiaMatrix ignored"),
    ],
)
def test_mass_and_density_conventions(physics: str, expected: float, warning: str | None) -> None:
    world = load_world_text(HEADER + f"Solid {{ name \"s\" boundingObject Box {{ size 0.1 0.1 0.1 }} "
                                     f"physics {physics} }}\n", "t.wbt")
    if warning is None:
        sim = Simulation(world)
    else:
        with pytest.warns(UserWarning, match=warning):
            sim = Simulation(world)
    try:
        assert sim.bodies[0].mass == pytest.approx(expected)
        if warning is not None:
            assert sim.build_warnings == [f"Solid 's': {warning}"]
    finally:
        sim.close()


def test_scaled_bounding_object_geoms_sit_where_their_mass_is() -> None:
    bounding = "Transform { scale 3 3 3 children [ Pose { translation 0.1 0 0 children [ Sphere { radius 0.1 } ] } ] }"
    sim = Simulation(load_world_text(HEADER + f"Solid {{ boundingObject {bounding} physics Physics {{ }} }}\n", "t.wbt"))
    try:
        (body,) = sim.bodies
        (geom,) = body.root.geoms
        assert geom.local.t == pytest.approx((0.3, 0.0, 0.0))
        assert body.com == pytest.approx(geom.local.t)
        assert sim._lib.dGeomSphereGetRadius(geom.ptr) == pytest.approx(0.3)
    finally:
        sim.close()
