"""Section 1 of the Webots-on-ODE specification (/work/shared/reference/webots-on-ode.md, restated in
docs/reference/webots-on-ode.md): WorldInfo defaults and their ODE mapping, the ODE world and space set-up,
auto-disable, the damping conversion, and the order of one step; plus Appendix A's build facts. One test per
fact; the expected values come from the specification's lines (cited) or hand computation, and the ODE state is
read back through ODE's own getters (tests/support/ode_probe.py)."""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Iterator

import pytest

from dualtwin.webots import ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.ode_probe import contact_joints, probe, simulations

BOX = ("DEF BOX Solid {{ translation 0 0 {z} boundingObject Box {{ size 0.1 0.1 0.1 }} "
       "physics Physics {{ {phys} }} {extra} }}")
FLOOR = "Solid { name \"floor\" boundingObject Plane { } }"

Make = Callable[..., Simulation]


@pytest.fixture
def make() -> Iterator[Make]:
    """``make(scene, info="")``: a Simulation of ``scene`` (world nodes as text) under ``WorldInfo { info }``."""
    with simulations() as build:
        yield build


def _box(z: float = 1.0, phys: str = "", extra: str = "") -> str:
    return BOX.format(z=z, phys=phys, extra=extra)


def _gravity(sim: Simulation) -> tuple[float, ...]:
    out = (ctypes.c_double * 4)()
    probe().dWorldGetGravity(sim._world, out)
    return out[0], out[1], out[2]


# ------------------------------------------------------------------ §1.1 WorldInfo fields


def test_gravity_default_is_9_81_along_minus_z_in_enu(make: Make) -> None:
    # §1.1 table: gravity 9.81, ENU: dWorldSetGravity(0, 0, -g)
    assert _gravity(make(_box())) == (0.0, 0.0, -9.81)


def test_gravity_in_nue_is_along_minus_y(make: Make) -> None:
    # §1.1 table: NUE: (0, -g, 0)
    assert _gravity(make(_box(), 'coordinateSystem "NUE" gravity 3')) == (0.0, -3.0, 0.0)


def test_world_erp_and_cfm_defaults_reach_ode(make: Make) -> None:
    # §1.1 table: CFM 0.00001 -> dWorldSetCFM, ERP 0.2 -> dWorldSetERP
    sim = make(_box())
    assert probe().dWorldGetERP(sim._world) == 0.2
    assert probe().dWorldGetCFM(sim._world) == 0.00001


@pytest.mark.parametrize(("info", "erp", "cfm"), [("CFM 0", 0.2, 1e-5), ("CFM -3", 0.2, 1e-5),
                                                  ("ERP 1.5", 0.2, 1e-5), ("ERP -0.1", 0.2, 1e-5),
                                                  ("ERP 1 CFM 0.5", 1.0, 0.5)])
def test_world_cfm_not_positive_and_erp_outside_0_1_are_reset_at_load(make: Make, info: str, erp: float,
                                                                       cfm: float) -> None:
    # §1.1 table: CFM "reset to 1e-5 if ≤ 0", ERP "reset to 0.2 if outside [0,1]"
    sim = make(_box(), info)
    assert (probe().dWorldGetERP(sim._world), probe().dWorldGetCFM(sim._world)) == (erp, cfm)


@pytest.mark.parametrize("step", ["0", "-8"])
def test_basic_time_step_not_positive_is_reset_to_32_ms(make: Make, step: str) -> None:
    # §1.1 table: basicTimeStep "reset to 32 if ≤ 0"; step size = basicTimeStep·0.001 s
    sim = make(_box(), f"basicTimeStep {step}")
    assert sim.dt == 0.032
    sim.step()
    assert sim.time == pytest.approx(0.032)


def test_world_info_random_seed_seeds_odes_generator(make: Make) -> None:
    # §1.1 table: randomSeed seeds dRandSetSeed (Appendix A.7: "call it anyway for parity")
    sim = make(_box(), "randomSeed 7")
    assert sim._lib.dRandGetSeed() == 7


