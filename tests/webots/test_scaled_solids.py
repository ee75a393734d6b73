"""Solids below a scaled Transform (webots-on-ode.md §3.1: Transform = Pose + ``scale``, a world frame is the product
of its ancestors' matrices; §3.2: "with a scaled Transform ancestor, sizes scale, mass ∝ s³ and inertia ∝ s⁵";
§3.4: "geometries inside a scaled Transform use scaled dimensions"). The twin used to ignore such a scale with a
warning: the Solid sat at its unscaled translation with its unscaled box and mass.

Every expected value is computed by hand in the test's comment; each test has its scale-1 control.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation
from tests.support.kicks import FORCE, TORQUE, kick, supervisor_in
from tests.support.quiet_worlds import quiet_supervisor

HEADER = "#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {step} }}\n"
FLOOR = "Solid { name \"floor\" boundingObject Plane { size 10 10 } }\n"


def falling_box(scale: float) -> str:
    """A 0.1 m cube 0.5 m up in a Transform scaled by ``scale``, a Pose 0.1 m above its centre inside it."""
    return (f"Transform {{ translation 0 0 0.2 scale {scale} {scale} {scale} children [ DEF BOX Solid {{ "
            "translation 0 0 0.5 children [ DEF MARK Pose { translation 0 0 0.1 } ] "
            "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } ] }\n" + FLOOR)


@pytest.mark.parametrize(("scale", "start", "mark", "rest"), [
    # start: the Transform's own translation is not scaled (0.2), the Solid's is: 0.2 + 2·0.5 = 1.2 m; the Pose
    # inside the Solid 2·0.1 = 0.2 m above its centre; at rest the 0.2 m cube's centre is 0.1 m above the floor
    (2.0, 1.2, 0.2, 0.1),
    (1.0, 0.7, 0.1, 0.05),  # control: 0.2 + 0.5, 0.1 above, a 0.1 m cube rests at 0.05
])
def test_a_box_below_a_scaled_transform_starts_and_rests_scaled(scale: float, start: float, mark: float,
                                                                 rest: float) -> None:
    sup = supervisor_in(falling_box(scale), 4, gravity=9.81)
    box, marker = sup.getFromDef("BOX"), sup.getFromDef("MARK")
    try:
        assert box.getPosition()[2] == pytest.approx(start - 0.5 * 9.81 * 0.004**2, abs=1e-4)  # one step fallen
        assert marker.getPosition()[2] - box.getPosition()[2] == pytest.approx(mark, abs=1e-12)
        while sup.getTime() < 1.5:  # fallen 1.1 m at most (0.47 s) and settled
            sup.step(4)
        assert box.getPosition()[2] == pytest.approx(rest, abs=2e-3)  # ODE's contacts sink a millimetre or so
        assert box.getOrientation() == pytest.approx((1, 0, 0, 0, 1, 0, 0, 0, 1), abs=1e-6)  # a rotation, unscaled
    finally:
        sup.simulation.close()


@pytest.mark.parametrize(("scale", "physics", "mass", "inertia"), [
    # a density: the 0.2 m cube weighs 1000·0.2³ = 8 kg, Izz = 8·(0.2² + 0.2²)/12 = 0.05333 kg·m²
    (2.0, "Physics { }", 8.0, 8 * 0.08 / 12),
    # a given mass is scaled as the whole distribution is (§3.2: mass ∝ s³): 2·2³ = 16 kg; its box inertia
    # 2·(0.1² + 0.1²)/12 = 0.003333 times 2⁵ = 0.10667 (that of a 16 kg 0.2 m cube: 16·0.08/12)
    (2.0, "Physics { density -1 mass 2 }", 16.0, 16 * 0.08 / 12),
    # an inertiaMatrix too (inertia ∝ s⁵): 0.3·2⁵ = 9.6 kg·m² about z, the mass 16 kg
    (2.0, "Physics { density -1 mass 2 centerOfMass [ 0 0 0 ] inertiaMatrix [ 0.1 0.2 0.3, 0 0 0 ] }", 16.0, 9.6),
    (1.0, "Physics { density -1 mass 2 }", 2.0, 2 * 0.02 / 12),  # control at scale 1
])
def test_a_scaled_solids_mass_and_inertia_read_through_a_kick(scale: float, physics: str, mass: float,
                                                               inertia: float) -> None:
    # one 4 ms step of 1 N and 0.01 N·m (tests/support/kicks.py) adds h·F/m to the speed and h·τ/I to the spin
    scene = (f"Transform {{ scale {scale} {scale} {scale} children [ DEF BODY Solid {{ "
             f"boundingObject Box {{ size 0.1 0.1 0.1 }} physics {physics} }} ] }}")
    sup = supervisor_in(scene, 4)
    try:
        dv, dw = kick(sup, 4)
        assert dv == pytest.approx(0.004 * FORCE / mass, rel=1e-9)
        assert dw == pytest.approx(0.004 * TORQUE / inertia, rel=1e-9)
    finally:
        sup.simulation.close()


def pendulum(scale: float) -> str:
    """A Robot holding, in a Transform scaled by ``scale``, a hinge (axis y) anchored 0.25 m up and a 2 cm bob 0.5 m
    from the anchor, started 0.05 rad from the vertical (all lengths before the scale)."""
    theta = 0.05
    x, z = 0.5 * math.sin(theta), 0.25 - 0.5 * math.cos(theta)
    return (f"Robot {{ translation 0 0 2 children [ Transform {{ scale {scale} {scale} {scale} children [ "
            "HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 anchor 0 0 0.25 } "
            f"endPoint DEF BOB Solid {{ translation {x!r} 0 {z!r} "
            "boundingObject Sphere { radius 0.02 } physics Physics { } } } ] } ] }\n")


def period(scale: float) -> float:
    """The pendulum's period (s), from the times its bob crosses the vertical under the anchor going the same way."""
    world = load_world_text(HEADER.format(step=1) + pendulum(scale), "pendulum.wbt")
    sim = Simulation(world)
    try:
        (bob,) = [s for s in sim.solids if s.node.def_name == "BOB"]
        crossings: list[float] = []
        previous = sim.solid_world_pose(bob).t[0]
        while len(crossings) < 4:
            sim.step()
            x = sim.solid_world_pose(bob).t[0]
            if previous > 0 >= x:  # linear interpolation within the step
                crossings.append(sim.time - sim.dt * x / (x - previous))
            previous = x
        return (crossings[-1] - crossings[0]) / 3
    finally:
        sim.close()


