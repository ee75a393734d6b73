"""Section 3 of the Webots-on-ODE specification (/work/shared/reference/webots-on-ode.md, restated in
docs/reference/webots-on-ode.md): transform conventions, the Physics node's mass rules, nested Solids (merging,
the static basis) and the boundingObject → ODE geom mapping, one test per fact. Masses are hand computed from
the primitives' formulas; ODE bodies and geoms are read back through ODE (tests/support/ode_probe.py) or the
Simulation's body records."""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Iterator

import pytest

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.ode_probe import probe, simulations

Make = Callable[..., Simulation]
RHO = 1000.0  # §3.2: reference density of boundingObject primitives


@pytest.fixture
def make() -> Iterator[Make]:
    """``make(scene, info="gravity 0")``: a Simulation of ``scene`` (world nodes as text) under
    ``WorldInfo { info }``; build warnings are silenced (read them from ``build_warnings``)."""
    with simulations("gravity 0", quiet=True) as build:
        yield build


def _one_body(sim: Simulation):  # type: ignore[no-untyped-def]
    (body,) = sim.bodies
    return body


def _diag(inertia: tuple[float, ...]) -> tuple[float, float, float]:
    return inertia[0], inertia[4], inertia[8]


def _rotation(ptr: int) -> tuple[float, ...]:
    r = ode.mat3(ptr)
    return (r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10])


# ------------------------------------------------------------------ §3.1 transform conventions


def test_rotation_axis_is_normalised_before_use(make: Make) -> None:
    # §3.1: "The rotation axis is normalised before use": axis 0 0 2 is axis 0 0 1
    sim = make("Solid { rotation 0 0 2 1 boundingObject Sphere { radius 0.1 } physics Physics { } }")
    expected = (math.cos(1), -math.sin(1), 0.0, math.sin(1), math.cos(1), 0.0, 0.0, 0.0, 1.0)
    assert _rotation(sim._lib.dBodyGetRotation(_one_body(sim).ptr)) == pytest.approx(expected, abs=1e-12)


def test_world_pose_is_the_product_of_the_ancestor_frames(make: Make) -> None:
    # §3.1: translation/rotation relative to the parent Pose/Solid frame; world pose = product of ancestor
    # matrices: a Pose at (1, 0, 0) turned 90° about z, then a Solid at (1, 0, 0) in it: world (1, 1, 0)
    sim = make("Pose { translation 1 0 0 rotation 0 0 1 1.5707963267948966 children [ "
               "Solid { translation 1 0 0 boundingObject Sphere { radius 0.1 } physics Physics { } } ] }")
    assert list(_one_body(sim).pos) == pytest.approx([1.0, 1.0, 0.0], abs=1e-12)


def test_hidden_velocity_fields_give_the_initial_body_velocities(make: Make) -> None:
    # §3.1: hidden linearVelocity / angularVelocity (world frame) give the initial body velocities
    sim = make("Solid { linearVelocity 1 2 3 angularVelocity 0.1 0.2 0.3 boundingObject Sphere { radius 0.1 } "
               "physics Physics { } }")
    body = _one_body(sim)
    assert (list(body.lvel), list(body.avel)) == ([1.0, 2.0, 3.0], [0.1, 0.2, 0.3])


# ------------------------------------------------------------------ §3.2 mass computation


def test_capsule_mass_is_odes_capsule_along_z_at_density_1000(make: Make) -> None:
    # §3.2: dMassSetCapsule(1000, 3, r, h), h the cylindrical part: m = ρ(πr²h + 4/3πr³), axial Izz = ...
    r, h = 0.1, 0.4
    sim = make(f"Solid {{ boundingObject Capsule {{ radius {r} height {h} }} physics Physics {{ }} }}")
    m_cyl, m_caps = RHO * math.pi * r * r * h, RHO * 4 / 3 * math.pi * r**3
    body = _one_body(sim)
    assert body.mass == pytest.approx(m_cyl + m_caps, rel=1e-12)
    # ODE's capsule: Izz = m_cyl r²/2 + m_caps·2r²/5; Ixx = m_cyl(r²/4 + h²/12) + m_caps(2r²/5 + 3rh/8 + h²/4)
    izz = m_cyl * r * r / 2 + m_caps * 2 * r * r / 5
    ixx = m_cyl * (r * r / 4 + h * h / 12) + m_caps * (0.4 * r * r + 0.375 * r * h + 0.25 * h * h)
    assert _diag(body.inertia) == pytest.approx((ixx, ixx, izz), rel=1e-12)