# ------------------------------------------------------------------ §1.2 world and space


def test_damping_thresholds_are_zero_so_damping_always_acts(make: Make) -> None:
    # §1.2: dWorldSetLinearDampingThreshold(0) and dWorldSetAngularDampingThreshold(0)
    sim = make(_box())
    assert probe().dWorldGetLinearDampingThreshold(sim._world) == 0.0
    assert probe().dWorldGetAngularDampingThreshold(sim._world) == 0.0


def test_top_space_is_a_simple_space(make: Make) -> None:
    # §1.2: one top-level dSimpleSpaceCreate(NULL), not a hash space (ODE: dSimpleSpaceClass = 10)
    sim = make(_box() + FLOOR)
    assert probe().dSpaceGetClass(sim._space) == 10


def test_contact_surface_layer_and_max_correcting_velocity_keep_odes_defaults(make: Make) -> None:
    # §1.2: never set by Webots => ODE defaults: surface layer 0, max correcting velocity infinity
    sim = make(_box())
    assert probe().dWorldGetContactSurfaceLayer(sim._world) == 0.0
    assert probe().dWorldGetContactMaxCorrectingVel(sim._world) == math.inf


# ------------------------------------------------------------------ §1.3 auto-disable


def test_world_auto_disable_is_time_based_and_its_flag_is_not_set(make: Make) -> None:
    # §1.3: dWorldSetAutoDisableTime(physicsDisableTime), dWorldSetAutoDisableSteps(0), world flag not set
    sim = make(_box(), "physicsDisableTime 2.5")
    lib = probe()
    assert lib.dWorldGetAutoDisableTime(sim._world) == 2.5
    assert lib.dWorldGetAutoDisableSteps(sim._world) == 0
    assert lib.dWorldGetAutoDisableFlag(sim._world) == 0


def test_each_body_auto_disables_with_the_world_info_thresholds_and_time(make: Make) -> None:
    # §1.3: per body, physicsDisableTime > 0 -> flag on, thresholds and time from WorldInfo (steps 0: time only)
    sim = make(_box(), "physicsDisableTime 0.7 physicsDisableLinearThreshold 0.03 "
                       "physicsDisableAngularThreshold 0.04")
    lib, b = probe(), sim.bodies[0].ptr
    assert lib.dBodyGetAutoDisableFlag(b) == 1
    assert lib.dBodyGetAutoDisableLinearThreshold(b) == 0.03
    assert lib.dBodyGetAutoDisableAngularThreshold(b) == 0.04
    assert lib.dBodyGetAutoDisableTime(b) == 0.7
    assert lib.dBodyGetAutoDisableSteps(b) == 0


def test_auto_disable_defaults_are_one_second_and_0_01(make: Make) -> None:
    # §1.1 table: physicsDisableTime 1, physicsDisableLinearThreshold 0.01, physicsDisableAngularThreshold 0.01
    sim = make(_box())
    lib, b = probe(), sim.bodies[0].ptr
    assert (lib.dBodyGetAutoDisableFlag(b), lib.dBodyGetAutoDisableTime(b)) == (1, 1.0)
    assert lib.dBodyGetAutoDisableLinearThreshold(b) == lib.dBodyGetAutoDisableAngularThreshold(b) == 0.01


def test_physics_disable_time_zero_turns_body_auto_disable_off(make: Make) -> None:
    # §1.1 table: "0 disables the feature"; §1.3: "else flag off"
    sim = make(_box(), "physicsDisableTime 0")
    assert probe().dBodyGetAutoDisableFlag(sim.bodies[0].ptr) == 0