@pytest.mark.parametrize(("scale", "length", "radius"), [
    # scaled: anchor at 2·0.25, bob 2·0.5 = 1.0 m from it (an unscaled anchor would make it 0.75 m), radius 0.04 m
    (2.0, 1.0, 0.04),
    (1.0, 0.5, 0.02),  # control
])
def test_a_pendulum_below_a_scaled_transform_swings_with_its_scaled_length(scale: float, length: float,
                                                                           radius: float) -> None:
    # a solid sphere on a massless hinge: I/m = L² + 2r²/5 about the anchor, T = 2π·√(I/(m·g·L)), times the
    # amplitude's 1 + θ²/16 (θ = 0.05: 1.00016); scaled: 2π·√(1.00064/9.81) · 1.00016 = 2.0070 s, control:
    # 2π·√(0.25016/(9.81·0.5))·1.00016 = 1.4193 s
    expected = 2 * math.pi * math.sqrt((length**2 + 0.4 * radius**2) / (9.81 * length)) * (1 + 0.05**2 / 16)
    assert period(scale) == pytest.approx(expected, rel=2e-3)


def test_a_non_positive_or_non_uniform_scale_above_a_solid_says_so_in_one_line() -> None:
    # a zero component is reset to 1 (scale 1 2 1), then the non-uniform scale acts as its largest factor: 2
    world = load_world_text(HEADER.format(step=4) + "Transform { scale 0 2 1 children [ Solid { translation 0 0 1 "
                            "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } ] }\n", "s.wbt")
    with pytest.warns(UserWarning) as caught:
        sim = Simulation(world)
    try:
        (body,) = sim.bodies
        assert body.mass == pytest.approx(1000 * 0.2**3)
        assert sim.solid_world_pose(body.root).t == pytest.approx((0.0, 0.0, 2.0))
    finally:
        sim.close()
    lines = [str(w.message) for w in caught]
    assert sum("must be positive; reset to 1" in line for line in lines) == 1
    assert sum("not uniform above a Solid or joint: scaled by its largest factor 2" in line for line in lines) == 1
    assert all("\n" not in line for line in lines)


