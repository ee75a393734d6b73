"""The ODE binding's calls and the GIL: short queries and setters keep it (no release and re-acquisition around
each of the dozens of calls a basic step makes); the world step and the collision pass release it, the former
because it runs long, the latter because it calls back into Python for every candidate pair."""

from __future__ import annotations

import ctypes

from dualtwin.webots import load_world_text, ode
from dualtwin.webots.physics import Simulation

KEEPS_GIL = ctypes._FUNCFLAG_PYTHONAPI  # type: ignore[attr-defined]

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { children [ Shape { geometry Plane { size 4 4 } } ] boundingObject Plane { size 4 4 } }
Solid {
  translation 0 0 0.2
  children [ Shape { geometry Sphere { radius 0.1 } } ]
  boundingObject Sphere { radius 0.1 }
  physics Physics { mass 1 }
}
"""


def test_only_the_step_and_the_collision_pass_release_the_gil() -> None:
    lib = ode.load()
    for name in ("dWorldStep", "dSpaceCollide", "dSpaceCollide2"):
        assert not getattr(lib, name)._flags_ & KEEPS_GIL, name
    for name in ("dJointSetHingeParam", "dJointGetHingeAngle", "dJointGetHingeAngleRate", "dBodyIsEnabled",
                 "dJointGroupEmpty", "dCollide", "dJointCreateContact", "dJointAttach", "dBodyGetPosition"):
        fn = getattr(lib, name)
        assert fn._flags_ & KEEPS_GIL, name
        assert fn.argtypes is not None, name  # still declared: pointers and doubles are converted as before


def test_a_ball_lands_with_contacts_made_inside_the_collision_pass() -> None:
    """dCollide and the contact joints are called from the near callback, inside dSpaceCollide: the ball comes to
    rest on the plane, not through it."""
    sim = Simulation(load_world_text(WORLD))
    for _ in range(250):
        sim.step()
    z = sim.bodies[0].pos[2]
    assert abs(z - 0.1) < 2e-3, z
    sim.close()