def test_contact_joints_of_a_sleeping_body_persist(make: Make) -> None:
    # §1.3: contact joint groups of disabled bodies are not emptied; §2.3 rule 9: no new joints for a
    # disabled body against static geoms; together: the sleeping box keeps the joints it had when it fell asleep
    sim = make(_box(0.0495) + FLOOR, "basicTimeStep 8 physicsDisableTime 0.2")
    body = sim.bodies[0]
    for _ in range(200):
        sim.step()
        if not sim._lib.dBodyIsEnabled(body.ptr):
            break
    assert not sim._lib.dBodyIsEnabled(body.ptr)
    kept = contact_joints(body.ptr)
    assert kept
    sim.step(5)
    assert contact_joints(body.ptr) == kept and not sim._lib.dBodyIsEnabled(body.ptr)


# ------------------------------------------------------------------ §1.4 damping


def _per_step(per_second: float, dt: float) -> float:
    return 1.0 - (1.0 - per_second) ** dt  # §1.4: d_step = 1 − (1 − d_per_second)^(basicTimeStep·0.001)


def test_world_damping_is_zero_without_default_damping(make: Make) -> None:
    # §1.4: dWorldSetDamping(0, 0) when defaultDamping is NULL
    sim = make(_box())
    assert probe().dWorldGetLinearDamping(sim._world) == 0.0
    assert probe().dWorldGetAngularDamping(sim._world) == 0.0


def test_default_damping_is_converted_to_a_per_step_fraction(make: Make) -> None:
    sim = make(_box(), "basicTimeStep 16 defaultDamping Damping { linear 0.5 angular 0.3 }")
    assert probe().dWorldGetLinearDamping(sim._world) == pytest.approx(_per_step(0.5, 0.016), rel=1e-12)
    assert probe().dWorldGetAngularDamping(sim._world) == pytest.approx(_per_step(0.3, 0.016), rel=1e-12)


def test_damping_node_defaults_are_0_2_per_second(make: Make) -> None:
    # §1.4: Damping node defaults linear 0.2, angular 0.2
    sim = make(_box(), "defaultDamping Damping { }")
    assert probe().dWorldGetLinearDamping(sim._world) == pytest.approx(_per_step(0.2, 0.032), rel=1e-12)
    assert probe().dWorldGetAngularDamping(sim._world) == pytest.approx(_per_step(0.2, 0.032), rel=1e-12)


def test_body_damping_is_the_volume_weighted_average_of_its_merged_solids(make: Make) -> None:
    # §1.4: averaged over the merged Solids, weighted by boundingObject volume, a Solid without Damping counting
    # its volume with 0: a 0.001 m³ box with linear 0.6 merged with a 0.002 m³ box without Damping -> 0.2
    scene = ("Solid { translation 0 0 1 boundingObject Box { size 0.1 0.1 0.1 } "
             "physics Physics { damping Damping { linear 0.6 angular 0.9 } } children [ "
             "Solid { translation 0.5 0 0 boundingObject Box { size 0.1 0.1 0.2 } physics Physics { } } ] }")
    sim = make(scene, "basicTimeStep 10")
    (body,) = sim.bodies
    assert probe().dBodyGetLinearDamping(body.ptr) == pytest.approx(_per_step(0.2, 0.01), rel=1e-9)
    assert probe().dBodyGetAngularDamping(body.ptr) == pytest.approx(_per_step(0.3, 0.01), rel=1e-9)


def test_body_damping_component_not_positive_is_zero_not_the_worlds(make: Make) -> None:
    # §1.4: dBodySetDamping(l_step, a_step) "with the other component 0 if not positive"
    sim = make(_box(phys="damping Damping { linear 0.4 angular 0 }"),
               "defaultDamping Damping { linear 0.5 angular 0.5 }")
    b = sim.bodies[0].ptr
    assert probe().dBodyGetLinearDamping(b) == pytest.approx(_per_step(0.4, 0.032), rel=1e-12)
    assert probe().dBodyGetAngularDamping(b) == 0.0


