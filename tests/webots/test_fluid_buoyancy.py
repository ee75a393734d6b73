"""Buoyancy: a Solid whose immersionProperties name a Fluid is pushed up by ρ_fluid · V_immersed · g at the
centroid of the immersed volume, before every physics step, as Webots does (Archimedes).

The worlds are small pools: a Fluid Box 4 × 4 × 1 m (surface at height 1 m) on a floor Plane. Expected values are
worked by hand. A free body obeys ODE's semi-implicit Euler step exactly, so one step from rest gives
``v = h·(F/m − g)``; equilibria are reached with Physics damping (buoyancy alone conserves energy, so a floating
body would bob for ever) and are checked within 2 mm: ODE puts a body to sleep once its speed stays under
0.01 m/s for 1 s, and a bobbing body of angular frequency ω ≥ 9 rad/s (ω² = ρ_f·g·A/m for these bodies) moving
that slowly is within 0.01/ω ≈ 1 mm of its rest height.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

G = 9.81
H = 0.016  # basicTimeStep 16
SURFACE = 1.0
ENU_POOL = "Fluid {{ translation 0 0 0.5 boundingObject Box {{ size 4 4 1 }} {fluid} }}"
NUE_POOL = "Fluid {{ translation 0 0.5 0 boundingObject Box {{ size 4 1 4 }} {fluid} }}"

WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 coordinateSystem "{cs}" }}
{pool}
DEF FLOATER Solid {{
  translation {translation}
  rotation {rotation}
  children [ Shape {{ geometry DEF G {geometry} }} ]
  boundingObject {bounding}
  physics Physics {{ density {density} {damping} }}
  {immersion}
}}
Solid {{ rotation {floor_rotation} children [ Shape {{ geometry DEF P Plane {{ size 10 10 }} }} ] boundingObject USE P
  name "floor" }}
"""
DAMPED = "damping Damping { linear 0.9 angular 0.9 }"


def world(
    geometry: str, translation: str, *, density: float = 500.0, rotation: str = "0 0 1 0", damping: str = "",
    fluid_name: str = "fluid", fluid: str = "", cs: str = "ENU", bounding: str = "USE G", pool: bool = True,
    pool_text: str | None = None,
) -> str:
    immersion = f'immersionProperties [ ImmersionProperties {{ fluidName "{fluid_name}" }} ]' if fluid_name else ""
    if pool_text is None:
        pool_text = (ENU_POOL if cs == "ENU" else NUE_POOL).format(fluid=fluid) if pool else ""
    return WORLD.format(cs=cs, pool=pool_text, translation=translation, rotation=rotation, geometry=geometry,
                        bounding=bounding, density=density, damping=damping, immersion=immersion,
                        floor_rotation="0 0 1 0" if cs == "ENU" else "1 0 0 -1.5707963267948966")


def simulate(text: str) -> Simulation:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(text))


def body_state(sim: Simulation) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    b = sim.bodies[0]
    return tuple(b.pos[:3]), tuple(b.lvel[:3]), tuple(b.avel[:3])


@pytest.mark.parametrize("density", [500.0, 300.0])
def test_a_light_box_comes_to_rest_floating_at_the_archimedes_depth(density: float) -> None:
    # a plate 0.4 × 0.4 × 0.1 (upright it is stable: metacentre far above its centre of mass); immersed depth
    # ρ_s/ρ_f · h, so its centre rests at SURFACE − depth + h/2
    sim = simulate(world("Box { size 0.4 0.4 0.1 }", "0 0 1.3", density=density, damping=DAMPED))
    try:
        sim.step(int(12.0 / H))
        (_, _, z), _, _ = body_state(sim)
        depth = density / 1000.0 * 0.1
        assert z == pytest.approx(SURFACE - depth + 0.05, abs=2e-3)
    finally:
        sim.close()