def test_cylinder_mass_is_along_z(make: Make) -> None:
    # §3.2: dMassSetCylinder(1000, 3, r, h) (direction 3 = z): Izz = m r²/2, Ixx = Iyy = m(3r² + h²)/12
    r, h = 0.1, 0.5
    body = _one_body(make(f"Solid {{ boundingObject Cylinder {{ radius {r} height {h} }} physics Physics {{ }} }}"))
    m = RHO * math.pi * r * r * h
    assert body.mass == pytest.approx(m, rel=1e-12)
    assert _diag(body.inertia) == pytest.approx((m * (3 * r * r + h * h) / 12,) * 2 + (m * r * r / 2,), rel=1e-12)


def test_overlapping_group_children_are_counted_twice(make: Make) -> None:
    # §3.2: "children of a Group are added with dMassAdd. Overlapping volumes are counted twice"
    body = _one_body(make("Solid { boundingObject Group { children [ Box { size 0.1 0.1 0.1 } "
                          "Box { size 0.1 0.1 0.1 } ] } physics Physics { } }"))
    assert body.mass == pytest.approx(2 * RHO * 0.001, rel=1e-12)


def test_a_primitive_in_a_pose_is_translated_and_the_com_is_its_centroid(make: Make) -> None:
    # §3.2: each primitive inside a Pose is rotated then translated by it; CoM = volume centroid: a 1 kg·(0.1)³
    # box at x = 0.3 and another at the origin: CoM x = 0.15; Iyy = 2·(m·0.02/12) + 2·m·0.15²
    body = _one_body(make("Solid { boundingObject Group { children [ Box { size 0.1 0.1 0.1 } "
                          "Pose { translation 0.3 0 0 children [ Box { size 0.1 0.1 0.1 } ] } ] } "
                          "physics Physics { } }"))
    m = RHO * 0.001
    assert body.com == pytest.approx((0.15, 0.0, 0.0), abs=1e-12)
    assert body.inertia[4] == pytest.approx(2 * m * 0.02 / 12 + 2 * m * 0.15**2, rel=1e-12)


def test_an_invalid_primitive_contributes_one_kilogram_and_identity_inertia(make: Make) -> None:
    # §3.2: "Invalid/zero-size primitives ... contribute mass 1 kg / identity inertia"
    body = _one_body(make("Solid { boundingObject Group { children [ Box { size 0 0.1 0.1 } "
                          "Box { size 0.1 0.1 0.1 } ] } physics Physics { } }"))
    m = RHO * 0.001
    assert body.mass == pytest.approx(1.0 + m, rel=1e-12)
    assert body.inertia[0] == pytest.approx(1.0 + m * 0.02 / 12, rel=1e-12)


def test_a_plane_contributes_no_mass(make: Make) -> None:
    # §3.2 mass rules sum primitives with volume; the Plane is infinite and static (§3.4): with a Box beside it,
    # the mass is the Box's
    body = _one_body(make("Solid { translation 0 0 1 boundingObject Group { children [ Plane { } "
                          "Box { size 0.1 0.1 0.1 } ] } physics Physics { } }"))
    assert body.mass == pytest.approx(RHO * 0.001, rel=1e-12)


def test_without_bounding_object_density_gives_mass_and_inertia_over_1000(make: Make) -> None:
    # §3.2: no boundingObject and no mass: "mass = density/1000 kg ... inertia = (density/1000)·identity"
    sim = make("Solid { physics Physics { density 500 } }")
    body = _one_body(sim)
    assert body.mass == pytest.approx(0.5)
    assert body.inertia == pytest.approx((0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5))
    assert any("no boundingObject" in w for w in sim.build_warnings)  # "A warning is printed"


def test_without_bounding_object_the_com_is_at_center_of_mass(make: Make) -> None:
    # §3.2: "CoM at centerOfMass or origin"; the body origin sits there (body at solid origin + CoM)
    body = _one_body(make("Solid { translation 1 0 0 physics Physics { mass 2 centerOfMass [ 0 0.5 0 ] } }"))
    assert body.com == pytest.approx((0.0, 0.5, 0.0))
    assert list(body.pos) == pytest.approx([1.0, 0.5, 0.0])


def test_an_inertia_matrix_without_center_of_mass_is_not_used(make: Make) -> None:
    # §3.2: CUSTOM_INERTIA_MATRIX needs "mass > 0, exactly one centerOfMass and a valid inertiaMatrix";
    # without centerOfMass the boundingObject gives the inertia, scaled to the mass (dMassAdjust)
    body = _one_body(make("Solid { boundingObject Box { size 0.1 0.2 0.3 } physics Physics { density -1 mass 2 "
                          "inertiaMatrix [ 1 1 1, 0 0 0 ] } }"))
    assert body.mass == pytest.approx(2.0)
    assert _diag(body.inertia) == pytest.approx((2 * 0.13 / 12, 2 * 0.10 / 12, 2 * 0.05 / 12), rel=1e-12)


