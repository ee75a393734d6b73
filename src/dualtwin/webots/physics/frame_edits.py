"""Supervisor edits of the frames among a Solid's children: a ``Pose`` or ``Transform`` moved (``translation``,
``rotation``; a Transform's ``scale``) while the simulation runs.

In Webots such a frame carries everything below it, and the move shows at the next step: the Solid-derived
devices under it (their readings come from their Solids' poses), the Shapes that cameras, infra-red distance
sensors and lidars see, the joints and Propellers it holds, and the Solids below it with their subtrees. Every
frame cached under the edited node (a Solid's ``pre`` frame, a joint's or a Propeller's ``frame_rel``) is
computed again from the scene tree, as the load computed it (:meth:`SceneBuilder._walk_children`), and what
hangs on it follows:

* a Solid without a body of its own (static, or a device on a robot without Physics) moves with its subtree;
  its body-less geoms are placed again;
* a Solid merged into its parent's body (§3.3) takes its new place in that body: the body's mass and centre
  of mass are summed again (:meth:`MassEdits._remass`, the root Solid stays put) and its geoms move on the
  body;
* a Solid with a body of its own (fixed to its parent, or a joint's endPoint) is moved with its subtree as a
  supervisor edit of that Solid's ``translation``/``rotation`` would move it, the joints crossing its subtree's
  border anchored again.

The Shapes are drawn and ray-cast from the fields at their next use (the geometry version changes). DEF/USE
copies of the frame are one node in Webots: they move together. A reset restores the fields and applies the
edit again, which puts every frame back where the load had it.

A Transform's ``scale`` scales the translations below it (:mod:`dualtwin.webots.solid_scale`), as at load. A
run-time edit of the ``scale`` itself reaches the Shapes seen by rays and cameras and the boundingObjects it is
inside, not the Solids and joints below it: their frames, geoms, masses and own Shapes keep the load's scale (a
warning says so).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence

from dualtwin.webots import _math3 as m3
from dualtwin.webots._math3 import Pose
from dualtwin.webots.mass_rules import rot_matrix
from dualtwin.webots.nodes import Node, copy_value
from dualtwin.webots.physics.physics_changes import PhysicsChanges
from dualtwin.webots.physics.records import (
    ATTACHMENT_TYPES,
    JOINT_TYPES,
    BodyRec,
    SolidRec,
    field_or,
    is_solid,
)
from dualtwin.webots.solid_scale import holds_bodies, scaled_local

__all__ = ["FrameEdits", "FRAME_FIELDS"]

FRAME_FIELDS = ("translation", "rotation", "scale")


class FrameEdits(PhysicsChanges):
    """Frames among a Solid's children moved by a supervisor (see the module docstring)."""

    def _apply_field(self, node: Node, name: str) -> bool:
        if node.type_name in ("Pose", "Transform") and name in FRAME_FIELDS:
            # Its DEF/USE copies (one walk of the world) take the new value before anything is placed again.
            linked = self.linked_nodes(node)
            value = node.fields.get(name)
            for other in linked[1:]:
                other.fields[name] = copy_value(value)
            bounded = self._bounding_frame_changed(linked)  # the frame may sit in boundingObjects (scene_changes)
            if name == "scale" and holds_bodies(node):
                self.warn_once(f"{node.location}: a run-time edit of a Transform's scale above Solids or joints is "
                               "not applied to them (their frames, geoms and masses keep the load's scale)")
                # the Shapes beside those Solids follow the field, for rays and cameras (theirs go with them)
                self._geoms_changed()
                return True
            return self._children_frame_changed(linked) or bounded
        if name in ("translation", "rotation") and is_solid(node):
            solid = self._solid_by_node.get(id(node))
            if solid is not None and self._is_merged(solid):
                # a reset restored the fields of a merged Solid a supervisor moved: back to its load place
                solid.rel = solid.pre * scaled_local(node, solid.scale)
                self._rebody(solid, solid.body)  # type: ignore[arg-type]
                return True
        return super()._apply_field(node, name)

    @staticmethod
    def _is_merged(solid: SolidRec) -> bool:
        """Whether ``solid`` is merged into the body of a Solid above it (§3.3)."""
        body = solid.body
        return body is not None and body.root is not solid and not body.removed

    def _children_frame_changed(self, linked: list[Node]) -> bool:
        """A Pose or Transform moved, ``linked`` being it and its DEF/USE copies: every record below one of them
        among Solids' children is placed again. False when no Solid's children hold it."""
        ids = {id(n) for n in linked}
        found = False
        solids: dict[int, tuple[SolidRec, Pose]] = {}
        joints = []
        tops: list[tuple[Iterable[Node], SolidRec | None]] = [(self.world.nodes, None)]
        tops += [(s.node.children(), s) for s in self.solids]
        for children, top in tops:
            scale = top.scale if top is not None else 1.0
            for kind, item, frame, under in self._frames(children, Pose(), False, ids, scale):
                found = True
                if not under:
                    continue
                if kind == "solid":
                    solid = self._solid_by_node.get(id(item))
                    if solid is not None:
                        solids[id(solid)] = (solid, frame)
                elif kind == "joint":
                    joint = self._joint_by_node.get(id(item))
                    if joint is not None and joint.frame_rel != frame:
                        joint.frame_rel = frame
                        joints.append(joint)
                else:
                    for site in self.attachments:
                        if site.node is item:
                            site.frame_rel = frame
        if not found:
            return False
        for solid in self.solids:  # parents first: a Solid moved carries the Solids below it
            if id(solid) in solids:
                self._reframe(solid, solids[id(solid)][1])
        for joint in joints:  # a reset anchored them before the edit was applied again
            if joint.ptr:
                self._reanchor(joint)
        self._geoms_changed()  # visual Shapes and ray casters follow the fields at their next use
        return True

    def _frames(
        self, children: Iterable[Node | None], frame: Pose, under: bool, ids: set[int], scale: float
    ) -> Iterator[tuple[str, Node, Pose, bool]]:
        """Walk a Solid's children as the load does: each Solid, joint and attachment met with the frame it
        hangs in (in the Solid's frame) and whether an edited node lies above it. Yields ("frame", node, ...)
        for an edited node itself, so a frame that holds only Shapes counts as found."""
        for child in children:
            if child is None:
                continue
            if is_solid(child):
                yield "solid", child, frame, under
            elif child.type_name in JOINT_TYPES:
                yield "joint", child, frame, under
                end = field_or(child, "endPoint", None)
                while isinstance(end, Node) and end.type_name == "Slot":
                    end = field_or(end, "endPoint", None)
                if isinstance(end, Node) and is_solid(end):
                    yield "solid", end, frame, under
            elif child.type_name in ATTACHMENT_TYPES:
                yield "attachment", child, frame, under
            elif "translation" in child.fields and "rotation" in child.fields and "children" in child.fields:
                inside = under or id(child) in ids
                if id(child) in ids:
                    yield "frame", child, frame, True
                inner = self.factor_below(child, scale)
                yield from self._frames(child.children(), frame * scaled_local(child, scale), inside, ids, inner)
            elif "children" in child.fields:
                yield from self._frames(child.children(), frame, under, ids, scale)
            elif child.type_name == "Slot" and isinstance(field_or(child, "endPoint", None), Node):
                yield from self._frames([child.fields["endPoint"]], frame, under, ids, scale)

    def _reframe(self, solid: SolidRec, frame: Pose) -> None:
        """Put ``solid`` in its new parent frame ``frame`` (its own translation and rotation kept) and move what
        hangs on it (see the module docstring)."""
        load_pre: dict[SolidRec, Pose] = self.__dict__.setdefault("_load_pre", {})  # (no __init__ in the mixins)
        load_pre.setdefault(solid, solid.pre)
        # a reset put the Solid back at its load pose (rel is load_rel again) before this edit is applied again
        pre = load_pre[solid] if solid.rel is solid.load_rel else solid.pre
        body = solid.body
        if frame == pre:  # (bit for bit the load's frame after a reset: the Solid stays where the reset put it)
            solid.pre = frame
        merged = body is not None and body.root is not solid and not body.removed
        if merged and body is not None:
            if frame != pre:
                solid.pre, solid.rel = frame, frame * (pre.inverse() * solid.rel)
            self._rebody(solid, body)
            return
        if frame == pre:
            return
        old_world = self.solid_world_pose(solid)
        if body is None:
            solid.pre, solid.rel = frame, frame * (pre.inverse() * solid.rel)
            new_world = self.solid_world_pose(solid)
        else:  # a body of its own: moved as a supervisor edit of its translation would move it
            local = pre.inverse() * self._unmoved_rel(solid)
            solid.pre, solid.rel = frame, frame * (pre.inverse() * solid.rel)
            parent_world = self.solid_world_pose(solid.parent) if solid.parent is not None else Pose()
            new_world = parent_world * self._kinematic_extra(solid) * frame * local
        self._carry(solid, new_world * old_world.inverse(), None)

    def _teleport_solid(
        self, solid: SolidRec, translation: Sequence[float] | None, rotation: Sequence[float] | None
    ) -> None:
        """A supervisor's move of a Solid (§6); one merged into its parent's body (§3.3) stays merged and takes its
        new place in that body, as when a Pose above it moves (:meth:`_rebody`)."""
        body = solid.body
        if body is None or not self._is_merged(solid):
            super()._teleport_solid(solid, translation, rotation)
            return
        node = solid.node
        current = solid.pre.inverse() * solid.rel
        t = tuple(float(v) for v in translation) if translation is not None else m3.scale(current.t, 1 / solid.scale)
        R = m3.rot_axis_angle(rotation) if rotation is not None else current.R
        node.fields["translation"] = t
        node.fields["rotation"] = tuple(rotation) if rotation is not None else m3.axis_angle_from_mat(R)
        solid.rel = solid.pre * Pose(R, m3.scale(t, solid.scale))
        self._rebody(solid, body)
        self._edited[(id(node), "translation")] = node  # simulationReset puts it back (_apply_field)

    def _unmoved_rel(self, solid: SolidRec) -> Pose:
        """The current pose of a Solid with its own body in its parent Solid's frame (its joint's motion in)."""
        world = self.solid_world_pose(solid)
        parent = self.solid_world_pose(solid.parent) if solid.parent is not None else Pose()
        return parent.inverse() * world

    def _rebody(self, solid: SolidRec, body: BodyRec) -> None:
        """A merged Solid moved inside its body: the frames of the body's Solids in its root Solid's frame are
        computed again and, if one changed, the body's mass summed again (its geoms follow); the bodies and
        body-less geoms below it are carried along."""
        old_world = self.solid_world_pose(solid)
        changed = False
        for member in solid.subtree():
            if member.body is body and member.parent is not None and member is not body.root:
                in_body = member.parent.in_body * member.rel
                changed |= in_body != member.in_body
                member.in_body = in_body
        if not changed:
            return
        self._remass(body)
        new_world = self.solid_world_pose(solid)
        self._carry(solid, new_world * old_world.inverse(), body)

    def _carry(self, solid: SolidRec, T: Pose, own: BodyRec | None) -> None:
        """Move the bodies whose root Solid lies in ``solid``'s subtree (but ``own``, the body it is merged
        into) by the world transform ``T``, place its body-less geoms again and anchor the joints touching the
        subtree where their Solids now are."""
        lib = self._lib
        subtree = solid.subtree()
        inside = {id(s) for s in subtree}
        moved = [s.body for s in subtree if s.body is not None and s.body.root is s and s.body is not own
                 and not s.body.removed]  # fmt: skip
        for body in moved:
            new_root = T * body.pose()
            lib.dBodySetPosition(body.ptr, *new_root.apply(body.com))
            lib.dBodySetRotation(body.ptr, rot_matrix(new_root.R))
            self._wake_body(body.index)
        static = [g for s in subtree for g in s.geoms if g.body is None]
        reach = self._static_reach(static)
        for s in subtree:
            for g in s.geoms:
                if g.body is None:
                    self._place_static_geom(g, self.solid_world_pose(s))
        if static:  # a body asleep against a static shape that left, or where one arrived, must wake
            self._wake_reaching(reach + self._static_reach(static))
        for body in moved:
            if body.fixed_joint:
                lib.dJointSetFixed(body.fixed_joint)
        for joint in self.joints:
            touches = (joint.parent is not None and id(joint.parent) in inside) or (
                joint.child is not None and id(joint.child) in inside)
            if joint.ptr and touches:
                self._reanchor(joint)