def test_a_box_floats_the_same_when_the_up_axis_is_y() -> None:
    sim = simulate(world("Box { size 0.4 0.1 0.4 }", "0 1.3 0", density=300.0, damping=DAMPED, cs="NUE"))
    try:
        sim.step(int(12.0 / H))
        (x, y, z), _, _ = body_state(sim)
        assert y == pytest.approx(SURFACE - 0.03 + 0.05, abs=2e-3)
        assert abs(x) < 1e-6 and abs(z) < 1e-6
    finally:
        sim.close()


def test_a_sphere_floats_where_its_cap_displaces_its_mass() -> None:
    r, density = 0.1, 250.0
    mass = density * 4.0 / 3.0 * math.pi * r**3
    # cap height c with π·c²·(3r − c)/3 = m/ρ_f, by bisection on [0, 2r] (the cap volume grows with c)
    lo, hi = 0.0, 2 * r
    for _ in range(100):
        c = (lo + hi) / 2
        lo, hi = (c, hi) if math.pi * c * c * (3 * r - c) / 3 < mass / 1000.0 else (lo, c)
    sim = simulate(world(f"Sphere {{ radius {r} }}", "0 0 1.4", density=density, damping=DAMPED))
    try:
        sim.step(int(12.0 / H))
        (_, _, z), _, _ = body_state(sim)
        assert z == pytest.approx(SURFACE + r - c, abs=2e-3)
    finally:
        sim.close()


def test_a_dense_box_sinks_with_its_weight_less_the_displaced_water_and_rests_on_the_pool_floor() -> None:
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 0.5", density=2000.0))
    try:
        sim.step(10)  # fully immersed, no damping: a = g·(1 − ρ_f/ρ_s) = g/2 downwards
        _, (_, _, vz), _ = body_state(sim)
        assert vz == pytest.approx(-10 * H * G * 0.5, rel=1e-9)
        sim.step(int(5.0 / H))
        (_, _, z), (_, _, vz), _ = body_state(sim)
        assert 0.1 - 3e-3 < z < 0.1 + 1e-4  # on the floor, sunk into it by ODE's soft contact at most
        assert abs(vz) < 1e-3
    finally:
        sim.close()


ROTATED_POOL = "Pose { translation 0 0 0.5 children [ Fluid { rotation 1 0 0 1.5707963267948966 boundingObject " \
               "Pose { children [ Box { size 4 1 4 } ] } } ] }"  # the same water, its box turned: local y is up


@pytest.mark.parametrize("pool", [None, ROTATED_POOL], ids=["aligned", "rotated"])
def test_the_force_at_a_known_partial_immersion_is_rho_v_g(pool: str | None) -> None:
    # a 0.2 cube (4 kg) at rest, level, 5 cm below the surface: V = 0.2·0.2·0.05
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 1.05", pool_text=pool))
    try:
        sim.step(1)
        _, (vx, vy, vz), w = body_state(sim)
        force = 1000.0 * 0.2 * 0.2 * 0.05 * G
        assert vz == pytest.approx(H * (force / 4.0 - G), rel=1e-9)
        assert abs(vx) < 1e-12 and abs(vy) < 1e-12 and max(map(abs, w)) < 1e-12
    finally:
        sim.close()


def test_a_tilted_box_displaces_the_clipped_triangle_prism() -> None:
    # the cube turned 45° about x is a diamond in the y-z plane: its lowest edge at 1.05 − 0.1·√2; below the
    # surface it immerses a triangular prism of depth t, cross-section t² (width 2t at height t), length 0.2
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 1.05", rotation=f"1 0 0 {math.pi / 4}"))
    try:
        sim.step(1)
        _, (_, vy, vz), w = body_state(sim)
        t = SURFACE - (1.05 - 0.1 * math.sqrt(2.0))
        force = 1000.0 * 0.2 * t * t * G
        assert vz == pytest.approx(H * (force / 4.0 - G), rel=1e-9)
        assert abs(vy) < 1e-12 and max(map(abs, w)) < 1e-9  # the prism's centroid is under the centre
    finally:
        sim.close()