def test_body_rotation_is_the_solid_frame_not_the_principal_axes(make: Make) -> None:
    # §3.2: "The body origin is placed at the CoM, its rotation = the Solid frame rotation (not principal axes)":
    # a box turned 0.3 rad about z inside the boundingObject gives off-diagonal inertia, the body stays unturned
    sim = make("Solid { translation 0 0 1 boundingObject Pose { rotation 0 0 1 0.3 children [ "
               "Box { size 0.4 0.1 0.1 } ] } physics Physics { } }")
    body = _one_body(sim)
    assert abs(body.inertia[1]) > 1e-6  # the inertia is not diagonal in the body frame
    assert _rotation(sim._lib.dBodyGetRotation(body.ptr)) == pytest.approx(m3.IDENTITY, abs=1e-15)


def test_solid_position_reads_back_as_body_position_minus_the_turned_com(make: Make) -> None:
    # §3.2: "Solid position = body position − R·CoM_local": a spinning Solid whose CoM is 0.2 m off its
    # origin along x turns about its CoM; its origin stays 0.2 m from the CoM, opposite R·(0.2, 0, 0)
    scene = ("Solid { translation 1 0 0 angularVelocity 0 0 2 boundingObject Sphere { radius 0.1 } "
             "physics Physics { mass 1 centerOfMass [ 0.2 0 0 ] } } Robot { supervisor TRUE }")
    sim = make(scene, "gravity 0 basicTimeStep 10 physicsDisableTime 0")
    sup = Supervisor(simulation=sim)
    solid = sup.getRoot().getField("children").getMFNode(1)
    for _ in range(25):
        sup.step(10)
    body = sim.bodies[0]
    R = _rotation(sim._lib.dBodyGetRotation(body.ptr))
    expected = m3.sub(tuple(body.pos), m3.mat_vec(R, (0.2, 0.0, 0.0)))
    assert solid.getPosition() == pytest.approx(list(expected), abs=1e-12)
    assert list(body.pos) == pytest.approx([1.2, 0.0, 0.0], abs=1e-12)  # the CoM does not move


def test_geoms_sit_at_the_solid_frame_not_at_the_com(make: Make) -> None:
    # §3.2: geoms placed at their world pose with offsets relative to the CoM: a box whose CoM is moved 0.2 m
    # stays where the Solid frame is
    sim = make("Solid { translation 0 0 1 boundingObject Box { size 0.1 0.1 0.1 } "
               "physics Physics { centerOfMass [ 0.2 0 0 ] } }")
    (gr,) = sim.geoms.values()
    assert list(ode.vec3(sim._lib.dGeomGetPosition(gr.ptr))) == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert list(_one_body(sim).pos) == pytest.approx([0.2, 0.0, 1.0], abs=1e-12)


# ------------------------------------------------------------------ §3.3 nesting, merging, static basis


@pytest.mark.parametrize("name", ["left wheel", "Right Wheel", "LEFT WHEEL"])
def test_solids_named_left_or_right_wheel_are_not_merged(make: Make, name: str) -> None:
    # §3.3: "Solids named "left wheel" / "right wheel" (case-insensitive) are not merged"
    sim = make(f'Solid {{ boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} children [ '
               f'Solid {{ name "{name}" translation 0.3 0 0 boundingObject Sphere {{ radius 0.05 }} '
               f'physics Physics {{ }} }} ] }}')
    assert len(sim.bodies) == 2


def test_a_plainly_nested_physics_solid_is_merged(make: Make) -> None:
    # §3.3 (control for the wheel rule): another name merges into one body
    sim = make('Solid { boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } children [ '
               'Solid { name "wheel" translation 0.3 0 0 boundingObject Sphere { radius 0.05 } '
               'physics Physics { } } ] }')
    assert len(sim.bodies) == 1


