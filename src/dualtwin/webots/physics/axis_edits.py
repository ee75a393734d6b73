"""A supervisor's run-time edit of a joint's ``axis`` or ``anchor`` (a (Hinge)JointParameters' or
BallJointParameters' field) acts on the joint from the next step, as in Webots.

Webots (WbJoint::updateAxis, WbHingeJoint::updateAnchor) first places the endPoint where the joint's current
positions put it about the new axis through the new anchor, from its zero pose, which the edit keeps (the load
pose undone by the load positions, §4.1): the move of a ``position`` edit, its subtree's physics reset (§4.1).
Then the ODE joint is set again as at creation (applyToOdeAxis/applyToOdeAnchor): axes and anchor from the parent's
current pose with the sign rules of §4.2 (hinge, negated on a static parent), §4.3 (slider, negated) and §4.4
(Hinge2, the second axis carried by the first; BallJoint, the Euler AMotor's axes), ODE's zero at the current
configuration and the offsets the current positions, so the positions read on without a jump. The stops are
mapped from the new offsets (§4.2, a hinge's ±π re-basing starting again), the spring and damper rows and the
motor rows act about the new axes. A kinematic joint (an endPoint without Physics) turns or slides its endPoint
about the new axis at once.

Which fields move what, as at load (:meth:`SceneBuilder._joint_axes`): the ``axis`` of a HingeJoint's, a
SliderJoint's (normalised, §4.3) and a Hinge2Joint's first and second parameters; a BallJoint's first axis is its
jointParameters2's, its third its jointParameters3's, the second their cross product (§4.4); the ``anchor`` of the
first parameters of a HingeJoint, a Hinge2Joint and a BallJoint. A zero axis is refused as Webots refuses it
("'axis' must be non zero", a warning; the joint keeps its axis), and so are Hinge2 or BallJoint axes that the
edit would align (no frame spans them; ODE aborts on their cross product). ``suspensionAxis`` acts on nothing:
the HingeJoint's suspension is ODE-fork-only (Appendix A.2, not modelled) and a Hinge2Joint's suspension is
ODE's own, along its first axis, which an ``axis`` edit moves.
"""

from __future__ import annotations

from dualtwin.webots import _math3 as m3
from dualtwin.webots.physics.build import aligned, overflow_free
from dualtwin.webots.physics.edits import SupervisorEdits
from dualtwin.webots.physics.records import JointRec, field_or

__all__ = ["JointAxisEdits"]


class JointAxisEdits(SupervisorEdits):
    """Run-time edits of joint axes and anchors (see the module docstring)."""

    def _apply_joint_field(self, joint: JointRec, i: int, name: str) -> bool:
        if name == "axis":
            axes = self._edited_axes(joint, i)
            if axes is not None:
                self._set_axes_and_anchor(joint, axes, joint.anchor_local)
            return axes is not None
        if name == "anchor" and i == 0 and joint.kind != "slider":
            anchor = tuple(float(v) * joint.scale for v in field_or(joint.params[0], "anchor", (0.0, 0.0, 0.0)))
            self._set_axes_and_anchor(joint, list(joint.axis_local), anchor)  # type: ignore[arg-type]
            return True
        return super()._apply_joint_field(joint, i, name)

    def _edited_axes(self, joint: JointRec, i: int) -> list[m3.Vec3] | None:
        """The joint's axes with the ``axis`` of its parameters ``i`` as edited; None where that field is not an
        axis of the joint (a BallJointParameters' axis) or the edit is refused (with a warning)."""
        node = joint.params[i]
        if node is None or joint.kind == "ball" and i == 0:
            return None
        axis = tuple(float(v) for v in field_or(node, "axis", (0.0, 0.0, 0.0)))
        if m3.norm(axis) < 1e-12:
            self.warn(f"{node.type_name}: 'axis' must be non zero; the edit is ignored")
            return None
        axis = overflow_free(axis)  # components near 1e308, as at load (the Field API refuses non-finite ones)
        axes = list(joint.axis_local)
        if joint.kind == "slider":
            axes[0] = m3.normalized(axis)  # type: ignore[arg-type]  # §4.3: Webots normalises the slider axis
        elif joint.kind == "ball":
            a1 = axis if i == 1 else axes[0]
            a3 = axis if i == 2 else axes[2]
            axes = [a1, m3.cross(a3, a1), a3]  # type: ignore[list-item]
        else:
            axes[i] = axis  # type: ignore[assignment]
        if joint.kind in ("hinge2", "ball"):
            first, other = axes[0], axes[2] if joint.kind == "ball" else axes[1]
            if aligned(first, other):  # no frame spans them, as the load's test (SceneBuilder._joint_axes)
                self.warn(f"{joint.node.type_name}: the edited axis is aligned with the joint's other axis; "
                          "the edit is ignored")
                return None
        return axes

    def _set_axes_and_anchor(self, joint: JointRec, axes: list[m3.Vec3], anchor: m3.Vec3) -> None:
        """The joint takes ``axes`` and ``anchor`` (in its frame) from the next step (the module docstring)."""
        moved = axes != joint.axis_local or anchor != joint.anchor_local
        joint.axis_local[:] = axes
        joint.anchor_local = anchor
        if not joint.ptr:
            return  # kinematic: the endPoint's pose follows the new axes (SimulationCore._endpoint_motion)
        child = joint.child
        if moved and child is not None and child.joint is joint and joint.child_body is not None:
            self._place_endpoint(joint)
        self._set_joint_again(joint)
        self.wake(joint)
