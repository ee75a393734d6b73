"""Nodes a supervisor adds to or removes from the scene while the simulation runs (``importMFNodeFromString``,
``importSFNodeFromString``, ``Node.remove``, ``removeMF``...), made to take part in the physics or leave it.

Webots builds the ODE objects of an imported node as it builds those of the world at load: every Solid of the
subtree gets its records, its bodies (Webots' mass rules and Solid merging), its geoms and its joints, so an
imported Solid with Physics falls, collides and is seen by ray sensors from the next step on; a Robot brings its
devices. A removed subtree takes its geoms, joints and bodies out of the world at once: nothing collides with
it, no ray hits it, and nothing stays jointed to it.

What is supported: a subtree imported where no Solid is above it (the root's ``children``, or a Group/Pose
chain at the top). A Solid imported inside an existing Solid would change that Solid's body (merged mass,
static basis); it stays in the scene tree without physics, with one warning, as before.

Removed bodies are disabled and detached from every joint rather than destroyed, so the per-body indices and
the live views into ODE memory that the stepping keeps stay valid; they are skipped by resets.
"""

from __future__ import annotations

from collections.abc import Iterable

from dualtwin.webots._math3 import Pose
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.geometry_edits import _WAKE_MARGIN
from dualtwin.webots.physics.records import (
    SOLID_TYPES,
    BodyRec,
    GeomRec,
    SolidRec,
    field_or,
)
from dualtwin.webots.physics.stepping import Stepper

__all__ = ["SceneChanges"]


