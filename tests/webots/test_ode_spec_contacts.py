"""Section 2 of the Webots-on-ODE specification (/work/shared/reference/webots-on-ode.md, restated in
docs/reference/webots-on-ode.md): ContactProperties defaults, the surface parameters written into each dContact,
and the near-callback filtering rules, one test per fact. The contact joints are read from ODE itself (the
joints attached to a body after the collision pass, tests/support/ode_probe.py); the surface a pair gets is the
Simulation's pre-filled dContact template for that pair of materials."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import pytest

from dualtwin.webots import load_world_text, ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.ode_probe import contact_joints, simulations

Make = Callable[..., Simulation]
CUBE = "boundingObject Box {{ size {s} {s} {s} }} physics Physics {{ }}"
FLOOR = 'Solid { name "floor" boundingObject Plane { } }'
BASE_MODE = ode.dContactApprox1 | ode.dContactSoftCFM | ode.dContactSoftERP


@pytest.fixture
def make() -> Iterator[Make]:
    """``make(scene, info="")``: a Simulation of ``scene`` (world nodes as text) under ``WorldInfo { info }``."""
    with simulations() as build:
        yield build


def _cube(s: float = 0.1) -> str:
    return CUBE.format(s=s)


def _body(sim: Simulation, name: str):  # type: ignore[no-untyped-def]
    return next(s.body for s in sim.solids if s.name == name)


def _touching(sim: Simulation, a: str, b: str | None) -> int:
    """How many contact joints the collision pass made between Solid ``a``'s body and ``b``'s (None: static)."""
    pa = _body(sim, a).ptr
    pb = None if b is None else _body(sim, b).ptr
    return sum(1 for j in contact_joints(pa) if set(j) == {pa, pb})


def _surface(cp: str, m1: str = "a", m2: str = "b"):  # type: ignore[no-untyped-def]
    sim = Simulation(load_world_text(f"#VRML_SIM R2023b utf8\nWorldInfo {{ contactProperties [ "
                                     f"ContactProperties {{ material1 \"a\" material2 \"b\" {cp} }} ] }}\n", "t.wbt"))
    try:
        s = sim._surface_for(m1, m2)
        return s.template, s.max_joints
    finally:
        sim.close()


# ------------------------------------------------------------------ §2.1 ContactProperties defaults


def test_contact_properties_defaults_equal_the_hard_coded_defaults() -> None:
    # §2.1 table: coulombFriction [1], rollingFriction 0 0 0, bounce 0.5, bounceVelocity 0.01,
    # forceDependentSlip [0], softERP 0.2, softCFM 0.001, maxContactJoints 10; "If none matches, the hard-coded
    # defaults are used and they equal the node defaults"
    for s, max_joints in (_surface(""), _surface("", "x", "y")):
        assert (s.mu, s.bounce, s.bounce_vel, s.soft_erp, s.soft_cfm) == (1.0, 0.5, 0.01, 0.2, 0.001)
        assert (s.rho, s.rho2, s.rhoN) == (0.0, 0.0, 0.0)
        assert s.mode == BASE_MODE | ode.dContactBounce  # no slip, no rolling
        assert max_joints == 10


def test_world_info_erp_and_cfm_are_not_used_for_contacts(make: Make) -> None:
    # §1.1 / §2.1: "WorldInfo.ERP/CFM are not used for contacts"
    sim = make("", "ERP 0.9 CFM 0.1")
    s = sim._surface_for("default", "default").template
    assert (s.soft_erp, s.soft_cfm) == (0.2, 0.001)


# ------------------------------------------------------------------ §2.2 surface parameters


def test_bounce_zero_leaves_out_the_bounce_flag() -> None:
    # §2.2: dContactBounce "when bounce ≠ 0"
    s, _ = _surface("bounce 0")
    assert s.mode == BASE_MODE


def test_coulomb_friction_minus_one_is_infinite() -> None:
    # §2.1 table: coulombFriction "−1 = infinity (dInfinity)"
    s, _ = _surface("coulombFriction [ -1 ]")
    assert s.mu == math.inf


def test_symmetric_force_dependent_slip_sets_both_slip_rows() -> None:
    # §2.2: "if slip ≠ 0 then dContactSlip1 | dContactSlip2 with slip1 = slip2 = value"
    s, _ = _surface("forceDependentSlip [ 0.25 ] bounce 0")
    assert s.mode == BASE_MODE | ode.dContactSlip1 | ode.dContactSlip2
    assert (s.slip1, s.slip2) == (0.25, 0.25)


def test_rolling_friction_rho_alone_sets_rolling_without_axis_dependence() -> None:
    # §2.2: "if any rho > 0 -> dContactRolling; if rho2 or rhoN > 0 also dContactAxisDep"
    s, _ = _surface("rollingFriction 0.3 0 0 bounce 0")
    assert s.mode == BASE_MODE | ode.dContactRolling
    assert (s.rho, s.rho2, s.rhoN) == (0.3, 0.0, 0.0)


@pytest.mark.parametrize("rolling", ["0 0.2 0", "0 0 0.2"])
def test_rolling_friction_rho2_or_rhon_adds_axis_dependence(rolling: str) -> None:
    s, _ = _surface(f"rollingFriction {rolling} bounce 0")
    assert s.mode == BASE_MODE | ode.dContactRolling | ode.dContactAxisDep


def test_rolling_friction_minus_one_is_infinite() -> None:
    # §2.1 table: rollingFriction "−1 = infinity"; §2.2 "rho, rho2, rhoN set (−1 → infinity)"
    s, _ = _surface("rollingFriction 0.1 -1 -1")
    assert (s.rho, s.rho2, s.rhoN) == (0.1, math.inf, math.inf)


def test_bounce_values_are_copied_from_the_matched_properties() -> None:
    # §2.2: bounce, bounce_vel, soft_cfm, soft_erp copied from the matched properties
    s, max_joints = _surface("bounce 0.3 bounceVelocity 0.2 softERP 0.6 softCFM 0.05 maxContactJoints 3", "b", "a")
    assert (s.bounce, s.bounce_vel, s.soft_erp, s.soft_cfm, max_joints) == (0.3, 0.2, 0.6, 0.05, 3)


# ------------------------------------------------------------------ §2.3 near callback


def test_a_box_on_a_plane_gets_four_contact_joints_attached_to_it_and_the_static_world(make: Make) -> None:
    # §2.3 rule 10: a joint per point, attached to (b1, b2) with NULL for the static floor; ODE's box-plane
    # collider gives the 4 bottom corners (Appendix A.4: "box–plane (up to 4 points)")
    sim = make(f'Solid {{ name "box" translation 0 0 0.049 {_cube()} }}' + FLOOR)
    assert _touching(sim, "box", None) == 4


def test_max_contact_joints_keeps_that_many_points(make: Make) -> None:
    # §2.3 rule 8: "If more than maxContactJoints points, keep the deepest maxContactJoints"
    info = 'contactProperties [ ContactProperties { material1 "m" maxContactJoints 2 } ]'
    sim = make(f'Solid {{ name "box" translation 0 0 0.049 contactMaterial "m" {_cube()} }}' + FLOOR, info)
    assert _touching(sim, "box", None) == 2


def test_max_contact_joints_keeps_the_deepest_points(make: Make) -> None:
    # §2.3 rule 8: a box tilted by +0.1 rad about y has its +x bottom edge lower: all 4 bottom corners are in the
    # floor (the -x ones 1 mm, the +x ones 11 mm). Keeping the 2 deepest keeps the +x edge's, so the first step
    # pushes the box up there and turns it about -y (r × F at x = +0.05: ωy < 0; the -x edge would give ωy > 0)
    z = 0.05 * math.cos(0.1) - 0.05 * math.sin(0.1) - 0.001
    box = f'Solid {{ name "box" translation 0 0 {z} rotation 0 1 0 0.1 contactMaterial "m" {_cube()} }}' + FLOOR
    info = 'contactProperties [ ContactProperties {{ material1 "m" {} bounce 0 }} ] gravity 0'
    assert _touching(make(box, info.format("")), "box", None) == 4  # control: 4 points
    sim = make(box, info.format("maxContactJoints 2"))
    assert _touching(sim, "box", None) == 2
    sim.step()
    body = _body(sim, "box")
    assert body.lvel[2] > 0 and body.avel[1] < 0


def _two_arms(self_collision: bool) -> str:
    """A robot body with two hinged boxes "a" and "b" that overlap each other (hinges at different anchors)."""
    flag = "TRUE" if self_collision else "FALSE"
    anchor_b = "0.15 0 0"
    return f"""Robot {{ translation 0 0 5 selfCollision {flag} boundingObject Box {{ size 0.02 0.02 0.02 }}
  physics Physics {{ }} children [
    HingeJoint {{ jointParameters HingeJointParameters {{ anchor 0.1 0 0 axis 0 1 0 }}
      endPoint Solid {{ name "a" translation 0.1 0 0 {_cube()} }} }}
    HingeJoint {{ jointParameters HingeJointParameters {{ anchor {anchor_b} axis 0 1 0 }}
      endPoint Solid {{ name "b" translation 0.15 0 0 {_cube()} }} }} ] }}"""


def test_parts_of_one_robot_without_self_collision_do_not_collide(make: Make) -> None:
    # §2.3 rule 4: "Same robot, selfCollision FALSE (default) => no collision"
    sim = make(_two_arms(False), "gravity 0")
    assert _touching(sim, "a", "b") == 0


def test_parts_of_one_robot_with_self_collision_collide(make: Make) -> None:
    # §2.3 rule 4 (control): with selfCollision TRUE the two overlapping endPoints touch
    sim = make(_two_arms(True), "gravity 0")
    assert _touching(sim, "a", "b") > 0


def test_bodies_joined_by_a_joint_do_not_collide(make: Make) -> None:
    # §2.3 rule 6: bodies connected by any non-contact joint are ignored (the endPoint overlaps its parent)
    scene = f"""Solid {{ name "p" translation 0 0 5 {_cube()} children [
      SliderJoint {{ endPoint Solid {{ name "c" translation 0.05 0 0 {_cube()} }} }} ] }}"""
    sim = make(scene, "gravity 0")
    assert _touching(sim, "p", "c") == 0
    assert _touching(sim, "c", "p") == 0


def test_a_body_fixed_to_the_world_ignores_static_geoms_but_not_free_bodies(make: Make) -> None:
    # §3.3 static basis: a physics Solid under a Solid without Physics is fixed to the world by a joint;
    # §2.3 rule 6: such a body "does not collide with any static geom" (it sinks into the floor here), but a free
    # body that overlaps it does collide with it
    scene = (f'Solid {{ children [ Solid {{ name "fixed" translation 0 0 0.04 {_cube()} }} ] }}'
             f'Solid {{ name "free" translation 0.09 0 0.04 {_cube()} }}' + FLOOR)
    sim = make(scene, "gravity 0")
    assert _touching(sim, "fixed", None) == 0
    assert _touching(sim, "free", "fixed") > 0
    assert _touching(sim, "free", None) > 0  # control: the free box touches the floor


def _looped(close: bool) -> str:
    """A static robot; "A" hinged to it high up, "B" ball-jointed to "A" and sunk 1 cm into the floor; with
    ``close``, a second robot HingeJoint whose endPoint is a SolidReference to "B" ties "B" to the world too."""
    loop = ('HingeJoint { jointParameters HingeJointParameters { anchor 0 0 0.04 axis 1 0 0 } '
            'endPoint SolidReference { solidName "B" } }') if close else ""
    return f"""Robot {{ children [
    HingeJoint {{ jointParameters HingeJointParameters {{ anchor 0 0 1 axis 0 1 0 }}
      endPoint Solid {{ name "A" translation 0 0 1 {_cube()} children [
        BallJoint {{ jointParameters BallJointParameters {{ anchor 0 0 -0.96 }}
          endPoint Solid {{ name "B" translation 0 0 -0.96 {_cube()} }} }} ] }} }}
    {loop} ] }}""" + FLOOR


def test_a_body_jointed_to_the_world_by_a_closed_loop_ignores_static_geoms(make: Make) -> None:
    # §2.3 rule 6: "a body attached to the static environment by a joint ... does not collide with any static
    # geom" (ODE's dAreConnectedExcluding(b, NULL) finds any non-contact joint to body 0, Appendix A.8): here the
    # joint tying "B" to the world is a loop joint whose upper Solid (the robot) has no body
    assert _touching(make(_looped(False), "gravity 0"), "B", None) > 0  # control: without the loop B touches
    assert _touching(make(_looped(True), "gravity 0"), "B", None) == 0


def test_a_removed_loop_endpoint_lets_the_body_touch_static_geoms_again(make: Make) -> None:
    # §2.3 rule 6 once the loop joint is gone (a supervisor removes its SolidReference): "B" is jointed only to
    # "A" again and touches the floor at the next collision pass
    sim = make(_looped(True) + ' Robot { name "s" supervisor TRUE }', "gravity 0 basicTimeStep 8")
    sup = Supervisor(simulation=sim, robot_node=sim.robots[-1].node)
    loop = sup.getRoot().getField("children").getMFNode(1).getField("children").getMFNode(1)
    assert loop.getTypeName() == "HingeJoint"
    loop.getField("endPoint").removeSF()
    sup.step(8)
    assert _touching(sim, "B", None) > 0


def _chain(anchor_b: str) -> str:
    """A robot body; "a" hinged to it at the origin; "b", hinged to "a" at ``anchor_b``, overlapping the robot."""
    return f"""Robot {{ selfCollision TRUE translation 0 0 5 boundingObject Box {{ size 0.2 0.2 0.2 }}
  physics Physics {{ }} children [
    HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }}
      endPoint Solid {{ name "a" translation 0 0 1 {_cube()} children [
        HingeJoint {{ jointParameters HingeJointParameters {{ anchor {anchor_b} axis 1 0 0 }}
          endPoint Solid {{ name "b" translation 0 0 -0.95 {_cube()} }} }} ] }} }} ] }}"""


def test_a_chain_of_hinges_sharing_one_anchor_does_not_collide(make: Make) -> None:
    # §2.3 rule 7: hinge chains sharing the same anchor between the two bodies => ignored ("b"'s anchor, in
    # "a"'s frame, 0 0 -1, is the robot-"a" hinge's anchor, the robot's origin)
    sim = make(_chain("0 0 -1"), "gravity 0")
    assert _touching(sim, "b", None) == 0
    robot = _body(sim, "robot").ptr
    assert not [j for j in contact_joints(_body(sim, "b").ptr) if robot in j]


def test_a_chain_of_hinges_with_different_anchors_collides(make: Make) -> None:
    # §2.3 rule 7 (control): the same chain with "b" hinged elsewhere: the robot and "b" overlap and touch
    sim = make(_chain("0 0 -0.5"), "gravity 0")
    robot = _body(sim, "robot").ptr
    assert [j for j in contact_joints(_body(sim, "b").ptr) if robot in j]


# ------------------------------------------------------------------ §2.4 kinematic Solids


def _robot_with_kinematic_child(extra: str = "", velocity: str = "0 0 0") -> str:
    """A robot body moving at ``velocity`` with a Solid without Physics ("kin", a 0.1 m box) 0.5 m along x."""
    return f"""Robot {{ linearVelocity {velocity} boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }}
  children [ Solid {{ name "kin" translation 0.5 0 0 boundingObject Box {{ size 0.1 0.1 0.1 }} }} ] }} {extra}"""


def test_a_kinematic_solid_in_a_robot_is_placed_from_the_scene_graph_every_step(make: Make) -> None:
    # §2.4: geoms of Solids without Physics have no body; "Inside a Robot they are re-positioned each step from
    # the scene graph", in prePhysicsStep (§1.6 step 2, before dWorldStep): the robot drifts 1 m/s along x for
    # 10 steps of 10 ms; the collision pass after step 10 sees the child's geom where the scene graph had it
    # before that step, 0.5 + 9·0.01 (the robot at 0.1 by then)
    sim = make(_robot_with_kinematic_child(velocity="1 0 0"), "gravity 0 basicTimeStep 10 physicsDisableTime 0")
    kin = next(s for s in sim.solids if s.name == "kin")
    (gr,) = kin.geoms
    assert gr.body is None
    sim.step(10)
    assert _body(sim, "robot").pos[0] == pytest.approx(0.1, abs=1e-12)
    assert list(ode.vec3(sim._lib.dGeomGetPosition(gr.ptr))) == pytest.approx([0.59, 0.0, 0.0], abs=1e-9)


def test_a_kinematic_solid_in_a_robot_pushes_others_without_forces_on_the_robot(make: Make) -> None:
    # §2.4: "forces are not transmitted to the robot's bodies": a free box overlapping the robot's kinematic
    # child is pushed out while the robot's body stays at rest
    box = f'Solid {{ name "box" translation 0.55 0 0 {_cube()} }}'
    sim = make(_robot_with_kinematic_child(box), "gravity 0 basicTimeStep 10 physicsDisableTime 0")
    assert _touching(sim, "box", None) > 0  # the pair is (box, static): the robot's body is not in it
    sim.step(20)
    assert _body(sim, "box").pos[0] > 0.56
    robot = _body(sim, "robot")
    assert list(robot.lvel) == [0.0, 0.0, 0.0] and list(robot.avel) == [0.0, 0.0, 0.0]