def test_a_physics_solid_under_a_static_basis_is_fixed_to_the_world(make: Make) -> None:
    # §3.3: a Solid with Physics under Solids without Physics up to the top gets its own body fixed to the world
    # (dJointCreateFixed attached to NULL): it never moves, even under gravity
    sim = make("Solid { children [ Pose { children [ Solid { children [ Solid { translation 0 0 1 "
               "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } ] } ] } ] }",
               "gravity 9.81 basicTimeStep 10")
    body = _one_body(sim)
    lib = probe()
    joints = [lib.dBodyGetJoint(body.ptr, i) for i in range(lib.dBodyGetNumJoints(body.ptr))]
    fixed = [j for j in joints if lib.dJointGetType(j) == 7]  # dJointTypeFixed
    assert len(fixed) == 1 and {lib.dJointGetBody(fixed[0], 0), lib.dJointGetBody(fixed[0], 1)} == {None, body.ptr}
    sim.step(50)
    assert list(body.pos) == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)


# ------------------------------------------------------------------ §3.4 boundingObject geometries


def _geom(sim: Simulation) -> int:
    (gr,) = sim.geoms.values()
    return gr.ptr


def test_box_size_is_the_full_extents(make: Make) -> None:
    # §3.4 table: Box size = full extents -> dCreateBox(sx, sy, sz) (ODE also full lengths)
    sim = make("Solid { boundingObject Box { size 0.1 0.2 0.3 } }")
    lengths = (ctypes.c_double * 4)()
    sim._lib.dGeomBoxGetLengths(_geom(sim), lengths)
    assert list(lengths)[:3] == pytest.approx([0.1, 0.2, 0.3])


def test_default_box_is_2_metres(make: Make) -> None:
    # §3.4 table: Box size default 2 2 2
    sim = make("Solid { boundingObject Box { } }")
    lengths = (ctypes.c_double * 4)()
    sim._lib.dGeomBoxGetLengths(_geom(sim), lengths)
    assert list(lengths)[:3] == [2.0, 2.0, 2.0]


@pytest.mark.parametrize(("kind", "cls"), [("Cylinder", 3), ("Capsule", 2)])
def test_cylinder_and_capsule_are_along_local_z_with_height_as_given(make: Make, kind: str, cls: int) -> None:
    # §3.4 table: dCreateCylinder(r, h) / dCreateCapsule(r, h) (capsule h = cylindrical part), axis = local z,
    # no extra rotation: the geom's rotation is the Solid's
    sim = make(f"Solid {{ rotation 1 0 0 0.5 boundingObject {kind} {{ radius 0.1 height 0.4 }} }}")
    g = _geom(sim)
    assert sim._lib.dGeomGetClass(g) == cls
    assert ode.primitive_size(sim._lib, g, cls) == pytest.approx((0.1, 0.2))
    expected = m3.rot_axis_angle((1.0, 0.0, 0.0, 0.5))
    assert _rotation(sim._lib.dGeomGetRotation(g)) == pytest.approx(expected, abs=1e-15)


def test_sphere_radius_default_is_1(make: Make) -> None:
    # §3.4 table: Sphere radius 1 -> dCreateSphere(r)
    sim = make("Solid { boundingObject Sphere { } }")
    assert sim._lib.dGeomSphereGetRadius(_geom(sim)) == 1.0


def test_plane_normal_is_the_turned_z_axis_and_offset_its_dot_with_the_position(make: Make) -> None:
    # §3.4 table: Plane -> dCreatePlane(n, d), n = upper Pose rotation·(0,0,1), d = n·position: a plane turned
    # 90° about x at (0, 2, 3): n = (0, -1, 0), d = -2
    sim = make("Solid { translation 0 2 3 rotation 1 0 0 1.5707963267948966 boundingObject Plane { } }")
    params = (ctypes.c_double * 4)()
    sim._lib.dGeomPlaneGetParams(_geom(sim), params)
    assert list(params) == pytest.approx([0.0, -1.0, 0.0, -2.0], abs=1e-12)


def test_a_plane_on_a_physics_solid_stays_static_with_a_warning(make: Make) -> None:
    # §3.4: "Plane cannot be attached to a body (... get a warning and the plane stays static)"
    sim = make("Solid { boundingObject Group { children [ Plane { } Box { size 0.1 0.1 0.1 } ] } "
               "physics Physics { } }")
    planes = [g for g in sim.geoms.values() if g.kind == "Plane"]
    assert len(planes) == 1 and probe().dGeomGetBody(planes[0].ptr) is None
    assert any("Plane cannot be attached" in w for w in sim.build_warnings)


def test_cone_is_not_a_bounding_geometry(make: Make) -> None:
    # §3.4: "Cone is not a valid bounding geometry (base class warns)"
    sim = make("Solid { boundingObject Cone { } }")
    assert not sim.geoms
    assert any("Cone is not a valid bounding geometry" in w for w in sim.build_warnings)
