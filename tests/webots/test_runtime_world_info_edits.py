"""A supervisor's write of a WorldInfo field the physics reads acts on ODE from the next step, as in Webots (every
field write reaches ODE at the next step): ``gravity``, the sleep fields ``physicsDisableTime``,
``physicsDisableLinearThreshold`` and ``physicsDisableAngularThreshold``, and ``basicTimeStep``; a
``simulationReset`` puts the load values back into ODE. Before, these four were read once at load.

S = webots-on-ode.md (shared reference). Expected values by hand:
* ODE integrates v ← v + g·h per step (semi-implicit Euler, §1.5: one dWorldStep of h = basicTimeStep/1000), so a
  free ball gains g·n·h of downward speed over n steps.
* §1.3: a body below both thresholds for physicsDisableTime seconds is disabled (asleep).
* §1.4: a Damping fraction d lost per second becomes c = 1 - (1 - d)^h per step, so over a time T the speed kept
  is (1 - d)^T whatever the step length, once c is converted with the step's h.
* §4.5: a slider spring K (damping 0) is the stop row ERP = hK/(hK + B), CFM = 1/(hK + B), i.e. the implicit
  spring m·v₁ = m·v₀ - h·K·(x₀ + h·v₁): from rest at x₀, v₁ = -h·K·x₀/(m + h²·K).
Each test has its control (the same world without the edit, or the value before it).
"""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text, ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.kicks import supervisor_in
from tests.support.ode_probe import probe
from tests.support.quiet_worlds import quiet_supervisor

TS = 8
H = TS / 1000
BALL = ("DEF BALL Solid { translation 0 0 5 boundingObject Sphere { radius 0.1 } "
        "physics Physics { density -1 mass 1 } }")
RESTING = ("DEF BALL Solid { translation 0 0 0.1 boundingObject Sphere { radius 0.1 } "
           "physics Physics { density -1 mass 1 } } Solid { boundingObject Plane { } }")


def _info(sup: Supervisor) -> object:
    info = sup.getRoot().getField("children").getMFNode(0)
    assert info.getTypeName() == "WorldInfo"
    return info


def _fall(sup: Supervisor, steps: int, ms: int = TS) -> float:
    """The vertical speed the ball gains over ``steps`` controller steps of ``ms``."""
    ball = sup.getFromDef("BALL")
    before = ball.getVelocity()[2]
    for _ in range(steps):
        assert sup.step(ms) == 0
    return ball.getVelocity()[2] - before


def _asleep(sup: Supervisor) -> bool:
    sim = sup.simulation
    return not sim._lib.dBodyIsEnabled(sim.solid_for(sup.getFromDef("BALL").scene_node).body.ptr)


def _world_gravity(sup: Supervisor) -> tuple[float, ...]:
    g = (probe().dWorldGetGravity.argtypes[1]._type_ * 3)()
    probe().dWorldGetGravity(sup.simulation._world, g)
    return tuple(g)


def _unstepped(scene: str, gravity: float = 0.0, info: str = "") -> Supervisor:
    """A supervisor in ``scene`` before its first step."""
    world = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity {gravity} {info} }}\n{scene}\n" \
            "Robot { supervisor TRUE }\n"
    return Supervisor(simulation=Simulation(load_world_text(world)))


# ---------------------------------------------------------------------------------------------- gravity


def test_a_gravity_edit_changes_the_fall_from_the_next_step() -> None:
    sup = supervisor_in(BALL, TS, gravity=9.81)
    assert _fall(sup, 10) == pytest.approx(-9.81 * 10 * H, rel=1e-9)  # control: 9.81 m/s² before the edit
    _info(sup).getField("gravity").setSFFloat(2.0)
    assert _world_gravity(sup) == (0.0, 0.0, -2.0)  # ENU: down is -z (S §1.1)
    assert _fall(sup, 10) == pytest.approx(-2.0 * 10 * H, rel=1e-9)  # (before: -0.7848 again)
    _info(sup).getField("gravity").setSFFloat(0.0)
    assert _fall(sup, 10) == 0.0


