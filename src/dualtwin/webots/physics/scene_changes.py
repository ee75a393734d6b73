"""Nodes a supervisor adds to or removes from the scene while the simulation runs (``importMFNodeFromString``,
``importSFNodeFromString``, ``Node.remove``, ``removeMF``...), made to take part in the physics or leave it.

Webots builds the ODE objects of an imported node as it builds those of the world at load: every Solid of the
subtree gets its records, its bodies (Webots' mass rules and Solid merging), its geoms and its joints, so an
imported Solid with Physics falls, collides and is seen by ray sensors from the next step on; a Robot brings its
devices. A removed subtree takes its geoms, joints and bodies out of the world at once: nothing collides with
it, no ray hits it, and nothing stays jointed to it.

A subtree imported inside an existing Solid follows the load's rules too (§3.3): a Solid with Physics merges
into the body of a parent that has one (its mass is summed again, the parent stays where it is), or gets its
own body fixed to the nearest body above or to the world; a Solid without Physics brings body-less geoms. Its
removal takes its mass out of the body again. A Solid imported into a joint's empty ``endPoint`` (directly or
through a Slot pair) becomes that joint's endPoint as at load (§4.1): its own body if it has Physics, and the
ODE joint made between the parent's body and it, anchored where the parent is now; the joint's motor and
position sensor then act on it. Its removal leaves the joint (and its devices) without an endPoint. A
SolidReference imported there closes a loop as at load (§10) and its removal opens it again. A
boundingObject imported or removed on its own rebuilds its Solid's geoms and, as the mass of a Solid with
Physics comes from its boundingObject (§3.2), sums its body's mass again
(:meth:`SceneChanges.bounding_object_changed`). The same happens when a supervisor moves (or, a Transform,
scales) a frame inside a boundingObject: Webots moves the geoms to the new offset from the Solid at the next
step, and on a body the mass distribution follows. And when a supervisor edits a bounding ``Mesh``'s ``url``,
``name``, ``materialIndex`` or ``ccw``: its triangles are read again and the geoms built again from them (a Mesh
that could not be read at load gets its geom once it can be).

Removed bodies are disabled and detached from every joint rather than destroyed, so the per-body indices and
the live views into ODE memory that the stepping keeps stay valid; they are skipped by resets.
"""

from __future__ import annotations

from collections.abc import Iterable

from dualtwin.webots._math3 import Pose
from dualtwin.webots.nodes import Node, copy_value
from dualtwin.webots.physics.joint_changes import JointChanges
from dualtwin.webots.physics.records import (
    JOINT_TYPES,
    SOLID_TYPES,
    BodyRec,
    GeomRec,
    JointRec,
    SolidRec,
    field_or,
    is_solid,
)
from dualtwin.webots.solid_scale import scaled_local

__all__ = ["SceneChanges"]