class SceneChanges(Stepper):
    """Run-time addition and removal of scene subtrees (see the module docstring)."""

    def can_add(self, ancestors: Iterable[Node]) -> bool:
        """Whether a node placed below ``ancestors`` (top-level first, its parent last) can join the physics:
        no Solid may be above it."""
        return not any(node.type_name in SOLID_TYPES for node in ancestors)

    def add_nodes(self, top: Node, ancestors: Iterable[Node] = ()) -> list[SolidRec]:
        """Build the ODE objects of ``top`` (just inserted below ``ancestors``, none of them a Solid) and
        return the new Solids' records. Geoms, bodies and joints exist when this returns."""
        frame = Pose()
        for node in ancestors:  # Pose/Transform chain above the node (Groups add nothing)
            if "translation" in node.fields and "rotation" in node.fields:
                frame = frame * Pose.from_fields(field_or(node, "translation", None), field_or(node, "rotation", None))
        n_solids, n_bodies, n_joints = len(self.solids), len(self.bodies), len(self.joints)
        n_robots, n_motors, n_loops = len(self.robots), len(self.motors), len(self._loops)
        self._walk_children([top], frame, None, None)
        solids = self.solids[n_solids:]
        self._assign_bodies(solids)
        bodies = self.bodies[n_bodies:]
        for body in bodies:
            self._create_body(body)
            self._enabled.append(True)
        for solid in solids:
            self._create_geoms(solid)
        for joint in self.joints[n_joints:]:
            self._create_joint(joint)
        for joint, name in self._loops[n_loops:]:
            self._close_loop(joint, name)
        self._create_fixed_joints(bodies)
        self._collect_devices(solids, self.robots[n_robots:])
        for motor in self.motors[n_motors:]:
            motor.reset_state()
        self._geoms_changed()
        return solids

    def remove_nodes(self, top: Node) -> None:
        """Take every Solid of the subtree ``top`` out of the physics (no-op for nodes that have none)."""
        ids = {id(n) for n in top.walk()}
        gone = [s for s in self.solids if id(s.node) in ids]
        reshaped = {id(g.solid): g.solid for g in self.geoms.values()
                    if g.source is not None and id(g.source) in ids and id(g.solid.node) not in ids}  # fmt: skip
        for solid in reshaped.values():  # a boundingObject (or a part of one) left a Solid that stays
            self.bounding_object_changed(solid.node)
        if not gone:
            return
        gone_ids = {id(s) for s in gone}
        lib = self._lib
        dead_geoms = {g.ptr for s in gone for g in s.geoms}
        for ptr in dead_geoms:
            lib.dGeomDestroy(ptr)
            del self.geoms[ptr]
        for s in gone:
            s.geoms.clear()
        self._plans.clear()  # cached pair plans name the destroyed geoms (ODE may reuse their addresses)
        dead_bodies = [b for b in self.bodies if id(b.root) in gone_ids and not b.removed]
        for body in dead_bodies:
            joints = [lib.dBodyGetJoint(body.ptr, i) for i in range(lib.dBodyGetNumJoints(body.ptr))]
            for j in joints:  # contacts, joints to surviving bodies, fixed joints: all out of the world
                lib.dJointAttach(j, None, None)
            lib.dBodySetLinearVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetAngularVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodyDisable(body.ptr)
            body.removed = True
            self._enabled[body.index] = False
            for group in body.groups:
                lib.dJointGroupEmpty(group)
        dead_joints = [j for j in self.joints if (j.child is not None and id(j.child) in gone_ids)
                       or (j.parent is not None and id(j.parent) in gone_ids)]  # fmt: skip
        for joint in dead_joints:
            for ptr in (joint.ptr, joint.amotor, joint.spring, joint.spring2):
                if ptr:
                    lib.dJointAttach(ptr, None, None)
            for end in (joint.parent_body, joint.child_body):
                if end is not None and joint in end.joints:
                    end.joints.remove(joint)
        dead_joint_ids = {id(j) for j in dead_joints}
        self.joints[:] = [j for j in self.joints if id(j) not in dead_joint_ids]
        self.motors[:] = [m for m in self.motors if id(m.joint) not in dead_joint_ids]
        self.devices[:] = [d for d in self.devices if id(d.solid) not in gone_ids]
        self.robots[:] = [r for r in self.robots if id(r.solid) not in gone_ids]
        for s in gone:
            if s.parent is not None and id(s.parent) not in gone_ids and s in s.parent.children:
                s.parent.children.remove(s)
            self._solid_by_node.pop(id(s.node), None)
        for joint in dead_joints:
            self._joint_by_node.pop(id(joint.node), None)
            for p in joint.params:
                if p is not None:
                    self._joint_by_node.pop(id(p), None)
        self.solids[:] = [s for s in self.solids if id(s) not in gone_ids]
        self._geoms_changed()

    def bounding_object_changed(self, solid_node: Node) -> None:
        """``solid_node``'s boundingObject was imported or removed, or a node inside it was: its geoms are built
        again from the field, where the Solid is now (on its body if it has one), so contacts and ray sensors
        see the new shape from the next step on. Bodies near the old or new geoms are woken (one resting on a
        removed shape must fall)."""
        solid = self._solid_by_node.get(id(solid_node))
        if solid is None:
            return
        boxes = [self._aabb(g) for g in solid.geoms]
        self._drop_geoms(solid.geoms)
        self._create_geoms(solid, self.solid_world_pose(solid))
        boxes += [self._aabb(g) for g in solid.geoms]
        self._wake_near(boxes, solid.body)
        self._geoms_changed()

    def _drop_geoms(self, geoms: list[GeomRec]) -> None:
        for g in list(geoms):
            self._lib.dGeomDestroy(g.ptr)
            del self.geoms[g.ptr]
            g.solid.geoms.remove(g)
        self._plans.clear()  # cached pair plans name the destroyed geoms (ODE may reuse their addresses)

    def _wake_near(self, boxes: list[list[float]], body: BodyRec | None) -> None:
        woken = {body.index} if body is not None else set()
        for g in self.geoms.values():
            if g.body is None or g.body.index in woken or g.is_plane:
                continue
            other = self._aabb(g)
            if any(all(other[2 * k] <= box[2 * k + 1] + _WAKE_MARGIN and other[2 * k + 1] >= box[2 * k] - _WAKE_MARGIN
                       for k in range(3)) for box in boxes):  # fmt: skip
                woken.add(g.body.index)
        for index in woken:
            if not self.bodies[index].removed:
                self._wake_body(index)

    def live_bodies(self) -> list[BodyRec]:
        """The bodies still in the world (a removed Solid's body is kept, disabled, outside it)."""
        return [b for b in self.bodies if not b.removed]

    def _geoms_changed(self) -> None:
        self._prepare_step_lists()
        self.geometry_version += 1  # ray casters regroup their geoms
        self.extensions.pop("ray_targets", None)  # per-robot target lists (ranging) are rebuilt