def test_explicit_zero_body_damping_falls_back_to_world_damping(make: Make) -> None:
    # §1.4: "if both are 0 (including an explicit Damping {linear 0 angular 0}) ... = world damping"
    sim = make(_box(phys="damping Damping { linear 0 angular 0 }"),
               "defaultDamping Damping { linear 0.5 angular 0.25 }")
    b = sim.bodies[0].ptr
    assert probe().dBodyGetLinearDamping(b) == pytest.approx(_per_step(0.5, 0.032), rel=1e-12)
    assert probe().dBodyGetAngularDamping(b) == pytest.approx(_per_step(0.25, 0.032), rel=1e-12)


def test_every_body_has_a_max_angular_speed_of_10000(make: Make) -> None:
    # §1.4: dBodySetMaxAngularSpeed(body, 10000) rad/s
    sim = make(_box() + _box(2.0).replace("DEF BOX ", ""))
    assert [probe().dBodyGetMaxAngularSpeed(b.ptr) for b in sim.bodies] == [10000.0, 10000.0]


# ------------------------------------------------------------------ §1.5 / §1.6 stepping


def test_one_world_step_per_basic_step_without_substeps(make: Make) -> None:
    # §1.5: one dWorldStep of basicTimeStep/1000 s; ODE's semi-implicit Euler from rest: v_n = -g·n·h,
    # z_n = z0 - g·h²·n(n+1)/2 (sub-stepping would give a different z)
    sim = make(_box(10.0), "basicTimeStep 20 physicsDisableTime 0")
    sim.step(5)
    assert sim.bodies[0].lvel[2] == pytest.approx(-9.81 * 5 * 0.02, rel=1e-12)
    assert sim.bodies[0].pos[2] == pytest.approx(10.0 - 9.81 * 0.02**2 * 15, rel=1e-12)


def test_contacts_found_at_load_are_used_by_the_first_step(make: Make) -> None:
    # §1.6: "At world load: ... one collision pass whose contact joints are used by the first dWorldStep":
    # a box resting 0.5 mm into the floor is held by the first step (without contacts: vz = -g·dt = -0.314)
    sim = make(_box(0.0495) + FLOOR, "physicsDisableTime 0")
    assert contact_joints(sim.bodies[0].ptr)
    sim.step()
    assert sim.bodies[0].lvel[2] > -0.01


def test_a_body_moved_between_steps_steps_once_with_the_contacts_of_its_old_pose(make: Make) -> None:
    # §1.6 consequence: "when bodies are moved between steps (teleport by supervisor): Webots then steps once
    # with contacts computed at the old pose". A box resting on the floor, moved 1 m up, is held for one step
    # (vz ≈ 0 instead of -g·dt), then falls freely: its speed then drops by g·dt per step.
    sim = make(_box(0.0495) + FLOOR + " Robot { supervisor TRUE }", "basicTimeStep 8 physicsDisableTime 0")
    sup = Supervisor(simulation=sim)
    sup.step(8 * 20)
    box = sup.getFromDef("BOX")
    box.getField("translation").setSFVec3f([0.0, 0.0, 1.0])
    sup.step(8)
    body = sim.bodies[0]
    assert body.pos[2] > 0.9
    held = body.lvel[2]
    assert held > -0.01
    sup.step(8)
    assert body.lvel[2] == pytest.approx(held - 9.81 * 0.008, abs=1e-9)


# ------------------------------------------------------------------ Appendix A


def test_ode_is_built_in_double_precision() -> None:
    # Appendix A.1: Webots uses double precision
    assert ode.load().dCheckConfiguration(b"ODE_double_precision") == 1


def test_bodies_keep_odes_implicit_gyroscopic_term(make: Make) -> None:
    # Appendix A.5: gyroscopic forces integrated implicitly by default; Webots does not change it
    sim = make(_box())
    assert probe().dBodyGetGyroscopicMode(sim.bodies[0].ptr) != 0  # (ODE returns its flag bit, 256)
