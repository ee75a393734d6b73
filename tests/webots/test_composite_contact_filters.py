"""Contact filtering × joints made at run time (webots-on-ode.md §2.3 rule 6): Webots drops the contacts of a body
with every static geom when the body has a non-contact joint to the static environment (ODE's
``dAreConnectedExcluding(body, NULL, dJointTypeContact)``; "reverse joint, fixed-to-world joint"). The rule asks
about the joints the body has at the time of the collision pass, so a fixed joint made at run time to the static
world (a Connector docked to a Connector on a Solid without Physics) counts as one made at load, and its removal
lets the body touch static geoms again.

World: no gravity, so what holds the robot is the lock alone. The robot is a sphere of radius 0.05 m whose centre
is 0.04 m above a static Plane: 1 cm deep in it, a contact at every collision pass while nothing filters the
pair (ODE's sphere–plane collider). Its Connector faces +x at its origin; the static block's faces -x at the same
place (both in position: the pair docks at the first step with ``isLocked TRUE``)."""

from __future__ import annotations

import warnings

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.ode_probe import contact_joints

TS = 16


def _world(active: str) -> tuple[Supervisor, Simulation]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BOT Robot {{ translation 0 0 0.04 supervisor TRUE children [ Connector {{ name "a" type "active" {active} }} ]
  boundingObject Sphere {{ radius 0.05 }} physics Physics {{ mass 1 }} }}
Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF BLOCK Solid {{ translation 0.1 0 0.04 name "block" children [
  Connector {{ translation -0.1 0 0 rotation 0 0 1 3.14159265 name "b" type "passive" }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
        return Supervisor(simulation=sim, robot_node=sim.robots[0].node), sim


def _floor_contacts(sim: Simulation) -> int:
    """The contact joints the robot's body holds for the next step (all of them are with the static floor)."""
    (body,) = sim.bodies
    return len(contact_joints(body.ptr))


def test_a_body_docked_to_a_static_connector_no_longer_collides_with_static_geoms_and_does_again_once_undocked(
) -> None:
    control, control_sim = _world("")
    control.step(TS)
    assert _floor_contacts(control_sim) > 0  # not docked: the sphere 1 cm deep in the floor touches it
    sup, sim = _world("isLocked TRUE")
    sup.step(TS)
    sup.step(TS)
    assert sup.getDevice("a").isLocked()
    assert _floor_contacts(sim) == 0  # §2.3 rule 6: fixed to the static world by the docking joint
    sup.getDevice("a").unlock()
    sup.step(TS)
    sup.step(TS)
    assert _floor_contacts(sim) > 0


def _arms(self_collision: str) -> tuple[Supervisor, Simulation]:
    """A robot without Physics holding two spheres (radius 0.05 m) on hinges of its own, 0.07 m apart: 3 cm deep in
    each other, not jointed to each other (each hinge joins its sphere to the static robot) and with different
    anchors (§2.3 rules 6 and 7 do not apply to the pair)."""
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BOT Robot {{ supervisor TRUE selfCollision {self_collision} children [
  HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 0 0 }}
    endPoint Solid {{ translation 0.05 0 0 name "a" boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }} }}
  HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0.2 0 0 }}
    endPoint Solid {{ translation 0.12 0 0 name "b" boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }} }}
] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
        return Supervisor(simulation=sim, robot_node=sim.robots[0].node), sim


def _sphere_contacts(sim: Simulation) -> int:
    """The contact joints between the two spheres' bodies, held for the next step."""
    a, b = sim.bodies
    return sum(1 for pair in contact_joints(a.ptr) if set(pair) == {a.ptr, b.ptr})


def test_self_collision_set_by_a_supervisor_governs_the_robots_contacts_from_the_next_collision_pass() -> None:
    # §2.3 rule 4 is a test of the near callback, made at every collision pass on the robot's selfCollision field
    control, control_sim = _arms("TRUE")
    assert _sphere_contacts(control_sim) > 0  # the pass at load: the spheres touch
    sup, sim = _arms("FALSE")
    assert _sphere_contacts(sim) == 0  # rule 4: two Solids of one robot
    sup.getSelf().getField("selfCollision").setSFBool(True)
    sup.step(TS)
    assert _sphere_contacts(sim) > 0
    sup.getSelf().getField("selfCollision").setSFBool(False)
    sup.step(TS)
    sup.step(TS)  # (the contacts of the pass before the edit act in the step after it, §1.6)
    assert _sphere_contacts(sim) == 0