def test_a_gravity_edit_wakes_the_bodies_asleep() -> None:
    sup = supervisor_in(RESTING, TS, gravity=9.81)
    for _ in range(250):  # 2 s at rest on the floor, physicsDisableTime 1 s (S §1.3)
        sup.step(TS)
    assert _asleep(sup)  # the control: asleep before the edit
    _info(sup).getField("gravity").setSFFloat(5.0)
    assert sup.step(TS) == 0
    assert not _asleep(sup)


def test_buoyancy_pushes_with_the_edited_gravity() -> None:
    # A box of density 500 under water (a Fluid's density 1000): buoyancy 1000·V·g against a weight of 500·V·g,
    # so it rises at (1000/500 - 1)·g = g, gaining g·h per step (webots-devices Fluid: Archimedes, ρ·V·g)
    sup = supervisor_in('Fluid { translation 0 0 0.5 boundingObject Box { size 4 4 1 } } DEF BALL Solid { '
                        'translation 0 0 0.5 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density 500 } '
                        'immersionProperties [ ImmersionProperties { fluidName "fluid" } ] }', TS, gravity=9.81)
    assert _fall(sup, 1) == pytest.approx(9.81 * H, rel=1e-9)  # the control
    _info(sup).getField("gravity").setSFFloat(2.0)
    assert _fall(sup, 1) == pytest.approx(2.0 * H, rel=1e-9)  # (the load's buoyancy: (2·9.81 - 2)·h)


# ---------------------------------------------------------------------------------------------- sleep


def _time_asleep(sup: Supervisor) -> float:
    for _ in range(500):
        sup.step(TS)
        if _asleep(sup):
            return sup.getTime()
    raise AssertionError("the ball never went to sleep")


def test_a_shorter_physics_disable_time_puts_a_body_to_sleep_sooner_once_it_rests() -> None:
    # The ball falls 0.2 m, bounces and comes to rest: ODE counts a body's idle time from its last step above
    # the thresholds, and disables it once the count passes physicsDisableTime (S §1.3). Both worlds move alike
    # until then, so the edited one (0.2 s) sleeps 1 - 0.2 = 0.8 s before the control (the load's 1 s).
    drop = RESTING.replace("translation 0 0 0.1", "translation 0 0 0.3")
    control = supervisor_in(drop, TS, gravity=9.81)
    edited = supervisor_in(drop, TS, gravity=9.81)
    _info(edited).getField("physicsDisableTime").setSFFloat(0.2)
    body = edited.simulation.solid_for(edited.getFromDef("BALL").scene_node).body
    assert probe().dBodyGetAutoDisableTime(body.ptr) == 0.2
    assert probe().dWorldGetAutoDisableTime(edited.simulation._world) == 0.2
    assert _time_asleep(control) - _time_asleep(edited) == pytest.approx(0.8, abs=H)  # (before: 0, both at 1 s)


def test_a_physics_disable_time_of_zero_wakes_the_bodies_and_keeps_them_awake() -> None:
    sup = supervisor_in(RESTING, TS, gravity=9.81)
    for _ in range(250):
        sup.step(TS)
    assert _asleep(sup)  # the control
    _info(sup).getField("physicsDisableTime").setSFFloat(0.0)
    for _ in range(250):
        assert sup.step(TS) == 0
        assert not _asleep(sup)
    body = sup.simulation.solid_for(sup.getFromDef("BALL").scene_node).body
    assert probe().dBodyGetAutoDisableFlag(body.ptr) == 0  # S §1.3: physicsDisableTime 0 turns the feature off


def test_a_physics_disable_time_set_on_a_world_loaded_without_sleeping_puts_a_resting_body_to_sleep() -> None:
    sup = _unstepped(RESTING, gravity=9.81, info="physicsDisableTime 0")
    for _ in range(250):  # 2 s at rest
        sup.step(TS)
    assert not _asleep(sup)  # the control: no sleeping in this world (S §1.3)
    _info(sup).getField("physicsDisableTime").setSFFloat(1.0)
    for _ in range(140):  # more than the 1 s of rest it now takes
        sup.step(TS)
    assert _asleep(sup)  # (before: awake, the body kept the load's flag off)


