"""Mass properties measured the way a user could: a supervisor gives a body one step of a known force and
torque and reads what they added to its speed and spin (h/m and τ·h/I for a step of h seconds)."""

from __future__ import annotations

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

FORCE = 1.0  # N along x
TORQUE = 0.01  # N·m about z


def supervisor_in(scene: str, time_step: int, gravity: float = 0.0) -> Supervisor:
    """A supervisor robot added to ``scene`` (world nodes, as text), stepped once."""
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {time_step} gravity {gravity} }}
{scene}
Robot {{ supervisor TRUE }}
"""
    sup = Supervisor(simulation=Simulation(load_world_text(world)))
    sup.step(time_step)
    return sup


def kick(sup: Supervisor, time_step: int, name: str = "BODY") -> tuple[float, float]:
    """The x speed and the z spin that one step of :data:`FORCE` along x and :data:`TORQUE` about z add to the
    Solid DEF ``name``."""
    body = sup.getFromDef(name)
    before = body.getVelocity()
    body.addForce([FORCE, 0.0, 0.0], False)
    body.addTorque([0.0, 0.0, TORQUE], False)
    sup.step(time_step)
    after = body.getVelocity()
    return after[0] - before[0], after[5] - before[5]