def test_a_box_across_the_fluid_wall_displaces_only_the_water_inside() -> None:
    # a 0.2 cube of density 2000 (16 kg) deep under water, its centre on the wall x = 2: half of it is in the
    # water, the force acting at x = 1.95, 5 cm from its centre of mass, so it also turns about y
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "2 0 0.5", density=2000.0))
    try:
        sim.step(1)
        _, (_, _, vz), (_, wy, _) = body_state(sim)
        force = 1000.0 * 0.004 * G
        assert vz == pytest.approx(H * (force / 16.0 - G), rel=1e-9)
        assert wy == pytest.approx(H * (0.05 * force) / (16.0 * 0.08 / 12), rel=1e-9)
    finally:
        sim.close()


def test_the_force_acts_at_the_centroid_of_the_immersed_volume() -> None:
    # two 0.2 cubes (density 500: 4 kg each) on one body, at x = −0.3 (centre 1.05, 5 cm immersed) and
    # x = +0.3 (centre 1.0, 10 cm immersed): the difference of their buoyancies turns the body about y
    bounding = ("Group { children [ Pose { translation -0.3 0 0 children [ Box { size 0.2 0.2 0.2 } ] } "
                "Pose { translation 0.3 0 -0.05 children [ Box { size 0.2 0.2 0.2 } ] } ] }")
    sim = simulate(world("Box { size 0.01 0.01 0.01 }", "0 0 1.05", bounding=bounding))
    try:
        sim.step(1)
        _, (_, _, vz), (_, wy, _) = body_state(sim)
        m = 4.0
        f1 = 1000.0 * 0.04 * 0.05 * G  # the left cube
        f2 = 1000.0 * 0.04 * 0.10 * G  # the right cube
        assert vz == pytest.approx(H * ((f1 + f2) / (2 * m) - G), rel=1e-9)
        # about the centre of mass (0, 0, −0.025 from the Solid's origin): forces at x = ∓0.3 along +z
        # give τ_y = −x·F summed; the cubes' inertia about y plus their parallel-axis terms
        tau_y = -(-0.3 * f1 + 0.3 * f2)
        inertia = 2 * (m * (0.2**2 + 0.2**2) / 12 + m * (0.3**2 + 0.025**2))
        assert wy == pytest.approx(H * tau_y / inertia, rel=1e-9)
    finally:
        sim.close()


def test_a_solid_whose_fluid_name_matches_no_fluid_falls_as_in_air() -> None:
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 0.5", fluid_name="oil"))
    try:
        sim.step(10)
        _, (_, _, vz), _ = body_state(sim)
        assert vz == pytest.approx(-10 * H * G, rel=1e-12)
    finally:
        sim.close()


def test_a_renamed_fluid_pushes_the_solids_that_name_it() -> None:
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 0.5", fluid_name="oil", fluid='name "oil" density 800'))
    try:
        sim.step(10)  # a box of density 500 fully in oil: a = g·(800/500 − 1) upwards
        _, (_, _, vz), _ = body_state(sim)
        assert vz == pytest.approx(10 * H * G * (800.0 / 500.0 - 1.0), rel=1e-9)
    finally:
        sim.close()


def test_cylinders_and_capsules_get_their_true_volume_when_fully_immersed() -> None:
    for geometry, volume in (("Cylinder { radius 0.1 height 0.2 }", math.pi * 0.01 * 0.2),
                             ("Capsule { radius 0.1 height 0.2 }", math.pi * 0.01 * 0.2 + 4 / 3 * math.pi * 0.001)):
        sim = simulate(world(geometry, "0 0 0.5", density=2000.0))
        try:
            sim.step(1)
            _, (_, _, vz), _ = body_state(sim)
            mass = 2000.0 * volume
            assert vz == pytest.approx(H * (1000.0 * volume * G / mass - G), rel=1e-9), geometry
        finally:
            sim.close()


def test_a_half_immersed_cylinder_gets_half_its_volume() -> None:
    # upright (axis along z), centre on the surface: the polyhedron of revolution is cut in half exactly
    sim = simulate(world("Cylinder { radius 0.1 height 0.2 }", "0 0 1.0", density=2000.0))
    try:
        sim.step(1)
        _, (_, _, vz), _ = body_state(sim)
        volume = math.pi * 0.01 * 0.2
        assert vz == pytest.approx(H * (1000.0 * volume / 2 * G / (2000.0 * volume) - G), rel=1e-9)
    finally:
        sim.close()


