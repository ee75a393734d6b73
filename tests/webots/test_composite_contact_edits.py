"""Contact surfaces × run-time edits (webots-on-ode.md §2.1–§2.3 with §1.6): Webots fills every contact's surface
in the near callback of each collision pass (§2.3 step 10, fillSurfaceParameters of §2.2) from the first
ContactProperties matching the two Solids' ``contactMaterial`` at that moment (§2.1). So a supervisor's edit of a
ContactProperties field, or of a Solid's ``contactMaterial``, governs every contact created by the passes after it.

Hand computation shared by the tests: a 0.1 m Box of density 1000 (m = 1 kg) rests on a Plane with a speed of
1 m/s along x; h = 10 ms, g = 9.81 m/s². With Coulomb friction µ = 1 a step takes at most µ·g·h ≈ 0.098 m/s of
speed (friction ≤ µ·N, N ≈ m·g), so the box stops within about 11 steps (0.11 s). The edit is made after the first
step; the contact joints of the second step were created by the collision pass after the first one, still with
µ = 1 (§1.6: contacts of pass k act in step k+1), so the box keeps at least 1 − 2·0.098 − a margin > 0.7 m/s once
friction is gone, and is at rest (< 0.05 m/s) after 21 steps when it is not."""

from __future__ import annotations

from dualtwin.webots.controller import Field, Supervisor
from tests.support.quiet_worlds import quiet_supervisor

TS = 10


def _world(contact_properties: str, box_fields: str = "") -> Supervisor:
    return quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} contactProperties [ {contact_properties} ] }}
Robot {{ supervisor TRUE }}
Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF BOX Solid {{ translation 0 0 0.05 linearVelocity 1 0 0 {box_fields}
  boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} }}
""")


def _speed_after(sup: Supervisor, steps: int) -> float:
    for _ in range(steps):
        sup.step(TS)
    return float(sup.getFromDef("BOX").getVelocity()[0])


def test_a_coulomb_friction_edited_to_zero_frees_the_sliding_box_from_the_next_collision_pass() -> None:
    control = _world("DEF CP ContactProperties { coulombFriction 1 bounce 0 }")
    assert _speed_after(control, 21) < 0.05  # µ = 1 stops it (module docstring)
    sup = _world("DEF CP ContactProperties { coulombFriction 1 bounce 0 }")
    sup.step(TS)
    sup.getFromDef("CP").getField("coulombFriction").setMFFloat(0, 0.0)
    assert _speed_after(sup, 20) > 0.7


def test_a_solid_whose_contact_material_is_edited_takes_the_contact_properties_of_its_new_material() -> None:
    # §2.1: "ice" against "default" matches the first node (µ 0); "default" against "default" the second (µ 1)
    properties = ('ContactProperties { material1 "ice" material2 "default" coulombFriction 0 bounce 0 } '
                  "ContactProperties { coulombFriction 1 bounce 0 }")
    control = _world(properties)
    assert _speed_after(control, 21) < 0.05
    sup = _world(properties)
    sup.step(TS)
    sup.getFromDef("BOX").getField("contactMaterial").setSFString("ice")
    assert _speed_after(sup, 20) > 0.7


def _contact_properties_field(sup: Supervisor) -> Field:
    children = sup.getRoot().getField("children")
    assert children is not None
    info = children.getMFNode(0)
    assert info is not None and info.getTypeName() == "WorldInfo"
    field = info.getField("contactProperties")
    assert field is not None
    return field


def test_a_contact_properties_node_imported_first_into_world_info_matches_from_the_next_collision_pass() -> None:
    # §2.1: the first node of WorldInfo.contactProperties whose materials match wins
    sup = _world("ContactProperties { coulombFriction 1 bounce 0 }")
    sup.step(TS)
    _contact_properties_field(sup).importMFNodeFromString(0, "ContactProperties { coulombFriction 0 bounce 0 }")
    assert _speed_after(sup, 20) > 0.7
    sup.simulationReset()  # §6: imported nodes are taken out: µ = 1 again
    assert _speed_after(sup, 21) < 0.05


def test_removing_the_matching_contact_properties_hands_the_pairs_to_the_next_matching_node() -> None:
    properties = "ContactProperties { coulombFriction 0 bounce 0 } ContactProperties { coulombFriction 1 bounce 0 }"
    control = _world(properties)
    assert _speed_after(control, 21) > 0.7  # the first node (µ 0) matches
    sup = _world(properties)
    sup.step(TS)
    _contact_properties_field(sup).removeMF(0)
    assert _speed_after(sup, 20) < 0.05
    sup.simulationReset()  # §6: every field back to its load value, the removed node too
    assert _speed_after(sup, 21) > 0.7
