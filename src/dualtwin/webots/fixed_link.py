"""A fixed joint created at run time between two bodies (a locked Connector pair, a vacuum gripper's hold).

The joint keeps the bodies' relative pose at creation, reports the force it carries (ODE joint feedback) and
declares the two bodies jointed, so their geoms stop colliding with each other as any jointed pair (a body jointed
to the static world stops colliding with static geoms, §2.3 rule 6). Its strength test is Webots' for Connector
and VacuumGripper: the force on the first body is split into a tensile part along a given axis (pulling the two
apart) and a shear part perpendicular to it; either part above its strength (-1 = unbreakable) breaks the link.
"""

from __future__ import annotations

import ctypes

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.physics import BodyRec, Simulation, SolidRec

__all__ = ["FixedLink", "body_of"]


def body_of(solid: SolidRec | None) -> BodyRec | None:
    """The ODE body that carries ``solid`` (its own, or its nearest ancestor's); None for a static solid."""
    while solid is not None:
        if solid.body is not None:
            return solid.body
        solid = solid.parent
    return None


class FixedLink:
    """One fixed joint between ``first`` (a body) and ``second`` (a body, or None for the static world)."""

    def __init__(self, sim: Simulation, first: BodyRec, second: BodyRec | None) -> None:
        self.sim = sim
        self.first = first
        self.second = second
        lib = sim._lib
        self.joint = lib.dJointCreateFixed(sim._world, None)
        lib.dJointAttach(self.joint, first.ptr, second.ptr if second is not None else None)
        lib.dJointSetFixed(self.joint)
        self.feedback = ode.dJointFeedback()
        lib.dJointSetFeedback(self.joint, ctypes.byref(self.feedback))
        sim.link_bodies(first, second, True)

    def force(self) -> m3.Vec3:
        """The force the joint applied to the first body during the last step (N, world frame)."""
        f = self.feedback.f1
        return (f[0], f[1], f[2])

    def breaks(self, axis: m3.Vec3, tensile_strength: float, shear_strength: float) -> bool:
        """Whether the last step's force exceeds a strength; ``axis`` points from the first body to the second."""
        force = self.force()
        tensile = m3.dot(force, axis)
        shear = m3.norm(m3.sub(force, m3.scale(axis, tensile)))
        return (0.0 <= tensile_strength < tensile) or (0.0 <= shear_strength < shear)

    def destroy(self) -> None:
        lib = self.sim._lib
        lib.dJointDestroy(self.joint)
        self.sim.link_bodies(self.first, self.second, False)
        for body in (self.first, self.second):
            if body is not None:
                lib.dBodyEnable(body.ptr)