def test_a_higher_linear_threshold_puts_a_slowly_sliding_body_to_sleep() -> None:
    # A box slides on a frictionless floor (ODE never puts a body without any joint, contacts included, to sleep)
    sup = _unstepped("DEF BALL Solid { translation 0 0 0.1 boundingObject Box { size 0.2 0.2 0.2 } "
                     "physics Physics { } } Solid { boundingObject Plane { } }",
                     gravity=9.81, info="contactProperties [ ContactProperties { coulombFriction 0 } ]")
    ball = sup.getFromDef("BALL")
    ball.setVelocity([0.05, 0.0, 0.0, 0.0, 0.0, 0.0])  # above the default 0.01 m/s threshold (S §1.1)
    for _ in range(190):  # 1.5 s
        sup.step(TS)
    assert not _asleep(sup) and ball.getVelocity()[0] == pytest.approx(0.05)  # the control
    _info(sup).getField("physicsDisableLinearThreshold").setSFFloat(0.1)
    for _ in range(190):
        sup.step(TS)
    assert _asleep(sup)  # (before: awake, the body kept the load's 0.01 m/s)
    x = ball.getPosition()[0]
    sup.step(TS)
    assert ball.getPosition()[0] == x  # asleep: ODE no longer moves it
    body = sup.simulation.solid_for(ball.scene_node).body
    assert probe().dBodyGetAutoDisableLinearThreshold(body.ptr) == 0.1


def test_an_angular_threshold_edit_reaches_every_body() -> None:
    sup = supervisor_in(BALL, TS)
    _info(sup).getField("physicsDisableAngularThreshold").setSFFloat(0.3)
    body = sup.simulation.solid_for(sup.getFromDef("BALL").scene_node).body
    assert probe().dBodyGetAutoDisableAngularThreshold(body.ptr) == 0.3


# ---------------------------------------------------------------------------------------------- basicTimeStep


def test_a_basic_time_step_edit_makes_the_following_steps_that_long() -> None:
    sup = supervisor_in(BALL, TS, gravity=9.81)  # one step of 8 ms done
    assert sup.getTime() == pytest.approx(0.008)
    assert _fall(sup, 1, 8) == pytest.approx(-9.81 * 0.008, rel=1e-9)  # the control: one step of 8 ms
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    assert sup.getBasicTimeStep() == 16.0  # (before: 8)
    assert _fall(sup, 1, 16) == pytest.approx(-9.81 * 0.016, rel=1e-9)  # one dWorldStep of 16 ms
    assert sup.getTime() == pytest.approx(0.016 + 0.016)  # the time goes on from 0.016 s (before: 0.024)
    for _ in range(3):
        sup.step(16)
    assert sup.getTime() == pytest.approx(0.032 + 3 * 0.016)


def test_a_controller_step_shorter_than_the_new_basic_time_step_runs_one_basic_step() -> None:
    sup = supervisor_in(BALL, TS, gravity=9.81)
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    assert sup.step(8) == 0  # S §1.5: the simulator advances in basic steps only
    assert sup.getTime() == pytest.approx(0.008 + 0.016)


def test_a_basic_time_step_of_zero_is_reset_to_32_with_a_warning() -> None:
    sup = supervisor_in(BALL, TS)
    with pytest.warns(UserWarning, match=r"WorldInfo.basicTimeStep 0 must be positive; reset to 32"):
        _info(sup).getField("basicTimeStep").setSFFloat(0.0)
    assert _info(sup).getField("basicTimeStep").getSFFloat() == 32.0  # S §1.1: reset to 32 if ≤ 0
    assert sup.getBasicTimeStep() == 32.0
    sup.step(32)
    assert sup.getTime() == pytest.approx(0.008 + 0.032)