class SceneChanges(JointChanges):
    """Run-time addition and removal of scene subtrees (see the module docstring)."""

    def can_add(self, ancestors: Iterable[Node]) -> bool:
        """Whether a node placed below ``ancestors`` (top-level first, its parent last) can join the physics:
        its nearest Solid above (if any) is in the physics, and no joint or Slot lies between them unless the
        node is in a joint's ``endPoint`` (through Slots), a joint that is in the physics."""
        chain = list(ancestors)
        at = self._parent_solid_at(chain)
        if at >= 0 and id(chain[at]) not in self._solid_by_node:
            return False
        between = chain[at + 1 :]
        joints = [i for i, n in enumerate(between) if n.type_name in JOINT_TYPES]
        if not joints:
            return not any(n.type_name == "Slot" for n in between)
        first = joints[0]
        return (first == len(between) - 1 - sum(n.type_name == "Slot" for n in between[first + 1 :])
                and id(between[first]) in self._joint_by_node)  # fmt: skip

    @staticmethod
    def _parent_solid_at(chain: list[Node]) -> int:
        return max((i for i, n in enumerate(chain) if n.type_name in SOLID_TYPES), default=-1)

    def _endpoint_of(self, chain: list[Node], top: Node) -> tuple[JointRec | None, Node | None]:
        """The joint whose ``endPoint`` holds ``top`` (directly or through Slots) and the Solid that ends up
        there, or (None, None) when ``top`` is not in an endPoint."""
        holder = top
        for node in reversed(chain[self._parent_solid_at(chain) + 1 :]):
            if node.type_name not in JOINT_TYPES and node.type_name != "Slot":
                break
            if field_or(node, "endPoint", None) is not holder:
                return None, None  # a joint's device or parameters field, not its endPoint
            if node.type_name in JOINT_TYPES:
                end: Node | None = top
                while isinstance(end, Node) and end.type_name == "Slot":
                    end = field_or(end, "endPoint", None)
                held = isinstance(end, Node) and (is_solid(end) or end.type_name == "SolidReference")
                return self._joint_by_node.get(id(node)), end if held else None
            holder = node
        return None, None

    def add_nodes(self, top: Node, ancestors: Iterable[Node] = ()) -> list[SolidRec]:
        """Build the ODE objects of ``top`` (just inserted below ``ancestors``, see :meth:`can_add`) as the
        load builds them, and return the new Solids' records. Geoms, bodies and joints exist when this returns.

        In a joint's empty ``endPoint`` the Solid becomes the joint's endPoint as at load: the joint's ODE joint
        is made (when the Solid has a body) from the parent's current pose, its zero at the joint's current
        position, which the Solid's translation and rotation describe (§4.1).

        Below an existing Solid the load's rules hold (§3.3): a Solid with Physics that is a plain child of a
        Solid with a body is merged into that body, whose mass, centre of mass and inertia are summed again
        (the root Solid stays where it is and keeps its velocity); one below a Solid without a body gets its
        own body, fixed to the nearest body above or to the world (static basis); a Solid without Physics
        has body-less geoms (inside a robot they follow it every step). Everything is placed where the parent
        Solid is now, not where it was at load."""
        self.scene_version += 1  # (the caller has put top in the tree)
        chain = list(ancestors)
        if top.type_name == "Damping":  # into a Physics node's or WorldInfo's damping field
            self._apply_damping(top, "")
            return []
        if top.type_name == "ContactProperties":  # into WorldInfo's contactProperties
            self.contact_properties_changed()
            return []
        if top.type_name == "Physics" and chain and chain[-1] is not None and is_solid(chain[-1]):
            self.physics_changed(chain[-1])  # a Physics imported into a Solid's empty physics field
            return []
        if chain and chain[-1].type_name in JOINT_TYPES and self._joint_part_added(chain[-1], top):
            return []  # a device or parameters node of the joint (physics/joint_changes.py)
        at = self._parent_solid_at(chain)
        parent = self._solid_by_node[id(chain[at])] if at >= 0 else None
        in_joint = any(n.type_name in JOINT_TYPES for n in chain[at + 1 :])
        joint, end = self._endpoint_of(chain, top) if in_joint else (None, None)
        if in_joint and (joint is None or end is None or joint.child is not None or joint.ptr):
            return []  # a device or parameters node, or nothing a joint can hold
        if joint is not None and end is not None and end.type_name == "SolidReference":
            joint.reference = end
            self._close_loop(joint, str(field_or(end, "solidName", "")))
            self._plans.clear()  # the two bodies are jointed now (no contacts between them)
            self._geoms_changed()
            return []
        frame, scale = Pose(), parent.scale if parent is not None else 1.0
        for node in chain[at + 1 :]:  # Pose/Transform chain above the node (Groups add nothing)
            if "translation" in node.fields and "rotation" in node.fields:
                frame, scale = frame * scaled_local(node, scale), self.factor_below(node, scale)
        n_solids, n_bodies, n_joints = len(self.solids), len(self.bodies), len(self.joints)
        n_robots, n_motors, n_loops = len(self.robots), len(self.motors), len(self._loops)
        robot = parent.robot if parent is not None else None
        if joint is not None and end is not None:
            joint.child = self._add_solid(end, joint.frame_rel, parent, robot, joint, joint.scale)
            self._at_joint_position(joint.child)
        else:
            self._walk_children([top], frame, parent, robot, scale)
        solids = self.solids[n_solids:]
        self._assign_bodies(solids)
        bodies = self.bodies[n_bodies:]
        for body in bodies:
            self._create_body(body)
            self._enabled.append(True)
            if parent is not None:
                self._place_where_it_is_now(body)
        grown = {id(s.body): s.body for s in solids if s.body is not None and s.body.index < n_bodies}
        for body in grown.values():
            self._remass(body)
        for solid in solids:
            self._create_geoms(solid, None if parent is None else self.solid_world_pose(solid))
        for new in ([joint] if joint is not None else []) + self.joints[n_joints:]:
            self._create_joint(new)
        for loop, name in self._loops[n_loops:]:
            self._close_loop(loop, name)
        if joint is not None:
            self._plans.clear()  # the endPoint's body is jointed to its parent's now (no contacts between them)
        self._create_fixed_joints(bodies)
        robots = self.robots[n_robots:]
        if parent is not None and parent.robot is not None:
            robots = [parent.robot, *robots]  # its new devices take their places in its device order
        self._collect_devices(solids, robots)
        for motor in self.motors[n_motors:]:
            motor.reset_state()
        self._geoms_changed()
        return solids

    def _at_joint_position(self, solid: SolidRec) -> None:
        """An endPoint imported into a joint that has moved since load: its translation and rotation give its
        pose at the joint's current position, while an endPoint's ``rel`` is kept at the joint's initial
        position (the kinematic motion, teleports and resets start from there)."""
        moved = self._kinematic_rel(solid) * solid.rel.inverse()  # initial position -> current one
        solid.rel = solid.load_rel = moved.inverse() * solid.rel

    def _place_where_it_is_now(self, body: BodyRec) -> None:
        """A new body below an existing Solid: at its Solid's current pose, and that pose is its load pose
        (a reset removes imported nodes anyway). An endPoint is where its joint's current position puts it
        (its ODE joint does not exist yet, so the joint's kinematic motion gives it)."""
        root = body.root
        world = (self.solid_world_pose(root.parent) if root.parent is not None else Pose()) * self._kinematic_rel(root)
        body.load_R = world.R
        body.load_pos = world.apply(body.com)
        self._place_body_at_load(body)

    def remove_nodes(self, top: Node) -> None:
        """Take every Solid of the subtree ``top`` out of the physics (no-op for nodes that have none)."""
        self.scene_version += 1  # (the caller has taken top out of the tree)
        if top.type_name == "Damping":  # out of a Physics node's or WorldInfo's damping field
            self._apply_damping(top, "")
            return
        if top.type_name == "ContactProperties":  # out of WorldInfo's contactProperties
            self.contact_properties_changed()
            return
        if top.type_name == "Physics":  # taken out of a Solid's physics field: that Solid has a body still
            for solid in [s for s in self.solids if s.body is not None and s in s.body.members
                          and not isinstance(s.node.fields.get("physics"), Node)]:  # fmt: skip
                self.physics_changed(solid.node)
            return
        ids = {id(n) for n in top.walk()}
        self._joint_parts_removed(ids)
        gone = [s for s in self.solids if id(s.node) in ids]
        reshaped = {id(g.solid): g.solid for g in self.geoms.values()
                    if g.source is not None and id(g.source) in ids and id(g.solid.node) not in ids}  # fmt: skip
        for solid in reshaped.values():  # a boundingObject (or a part of one) left a Solid that stays
            self.bounding_object_changed(solid.node)
        for joint in [j for j in self.joints if j.reference is not None and id(j.reference) in ids
                      and id(j.node) not in ids]:  # fmt: skip
            self._open_loop(joint)
        if not gone:
            self._geoms_changed()
            return
        gone_ids = {id(s) for s in gone}
        lib = self._lib
        dead_geoms = {g.ptr: g for s in gone for g in s.geoms}
        for ptr, geom in dead_geoms.items():
            self._destroy_geom(geom)
            del self.geoms[ptr]
        for s in gone:
            s.geoms.clear()
        self._plans.clear()  # cached pair plans name the destroyed geoms (ODE may reuse their addresses)
        shrunk = {id(s.body): s.body for s in gone
                  if s.body is not None and id(s.body.root) not in gone_ids and not s.body.removed}  # fmt: skip
        for body in shrunk.values():  # merged Solids leave a body that stays: its mass is summed again
            body.members[:] = [m for m in body.members if id(m) not in gone_ids]
            self._remass(body)
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
            self._detach_joint(joint)
        kept = [j for j in dead_joints if id(j.node) not in ids]  # an endPoint left a joint that stays
        for joint in kept:
            self._without_endpoint(joint)
        dead_joints = [j for j in dead_joints if id(j.node) in ids]
        for joint in dead_joints:
            if joint.parent is not None and joint in joint.parent.child_joints:
                joint.parent.child_joints.remove(joint)
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

    def _detach_joint(self, joint: JointRec) -> None:
        """Take a joint's ODE parts out of the world (detached, not destroyed, as for bodies)."""
        for ptr in (joint.ptr, joint.amotor, joint.spring, joint.spring2, joint.stop2):
            if ptr:
                self._lib.dJointAttach(ptr, None, None)
        for end in (joint.parent_body, joint.child_body):
            if end is not None and joint in end.joints:
                end.joints.remove(joint)

    def _open_loop(self, joint: JointRec) -> None:
        """The SolidReference endPoint of a joint closing a loop was removed: the loop opens."""
        for end in (joint.parent_body, joint.child_body):
            if end is not None:
                self._wake_body(end.index)  # (a body held still may have fallen asleep)
        body = joint.parent_body if joint.child_body is None else None  # jointed to the static environment...
        body = joint.child_body if joint.parent_body is None else body  # ...at either end
        self._detach_joint(joint)
        self._without_endpoint(joint)
        if body is not None:  # §2.3 rule 6 holds while another joint or a fixed joint holds it to the world
            body.attached_to_world = (body.fixed_joint != 0 and body.fixed_to is None) or any(
                j.parent_body is None or j.child_body is None for j in body.joints)
        self._plans.clear()  # the bodies it held together collide again

    @staticmethod
    def _without_endpoint(joint: JointRec) -> None:
        """A joint whose endPoint was removed (its ODE parts detached) stays in the scene with its devices,
        kinematic and holding nothing, until a new endPoint is imported (:meth:`add_nodes`)."""
        joint.reference = None
        joint.child = None
        joint.ptr = joint.amotor = joint.spring = joint.spring2 = joint.stop2 = 0
        joint.parent_body = joint.child_body = None
        joint.reverse = False
        joint.euler_ref = ()

    def physics_changed(self, solid_node: Node) -> None:
        """``solid_node`` gained or lost its Physics node (:class:`.physics_changes.PhysicsChanges`)."""
        raise NotImplementedError

    def _bounding_frame_changed(self, linked: list[Node]) -> bool:
        """A Pose or Transform inside boundingObjects moved (or, a Transform, was scaled), ``linked`` being it and
        its DEF/USE copies, which already hold the new value (:meth:`FrameEdits._apply_field`): the geoms of every
        Solid bounded by one of them are built again where the new frame puts them and their bodies' mass summed
        again (:meth:`bounding_object_changed`), as Webots moves the geoms at the next step. False when no
        boundingObject holds it."""
        bounded = self._bounded_by({id(n) for n in linked})
        for solid in bounded:
            self.bounding_object_changed(solid.node)
        return bool(bounded)

    def _apply_geometry(self, node: Node, name: str) -> bool:
        """A field of a ``Mesh`` changed (its ``url``, ``name``, ``materialIndex`` or ``ccw``, on it or on a
        DEF/USE copy): the file is read again, so the geoms of every Solid it bounds are built again
        (:meth:`bounding_object_changed`, the mass summed again), and drawn Meshes follow (the geometry version
        changes). Other geometries are resized in place (:class:`.mass_edits.MassEdits`)."""
        if node.type_name != "Mesh":
            return super()._apply_geometry(node, name)
        linked = self.linked_nodes(node)
        value = node.fields.get(name)
        for other in linked[1:]:
            other.fields[name] = copy_value(value)
        for solid in self._bounded_by({id(n) for n in linked}):
            self.bounding_object_changed(solid.node)
        self._geoms_changed()
        return True

    def bounding_object_changed(self, solid_node: Node) -> None:
        """``solid_node``'s boundingObject was imported or removed, or a node inside it was: its geoms are built
        again from the field, where the Solid is now (on its body if it has one), so contacts and ray sensors
        see the new shape from the next step on. Bodies near the old or new geoms are woken (one resting on a
        removed shape must fall). On a body, the mass is summed again (§3.2: a Physics node without an inertia
        matrix takes its mass distribution, its centre of mass and, from its density, its mass from the
        boundingObject; without one, the density's or mass's default): the Solid stays where it is, the body's
        origin moves to the new centre of mass."""
        solid = self._solid_by_node.get(id(solid_node))
        if solid is None:
            return
        boxes = [self._aabb(g) for g in solid.geoms]
        self._drop_geoms(solid.geoms)
        if solid.body is not None and not solid.body.removed:
            self._remass(solid.body)
        self._create_geoms(solid, self.solid_world_pose(solid))
        boxes += [self._aabb(g) for g in solid.geoms]
        self._wake_near(boxes, solid.body)
        self._geoms_changed()

    def _drop_geoms(self, geoms: list[GeomRec]) -> None:
        for g in list(geoms):
            self._destroy_geom(g)
            del self.geoms[g.ptr]
            g.solid.geoms.remove(g)
        self._plans.clear()  # cached pair plans name the destroyed geoms (ODE may reuse their addresses)

    def _wake_near(self, boxes: list[list[float]], body: BodyRec | None) -> None:
        """Wake ``body`` and every body with a geom within reach of one of ``boxes`` (:meth:`_wake_reaching`)."""
        self._wake_reaching([tuple(box) for box in boxes])
        if body is not None and not body.removed:
            self._wake_body(body.index)

    def live_bodies(self) -> list[BodyRec]:
        """The bodies still in the world (a removed Solid's body is kept, disabled, outside it)."""
        return [b for b in self.bodies if not b.removed]

    def _geoms_changed(self) -> None:
        self._prepare_step_lists()
        self.geometry_version += 1  # ray casters regroup their geoms
        self.extensions.pop("ray_targets", None)  # per-robot target lists (ranging) are rebuilt
