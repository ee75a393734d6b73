"""Solid merging × supervisor moves (webots-on-ode.md §3.3 with §6): a Solid with Physics that is a plain child of
a Solid with Physics is merged into its parent's body, and a supervisor's write of its ``translation`` or
``rotation`` moves it, with its subtree, at the next step (§6: "Moving a Solid teleports its whole subtree"). The
Solid stays merged: it takes its new place in the body, whose mass is summed again over its Solids (§3.2/§3.3),
while the body's root Solid, whose fields were not written, stays where it is; as the twin already does when the
Pose holding such a Solid is moved.

Hand computation: no gravity; the root Solid is a 0.2 m Box at the origin (density 1000: 8 kg), the merged child
the same Box at x = 0.5 m (8 kg), so the body's centre of mass is at x = (8·0 + 8·0.5)/16 = 0.25 m. The child moved
to x = 1 puts it at (8·0 + 8·1)/16 = 0.5 m. A merged grandchild 0.1 m above the child (a 0.1 m Box: 1 kg) moves
with it: the child moved to x = 1 and turned half a turn about x puts it at (1, 0, -0.1), and the centre of mass
at ((8·1 + 1·1)/17, 0, -0.1·1/17)."""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

TS = 10


def _world(grandchild: str = "") -> Supervisor:
    return quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ supervisor TRUE }}
DEF ROOT Solid {{ boundingObject Box {{ size 0.2 0.2 0.2 }} physics Physics {{ }} children [
  DEF CHILD Solid {{ translation 0.5 0 0 name "child" boundingObject Box {{ size 0.2 0.2 0.2 }} physics Physics {{ }}
    children [ {grandchild} ] }} ] }}
""")


def test_a_merged_solid_moved_by_a_supervisor_takes_its_new_place_in_its_body() -> None:
    sup = _world()
    sup.step(TS)
    root, child = sup.getFromDef("ROOT"), sup.getFromDef("CHILD")
    assert root.getCenterOfMass() == pytest.approx([0.25, 0.0, 0.0], abs=1e-12)
    child.getField("translation").setSFVec3f([1.0, 0.0, 0.0])
    sup.step(TS)
    assert child.getPosition() == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert root.getPosition() == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert root.getCenterOfMass() == pytest.approx([0.5, 0.0, 0.0], abs=1e-12)
    assert root.getVelocity() == pytest.approx([0.0] * 6, abs=1e-12)  # nothing pushed it
    sup.simulationReset()  # §6: fields and Solids back to their load state
    sup.step(TS)
    assert child.getPosition() == pytest.approx([0.5, 0.0, 0.0], abs=1e-12)
    assert root.getCenterOfMass() == pytest.approx([0.25, 0.0, 0.0], abs=1e-12)


def test_a_merged_solid_turned_by_a_supervisor_carries_its_merged_subtree() -> None:
    sup = _world('DEF GRAND Solid { translation 0 0 0.1 name "grand" boundingObject Box { size 0.1 0.1 0.1 } '
                 "physics Physics { } }")
    sup.step(TS)
    child, grand = sup.getFromDef("CHILD"), sup.getFromDef("GRAND")
    assert grand.getPosition() == pytest.approx([0.5, 0.0, 0.1], abs=1e-12)
    # a half turn about x through the child's origin takes the grandchild from 0.1 above it to 0.1 below it
    child.getField("rotation").setSFRotation([1.0, 0.0, 0.0, 3.141592653589793])
    child.getField("translation").setSFVec3f([1.0, 0.0, 0.0])
    sup.step(TS)
    assert grand.getPosition() == pytest.approx([1.0, 0.0, -0.1], abs=1e-12)
    assert sup.getFromDef("ROOT").getCenterOfMass() == pytest.approx([(8 * 1 + 1 * 1) / 17, 0.0, -0.1 / 17],
                                                                     abs=1e-12)