def test_run_time_moves_below_a_scaled_transform_are_scaled_as_at_load() -> None:
    # Transform { scale 2 } holding a Pose at 0 0 0.5 that holds the Solid at 0 0 0.25: the Solid is 2·0.5 + 2·0.25
    # = 1.5 m up; its translation field reads back unscaled
    scene = ("Transform { scale 2 2 2 children [ DEF FRAME Pose { translation 0 0 0.5 children [ DEF BOX Solid { "
             "translation 0 0 0.25 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } ] } ] }\n"
             "DEF HOLDER Transform { scale 3 3 3 children [ ] }")
    sup = supervisor_in(scene, 4)
    box = sup.getFromDef("BOX")
    try:
        assert box.getPosition() == pytest.approx((0.0, 0.0, 1.5), abs=1e-12)
        assert box.getField("translation").getSFVec3f() == pytest.approx((0.0, 0.0, 0.25), abs=1e-12)
        box.getField("translation").setSFVec3f([0.1, 0.0, 0.25])  # a supervisor move: 2·0.1 = 0.2 m along x
        sup.step(4)
        assert box.getPosition() == pytest.approx((0.2, 0.0, 1.5), abs=1e-12)
        assert box.getField("translation").getSFVec3f() == pytest.approx((0.1, 0.0, 0.25), abs=1e-12)
        sup.getFromDef("FRAME").getField("translation").setSFVec3f([0.0, 0.0, 1.0])  # the Pose: 2·(1 - 0.5) up
        sup.step(4)
        assert box.getPosition() == pytest.approx((0.2, 0.0, 2.5), abs=1e-12)
        # a Solid imported into the Transform scaled by 3: 3·0.1 = 0.3 m up, its 0.1 m cube 27 kg
        sup.getFromDef("HOLDER").getField("children").importMFNodeFromString(
            -1, "DEF NEW Solid { translation 0 0 0.1 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } }")
        sup.step(4)
        assert sup.getFromDef("NEW").getPosition() == pytest.approx((0.0, 0.0, 0.3), abs=1e-12)
        (new,) = [b for b in sup.simulation.bodies if b.root.node.def_name == "NEW"]
        assert new.mass == pytest.approx(1000 * 0.3**3)
    finally:
        sup.simulation.close()


def test_a_run_time_scale_edit_above_a_solid_is_not_applied_to_it_and_says_so() -> None:
    # decided (the reference is silent on run-time scale edits): the Solid keeps the load's scale, a warning says so
    sup = supervisor_in("DEF T Transform { scale 2 2 2 children [ Pose { translation 0 0 0.5 children [ DEF BOX "
                        "Solid { boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } } ] } ] }", 4)
    try:
        with pytest.warns(UserWarning, match="run-time edit of a Transform's scale above Solids or joints is not "
                                             "applied to them"):
            sup.getFromDef("T").getField("scale").setSFVec3f([3.0, 3.0, 3.0])
            sup.step(4)
        assert sup.getFromDef("BOX").getPosition() == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
        assert sup.simulation.bodies[0].mass == pytest.approx(1000 * 0.2**3)
        # a later move of the Transform keeps that scale below it, for the Pose too: 1 + 2·0.5 = 2 m up (not 2.5)
        sup.getFromDef("T").getField("translation").setSFVec3f([0.0, 0.0, 1.0])
        sup.step(4)
        assert sup.getFromDef("BOX").getPosition() == pytest.approx((0.0, 0.0, 2.0), abs=1e-12)
    finally:
        sup.simulation.close()


