"""Fixed joints made at run time (a locked Connector, a VacuumGripper's hold: :mod:`dualtwin.webots.fixed_link`)
and the contact filter (webots-on-ode.md §2.3 rule 6: a body jointed to the static environment ignores static
geoms; jointed bodies do not collide). The filter holds while any such joint does: ODE asks whether a joint
connects the two, not how many.

Setting: no gravity; the dynamic 0.1 m box sits at z = 0.05 (bottom at 0), the static floor's top is at z = 0.01,
so they overlap by 1 cm. The contacts of the collision pass made when the world was built act in the first step
(contacts are found at the end of a step for the next, webots-on-ode.md §1.6), whatever is held; from then on a
body jointed to the world has no contact with the floor, so the joint only corrects that first step's small
displacement and its force dies away (below 0.01 N within 30 steps: no other force acts). Unfiltered, the 1 cm
overlap is a contact at every step, which the joint holds against with hundreds of newtons.
"""

from __future__ import annotations

import math

from dualtwin.webots.controller import Supervisor
from dualtwin.webots.fixed_link import FixedLink
from dualtwin.webots.physics import Simulation, SolidRec
from tests.support.quiet_worlds import quiet_supervisor

TS = 8
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ supervisor TRUE }}
Solid {{ name "floor" translation 0 0 -0.04 boundingObject Box {{ size 1 1 0.1 }} }}
Solid {{ name "box" translation 0 0 0.05 boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ mass 1 }} }}
"""


def _box_and_floor() -> tuple[Supervisor, Simulation, SolidRec]:
    sup = quiet_supervisor(WORLD)
    sim = sup.simulation
    return sup, sim, next(s for s in sim.solids if s.node.fields.get("name") == "box")


def _force_after(sup: Supervisor, hold: FixedLink, steps: int) -> float:
    for _ in range(steps):
        sup.step(TS)
    return math.hypot(*hold.force())


def test_a_body_held_to_the_world_twice_ignores_static_geoms_until_its_last_hold_goes() -> None:
    sup, sim, box = _box_and_floor()
    assert box.body is not None
    first, second = FixedLink(sim, box.body, None), FixedLink(sim, box.body, None)
    sup.step(TS)  # (the contacts found at build act here)
    first.destroy()  # one hold released: the other still joins the box to the static environment
    assert _force_after(sup, second, 30) < 0.01


def test_control_one_hold_filters_and_its_release_lets_the_floor_push() -> None:
    # the same box held once: the force dies away as above; released, the overlap is a contact again, which
    # pushes the box up (its velocity along +z)
    sup, sim, box = _box_and_floor()
    assert box.body is not None
    hold = FixedLink(sim, box.body, None)
    assert _force_after(sup, hold, 31) < 0.01
    hold.destroy()
    sup.step(TS)
    sup.step(TS)
    assert sim.solid_velocity(box)[2] > 0.0