def test_the_damping_is_converted_again_for_the_new_step_length() -> None:
    sup = supervisor_in("DEF BALL Solid { boundingObject Sphere { radius 0.1 } "
                        "physics Physics { damping Damping { linear 0.5 angular 0 } } }", TS)
    ball = sup.getFromDef("BALL")

    def kept(steps: int, ms: int) -> float:
        ball.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        for _ in range(steps):
            sup.step(ms)
        return ball.getVelocity()[0]

    assert kept(12, 8) == pytest.approx(0.5 ** 0.096, rel=1e-9)  # the control: 0.096 s in steps of 8 ms
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    start = sup.getTime()
    assert kept(6, 16) == pytest.approx(0.5 ** 0.096, rel=1e-9)  # (c of 8 ms at each step of 16: 0.5^0.048)
    assert sup.getTime() - start == pytest.approx(0.096) and sup.simulation.step_count == 1 + 12 + 6


SLIDER = """
Solid {
  children [
    SliderJoint {
      jointParameters JointParameters { position 0.1 axis 1 0 0 springConstant 100 }
      endPoint DEF BALL Solid {
        translation 0.1 0 0
        boundingObject Sphere { radius 0.05 }
        physics Physics { density -1 mass 1 }
      }
    }
  ]
}
"""


def test_a_slider_spring_is_converted_again_for_the_new_step_length() -> None:
    x0, k = 0.1, 100.0  # the spring pulls the endPoint back to position 0 (S §4.5)
    control = _unstepped(SLIDER)
    control.step(8)
    h = 0.008
    assert control.getFromDef("BALL").getVelocity()[0] == pytest.approx(-h * k * x0 / (1 + h * h * k), rel=1e-6)
    sup = _unstepped(SLIDER)
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    sup.step(16)
    h = 0.016
    # -0.15601 m/s; the spring rows of 8 ms (ERP 1, CFM 1.25) stepped over 16 ms gave -0.07899 (an implied K of 50)
    assert sup.getFromDef("BALL").getVelocity()[0] == pytest.approx(-h * k * x0 / (1 + h * h * k), rel=1e-6)


HINGE2 = """
Solid {
  boundingObject Sphere { radius 0.1 }
  physics Physics { }
  children [
    Hinge2Joint {
      jointParameters HingeJointParameters { axis 0 0 1 suspensionSpringConstant 100 suspensionDampingConstant 2 }
      jointParameters2 JointParameters { axis 0 1 0 }
      endPoint Solid { translation 0.3 0 0 boundingObject Sphere { radius 0.05 } physics Physics { } }
    }
  ]
}
"""


def test_a_hinge2_suspension_is_converted_again_for_the_new_step_length() -> None:
    sup = _unstepped(HINGE2)
    joint = next(j for j in sup.simulation.joints if j.kind == "hinge2")

    def suspension() -> tuple[float, float]:
        return (probe().dJointGetHinge2Param(joint.ptr, ode.dParamSuspensionERP),
                probe().dJointGetHinge2Param(joint.ptr, ode.dParamSuspensionCFM))

    # S §4.4/§4.5: ERP = hK/(hK + B), CFM = 1/(hK + B) with K = 100, B = 2
    assert suspension() == pytest.approx((0.8 / 2.8, 1 / 2.8), rel=1e-12)  # the control: h = 8 ms
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    assert suspension() == pytest.approx((1.6 / 3.6, 1 / 3.6), rel=1e-12)


# ---------------------------------------------------------------------------------------------- reset