def test_a_box_resized_at_run_time_below_a_scaled_transform_stays_scaled() -> None:
    # the 0.1 m cube set to 0.2 m below scale 2: a 0.4 m cube of 1000·0.4³ = 64 kg, resting 0.2 m above the floor
    sup = supervisor_in("Transform { scale 2 2 2 children [ DEF BOX Solid { translation 0 0 0.5 "
                        "boundingObject DEF CUBE Box { size 0.1 0.1 0.1 } physics Physics { } } ] }\n" + FLOOR, 4,
                        gravity=9.81)
    try:
        sup.getFromDef("CUBE").getField("size").setSFVec3f([0.2, 0.2, 0.2])
        sup.step(4)
        assert sup.simulation.bodies[0].mass == pytest.approx(1000 * 0.4**3)
        while sup.getTime() < 1.5:
            sup.step(4)
        # (ODE's soft contacts sink deeper under a heavier body: about 3 mm under these 64 kg)
        assert sup.getFromDef("BOX").getPosition()[2] == pytest.approx(0.2, abs=5e-3)
    finally:
        sup.simulation.close()


@pytest.mark.parametrize(("scale", "speed"), [
    # the pool Fluid { translation 0 0 0.25, Box 2 x 2 x 0.5 } in scale 2: a 4 x 4 x 1 m box, its surface 1 m up; the
    # 0.2 m cube of density 500 at 0.5 m is wholly under it: F/m = (1000/500)·g, one 16 ms step from rest adds
    # h·(2g - g) = 0.016·9.81 = 0.15696 m/s upwards
    (2.0, 0.016 * 9.81),
    (1.0, 0.0),  # control: the surface 0.5 m up, the cube half under it, F/m = g: it stays at rest
])
def test_a_fluid_below_a_scaled_transform_is_scaled(scale: float, speed: float) -> None:
    world = load_world_text(HEADER.format(step=16) + (
        f"Transform {{ scale {scale} {scale} {scale} children [ Fluid {{ translation 0 0 0.25 "
        "boundingObject Box { size 2 2 0.5 } } ] }\n"
        "DEF FLOATER Solid { translation 0 0 0.5 boundingObject Box { size 0.2 0.2 0.2 } "
        'physics Physics { density 500 } immersionProperties [ ImmersionProperties { fluidName "fluid" } ] }\n'),
        "pool.wbt")
    sim = Simulation(world)
    try:
        (body,) = sim.bodies
        sim.step()
        assert body.lvel[2] == pytest.approx(speed, abs=1e-9)
    finally:
        sim.close()


def test_a_camera_draws_a_solid_below_a_non_uniform_scale_as_the_physics_sizes_it() -> None:
    # scale 1 1 2 above a Solid acts as 2 (its largest factor) in the physics; the drawing used its x factor (1), so
    # cameras saw a 0.1 m cube where a 0.2 m one collides: the drawn box's half extents are 0.1 m, like the geom's
    from dualtwin.webots.visual_scene import WebotsVisualScene

    with pytest.warns(UserWarning, match="not uniform above a Solid or joint"):
        sup = supervisor_in("Transform { scale 1 1 2 children [ Solid { children [ Shape { geometry DEF CUBE Box { "
                            "size 0.1 0.1 0.1 } } ] boundingObject USE CUBE } ] }", 4)
    try:
        scene = WebotsVisualScene(sup)
        assert [list(scene.model.geom_size[i]) for i in range(scene.model.ngeom)] == [pytest.approx([0.1] * 3)]
        (geom,) = [g for g in sup.simulation.geoms.values() if g.kind == "Box"]
        assert geom.scale == (2.0, 2.0, 2.0)
    finally:
        sup.simulation.close()


