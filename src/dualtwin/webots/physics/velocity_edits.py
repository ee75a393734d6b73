"""A supervisor's write of a Solid's ``linearVelocity`` or ``angularVelocity`` field while the simulation runs.

The load reads both fields (§3: a body's initial velocity, its centre of mass moving at ``linearVelocity``; a
Solid without Physics that nothing carries moves by them every step, :meth:`Stepper._drift`), and a write acts
from the next step the same way (UNVERIFIED in the reference, which is silent on run-time writes; it follows the
rule that a field write reaches ODE at the next step):

* on the Solid at the root of a body, the written vector becomes the body's linear (centre of mass) or angular
  velocity, the other one kept, as :meth:`SupervisorEdits.set_body_velocity` (``Node.setVelocity``) sets them,
  in the order of the supervisor's requests; the body is woken;
* on a Solid without Physics that no body or joint carries, it moves by the new velocities from the next step
  on, starting or stopping as they become non-zero or zero, and ``Node.getVelocity`` reports them;
* a Solid merged into a body above it (§3.3) has no velocity of its own: its fields are not read, at load
  either.

A reset restores the fields and applies them again: the bodies take their load velocities back (as the reset
already does) and the Solids without Physics drift as at load.
"""

from __future__ import annotations

from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.frame_edits import FrameEdits
from dualtwin.webots.physics.records import is_solid

__all__ = ["VELOCITY_FIELDS", "SolidVelocityEdits"]

VELOCITY_FIELDS = ("linearVelocity", "angularVelocity")


class SolidVelocityEdits(FrameEdits):
    """Run-time writes of a Solid's velocity fields (see the module docstring)."""

    def _apply_field(self, node: Node, name: str) -> bool:
        if name in VELOCITY_FIELDS and is_solid(node):
            return self._velocity_field_changed(node, name)
        return super()._apply_field(node, name)

    def _velocity_field_changed(self, node: Node, name: str) -> bool:
        solid = self.solid_for(node)
        if solid is None:
            return False
        body = solid.body
        if body is not None:
            if body.root is not solid or body.removed:
                return False
            current = self.solid_velocity(solid)
            written = tuple(float(v) for v in node.fields[name])
            self.set_body_velocity(solid, (*written, *current[3:]) if name == "linearVelocity"
                                   else (*current[:3], *written))
            return True
        self._drifting = [s for s in self.solids if self._drifts(s)]
        return True