def test_simulation_reset_puts_the_load_values_back_into_ode() -> None:
    sup = supervisor_in(RESTING, TS, gravity=9.81)
    info = _info(sup)
    info.getField("gravity").setSFFloat(2.0)
    info.getField("physicsDisableTime").setSFFloat(0.0)
    info.getField("physicsDisableLinearThreshold").setSFFloat(0.5)
    info.getField("basicTimeStep").setSFFloat(16.0)
    sup.step(16)
    assert _world_gravity(sup) == (0.0, 0.0, -2.0) and sup.getTime() == pytest.approx(0.024)  # the edits acted
    sup.simulationReset()
    sup.step(16)  # the reset happens at the end of this step (S §6)
    assert sup.getBasicTimeStep() == 8.0
    assert _world_gravity(sup) == (0.0, 0.0, -9.81)
    body = sup.simulation.solid_for(sup.getFromDef("BALL").scene_node).body
    assert probe().dBodyGetAutoDisableFlag(body.ptr) == 1
    assert probe().dBodyGetAutoDisableTime(body.ptr) == 1.0
    assert probe().dBodyGetAutoDisableLinearThreshold(body.ptr) == 0.01
    assert sup.getTime() == 0.0
    sup.step(8)
    assert sup.getTime() == pytest.approx(0.008)
    for _ in range(250):  # asleep again after the load's 1 s at rest
        sup.step(TS)
    assert _asleep(sup)


def test_simulation_reset_restores_the_fall_and_the_step_length() -> None:
    sup = supervisor_in(BALL, TS, gravity=9.81)
    _info(sup).getField("gravity").setSFFloat(2.0)
    _info(sup).getField("basicTimeStep").setSFFloat(16.0)
    assert _fall(sup, 1, 16) == pytest.approx(-2.0 * 0.016, rel=1e-9)  # the edits acted
    sup.simulationReset()
    sup.step(16)
    assert _fall(sup, 10) == pytest.approx(-9.81 * 10 * H, rel=1e-9)  # ten steps of 8 ms under 9.81 m/s² again


def _belt_carries(sup: Supervisor, steps: int) -> float:
    """How far along x the belt carries the box in ``steps`` steps, the box pressed onto it by 20 N."""
    box = sup.getFromDef("BOX")
    start = box.getPosition()[0]
    for _ in range(steps):
        box.addForce([0.0, 0.0, -20.0], False)
        sup.step(TS)
    return box.getPosition()[0] - start


def test_a_gravity_edit_reaches_the_belt_rule_of_a_track() -> None:
    # D §7.2: the belt's surface speed is v·sign with sign = ±g_z, g the unit gravity of the world, so a gravity
    # written upward (a negative WorldInfo.gravity: S §1.1, along the down axis) reverses the belt's drive. A box
    # pressed by 20 N onto a belt running at v = 0.2 m/s (the gravity, ±0.01 m/s², barely weighs: the 50 kg Track
    # stays on the ground under the 20 N) is carried 0.2 m/s · 0.496 s = 0.0992 m along x, less 0.001 m while it
    # catches up (μ·N/m = 20 m/s²: 0.01 s at half the speed): 0.098 m. After the edit the belt runs the other way:
    # the box turns from +0.2 to -0.2 m/s in 0.02 s, losing 0.2·0.02 = 0.004 m: 0.0992 - 0.004 = 0.095 m back
    sup = quiet_supervisor(f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0.01 }}\n"
                           "Robot { supervisor TRUE children [ Track { translation 0 0 0.05 boundingObject Box { size "
                           "2 0.4 0.1 } physics Physics { mass 50 } device [ LinearMotor { maxVelocity 1 } ] } ] }\n"
                           "Solid { translation 0 0 -0.5 boundingObject Box { size 10 10 1 } }\n"
                           "DEF BOX Solid { translation 0 0 0.15 boundingObject Box { size 0.1 0.1 0.1 } "
                           "physics Physics { density -1 mass 1 } }\n")
    try:
        motor = sup.getDevice("linear motor")
        motor.setPosition(float("inf"))
        motor.setVelocity(0.2)
        before = _belt_carries(sup, 62)  # 0.496 s
        assert abs(before) == pytest.approx(0.098, abs=3e-3)  # the control, before the edit
        _info(sup).getField("gravity").setSFFloat(-0.01)
        after = _belt_carries(sup, 62)
        assert after == pytest.approx(-math.copysign(0.095, before), abs=3e-3)  # (before the mend: +0.099)
    finally:
        sup.simulation.close()