def test_a_camera_draws_a_solid_below_an_edited_scale_as_the_physics_and_the_rays_keep_it() -> None:
    # decided (the reference is silent on run-time scale edits): the Solid keeps the load's scale 2, so its 0.1 m cube
    # collides and is seen by rays as a 0.2 m cube after 'scale 3 3 3' is written, and is drawn so (half size 0.1 m);
    # the camera drew it with the written scale, a 0.3 m cube (half size 0.15 m) around the body scale 2 placed
    from dualtwin.webots.visual_rays import VisualGeoms
    from dualtwin.webots.visual_scene import WebotsVisualScene

    sup = supervisor_in("DEF T Transform { scale 2 2 2 children [ Solid { children [ Shape { geometry DEF CUBE Box { "
                        "size 0.1 0.1 0.1 } } ] boundingObject USE CUBE } ] }", 4)
    try:
        with pytest.warns(UserWarning, match="run-time edit of a Transform's scale above Solids or joints"):
            sup.getFromDef("T").getField("scale").setSFVec3f([3.0, 3.0, 3.0])
            sup.step(4)
        scene = WebotsVisualScene(sup)
        assert [list(scene.model.geom_size[i]) for i in range(scene.model.ngeom)] == [pytest.approx([0.1] * 3)]
        rays = VisualGeoms(sup.simulation)
        assert [geom.scale for geom in rays.geoms] == [(2.0, 2.0, 2.0)]  # the box the rays see: 2 · 0.1 m
        rays.close()
    finally:
        sup.simulation.close()


@pytest.mark.parametrize(("scale", "spin"), [
    # webots-devices.md §8: the thrust T·a_w acts at p_cot = upperPose·centerOfThrust, the upper Pose's matrix holding
    # the scale above it (on-ODE §3.1): below scale 2 the centre of thrust (0.1, 0, 0) is 0.2 m from the body's
    # centre. T = t1·ω² = 1e-4·100² = 1 N along z: a torque of -0.2 N·m about y on the drone, whose 1 kg 0.1 m cube is
    # magnified (§3.2) to I = (1/600)·2⁵ = 32/600 kg·m²: -3.75 rad/s², -0.015 rad/s over 4 ms (unscaled lever:
    # -1.875, half of it)
    (2.0, -3.75 * 0.004),
    (1.0, -60 * 0.004),  # control at scale 1: -0.1 N·m on I = 1/600: -60 rad/s²
])
def test_a_propeller_below_a_scaled_transform_pushes_at_its_scaled_centre_of_thrust(scale: float,
                                                                                      spin: float) -> None:
    sup = quiet_supervisor("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 gravity 0 }\n" + f"Transform {{ scale {scale} {scale} {scale} children [ DEF DRONE "
                           "Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
                           "children [ Propeller { shaftAxis 0 0 1 centerOfThrust 0.1 0 0 thrustConstants 1e-4 0 "
                           'torqueConstants 0 0 device RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 } '
                           "} ] } ] }")
    try:
        prop = sup.getDevice("prop")
        prop.setPosition(math.inf)
        prop.setVelocity(100.0)
        for _ in range(50):  # spun up (1000 rad/s² reach 100 rad/s in 0.1 s)
            sup.step(4)
        before = sup.getFromDef("DRONE").getVelocity()[4]
        sup.step(4)
        assert sup.getFromDef("DRONE").getVelocity()[4] - before == pytest.approx(spin, rel=2e-2)
    finally:
        sup.simulation.close()


@pytest.mark.parametrize(("scale", "inside", "seen"), [
    # a zero component is reset to 1, as the load says in its warning (solid_scale): the rays saw no box at all
    ("0 1 1", "", (1.0, 1.0, 1.0)),
    # beside a Solid, the non-uniform scale acts as its largest factor, as the camera draws it: the rays took it per
    # axis, a 0.1 x 0.1 x 0.2 m box where the camera draws a 0.2 m cube
    ("1 1 2", "Solid { name \"inner\" }", (2.0, 2.0, 2.0)),
    ("1 1 2", "", (1.0, 1.0, 2.0)),  # control: Shapes alone, per axis in both versions
])
def test_rays_see_the_shapes_below_a_transform_scale_as_the_load_reads_it(scale: str, inside: str,
                                                                          seen: tuple[float, ...]) -> None:
    from dualtwin.webots.visual_rays import VisualGeoms

    world = load_world_text(HEADER.format(step=4) + f"Solid {{ children [ Transform {{ scale {scale} children [ "
                            f"Shape {{ geometry Box {{ size 0.1 0.1 0.1 }} }} {inside} ] }} ] }}")
    with warnings.catch_warnings():  # (the load's line about the scale)
        warnings.simplefilter("ignore")
        sim = Simulation(world)
    try:
        rays = VisualGeoms(sim)
        assert [geom.scale for geom in rays.geoms] == [seen]
        rays.close()
    finally:
        sim.close()