@pytest.mark.parametrize("kind", ["Cylinder", "Capsule"])
def test_a_lying_cylinder_or_capsule_partly_immersed_gets_its_volume_within_two_percent(kind: str) -> None:
    # axis horizontal (turned about x), 5 cm of its 20 cm diameter under water: the immersed part is a
    # circular segment times the length (plus, for a capsule, two half caps making one spherical cap of
    # height d); the 24-sided polyhedron of revolution is within 1.5 % of it
    r, length, d = 0.1, 0.2, 0.05
    segment = r * r * math.acos((r - d) / r) - (r - d) * math.sqrt(2 * r * d - d * d)
    exact = segment * length + (math.pi * d * d * (3 * r - d) / 3 if kind == "Capsule" else 0.0)
    volume = math.pi * r * r * (length + (4 / 3 * r if kind == "Capsule" else 0.0))
    mass = 500.0 * volume
    sim = simulate(world(f"{kind} {{ radius {r} height {length} }}", f"0 0 {SURFACE + r - d}",
                         rotation=f"1 0 0 {math.pi / 2}"))
    try:
        sim.step(1)
        _, (_, _, vz), _ = body_state(sim)
        displaced = (vz / H + G) * mass / (1000.0 * G)
        assert displaced == pytest.approx(exact, rel=0.02)
    finally:
        sim.close()


def test_a_world_without_a_fluid_steps_as_it_did_without_immersion_properties() -> None:
    # control: immersionProperties and no Fluid change nothing, bit for bit, and register no step hook
    states = []
    for name in ("fluid", ""):
        sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 0.5", rotation="1 1 0 0.4", fluid_name=name,
                             pool=False))
        try:
            assert sim.pre_step_hooks == [] and "buoyancy" not in sim.extensions
            trace = []
            for _ in range(60):
                sim.step(1)
                trace.append(body_state(sim))
            states.append(trace)
        finally:
            sim.close()
    assert states[0] == states[1]


def test_a_supervisor_edit_of_the_fluid_counts_from_the_next_step() -> None:
    # the box (density 500, 4 kg) is fully immersed; the water turns denser, then the pool moves away
    pool = "DEF WATER Fluid { translation 0 0 0.5 boundingObject Box { size 4 4 1 } }"
    text = world("Box { size 0.2 0.2 0.2 }", "0 0 0.5", pool_text=pool)
    text += 'Robot { name "judge" supervisor TRUE controller "<none>" }\n'
    sim = simulate(text)
    try:
        sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
        water = sup.getFromDef("WATER")
        _, (_, _, v0), _ = body_state(sim)
        water.getField("density").setSFFloat(1500.0)
        sim.step(1)
        _, (_, _, v1), _ = body_state(sim)
        assert v1 - v0 == pytest.approx(H * (1500.0 * 0.008 * G / 4.0 - G), rel=1e-9)
        water.getField("translation").setSFVec3f([10.0, 0.0, 0.5])
        sim.step(1)
        _, (_, _, v2), _ = body_state(sim)
        assert v2 - v1 == pytest.approx(-H * G, rel=1e-9)
    finally:
        sim.close()


def test_a_reset_world_floats_again_as_it_did() -> None:
    # dropped from 10 cm above the surface, the box falls into the water; after simulationReset it does the same
    sim = simulate(world("Box { size 0.2 0.2 0.2 }", "0 0 1.2", density=400.0))
    try:
        runs = []
        for _ in range(2):
            trace = []
            for _ in range(20):
                sim.step(1)
                trace.append(body_state(sim))
            runs.append(trace)
            sim.reset()
        assert runs[0] == runs[1]
        assert runs[0][-1][1][2] > -20 * H * G + 1.0  # the water slowed its fall (0.5 m above the floor in air)
    finally:
        sim.close()
