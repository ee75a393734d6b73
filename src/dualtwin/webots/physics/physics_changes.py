"""A Physics node a supervisor imports into a Solid that has none, or removes from one, while the simulation runs.

Webots edits the one Solid: with Physics it gets a body by the load's rules (§3.3: merged into the body of a
parent that has one, its mass summed again; or a body of its own, falling from where it is, fixed to the nearest
body above when it is a plain child of a Solid without one); without, it becomes static where it is (or leaves
its parent's body, whose mass is summed again). Everything else goes on as it was:

* the Solids below it keep their pose and their motion: a jointed child body keeps its velocity and its joint
  its position (only what it is jointed to changed), a child merged into the Solid's body moves with it;
* inside a Robot, its devices (motors, sensors, the Solid devices of the subtree, the Robot itself) are the
  same devices: a controller's handles keep working, with their commands and settings (a motor's target and
  available torque, a brake's damping, the sensors' sampling), as do the modules simulating the Solid devices
  (rays, cameras...);
* a reset puts the Solids and joints back where they were at load.

The subtree's ODE objects are built again by the load's rules (:meth:`SceneChanges.remove_nodes` then
:meth:`SceneChanges.add_nodes`), where everything is now; the records that the rest of the program holds
(Solids, joints, motors, sensors, brakes, devices, robots, attachments) are kept: each old record takes the
new one's place, with the new one's structure (bodies, ODE joints) and its own state
(:meth:`PhysicsChanges._keep_records`).
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.nodes import Node, path_to_node
from dualtwin.webots.physics.records import (
    AttachmentRec,
    BodyRec,
    BrakeRec,
    DeviceRec,
    GeomRec,
    JointRec,
    MotorRec,
    PositionSensorRec,
    RobotRec,
    SolidRec,
)
from dualtwin.webots.physics.scene_changes import SceneChanges

__all__ = ["PhysicsChanges"]

#: The fields an old record takes from the new one built in its place (the structure); it keeps the others
#: (its state). A Solid's and a body's records are all structure; a joint keeps its load position (resets).
_FROM_NEW: dict[type, frozenset[str] | None] = {
    SolidRec: None,
    JointRec: frozenset(JointRec.__dataclass_fields__) - {"initial_positions"},
    MotorRec: frozenset({"joint", "sensor", "brake", "torque_params_set"}),
    PositionSensorRec: frozenset({"joint"}),
    BrakeRec: frozenset({"joint"}),
    DeviceRec: frozenset({"solid"}),
    RobotRec: frozenset({"solid", "devices"}),
    AttachmentRec: frozenset({"solid", "robot", "frame_rel"}),
}
_RECORDS = (SolidRec, JointRec, MotorRec, PositionSensorRec, BrakeRec, DeviceRec, RobotRec, AttachmentRec,
            BodyRec, GeomRec)

_Motion = tuple[m3.Vec3, m3.Vec3, m3.Vec3]  # a Solid's origin in the world, its velocity, its spin


class PhysicsChanges(SceneChanges):
    """A Physics node imported into or removed from a Solid at run time (see the module docstring)."""

    def physics_changed(self, solid_node: Node) -> None:
        """``solid_node`` gained or lost its Physics node: its subtree's bodies, geoms and joints are built
        again where they are now, by the load's rules, keeping the records, motions and joint positions (the
        module docstring)."""
        solid = self._solid_by_node.get(id(solid_node))
        if solid is None or isinstance(solid_node.fields.get("physics"), Node) == (solid.body is not None):
            return
        chain = path_to_node(self.world.nodes, solid_node)
        if chain is None:
            return
        subtree = solid.subtree()
        inside = {id(s) for s in subtree}
        joints = [j for j in self.joints if (j.parent is not None and id(j.parent) in inside)
                  or (j.child is not None and id(j.child) in inside)]  # fmt: skip
        old = self._records_of(subtree, joints)
        motions = {id(s.node): self._motion(s) for s in subtree if s is not solid}
        # Before the first step, and during a reset, the fields hold where everything is (at load); after it,
        # the fields of moving Solids are only refreshed lazily: they are set to where the Solids are now, and
        # the rebuilt Solids and bodies keep their load poses (a reset puts them back there).
        running = self.step_count > 0
        if running:
            for s in subtree:
                local = self.solid_local_pose(s)
                s.node.fields["translation"] = local.t
                s.node.fields["rotation"] = m3.axis_angle_from_mat(local.R)
            for joint in joints:
                if joint.parent is not None and id(joint.parent) in inside:
                    for p, position in zip(joint.params, joint.positions, strict=False):
                        if p is not None:
                            p.fields["position"] = position
        load_rels = {id(s.node): s.load_rel for s in subtree}
        self.remove_nodes(solid_node)
        rebuilt = self.add_nodes(solid_node, chain[:-1])
        if running:
            for s in rebuilt:
                s.load_rel = load_rels.get(id(s.node), s.load_rel)
            for body in {id(s.body): s.body for s in rebuilt if s.body is not None and s.body.root is s}.values():
                world = self.world_pose_at_load(body.root)
                body.load_R, body.load_pos = world.R, world.apply(body.com)
        self._keep_records(old)
        self._keep_motions(rebuilt, motions)

    def _records_of(self, subtree: list[SolidRec], joints: list[JointRec]) -> dict[tuple[type, int], Any]:
        """The records of a subtree about to be built again, by their type and node."""
        inside = {id(s) for s in subtree}
        found: list[Any] = [*subtree, *joints]
        for joint in joints:
            found += [d for group in (joint.motors, joint.sensors, joint.brakes) for d in group if d is not None]
        found += [d for d in self.devices if id(d.solid) in inside]
        found += [r for r in self.robots if id(r.solid) in inside]
        found += [a for a in self.attachments if a.solid is not None and id(a.solid) in inside]
        return {(type(r), id(r.node)): r for r in found}

    def _keep_records(self, old: dict[tuple[type, int], Any]) -> None:
        """Each old record takes the place of the new one built for its node (:data:`_FROM_NEW`), so that what
        holds the old one (a controller's device handles, the device modules) goes on with the new physics."""
        everything = self._all_records()
        old_joints = {id(j): (list(j.positions), j.ptr) for j in old.values() if isinstance(j, JointRec)}
        swap: dict[int, Any] = {}
        for new in everything:
            was = old.get((type(new), id(getattr(new, "node", None))))
            if was is None or was is new:
                continue
            structure = _FROM_NEW[type(new)]
            kept = {} if structure is None else {k: v for k, v in vars(was).items() if k not in structure}
            vars(was).update(vars(new))
            vars(was).update(kept)
            swap[id(new)] = was
        if not swap:
            return
        for rec in [*everything, *swap.values()]:
            for key, value in vars(rec).items():
                if isinstance(value, list):
                    value[:] = [swap.get(id(v), v) for v in value]
                elif isinstance(value, dict):
                    for k, v in value.items():
                        value[k] = swap.get(id(v), v)
                elif id(value) in swap:
                    setattr(rec, key, swap[id(value)])
        for records in (self.solids, self.joints, self.motors, self.devices, self.robots, self.attachments):
            unique: dict[int, Any] = {}
            for r in records:
                r = swap.get(id(r), r)
                unique.setdefault(id(r), r)
            records[:] = list(unique.values())  # (the attachments built again are the old ones now)
        for table in (self._solid_by_node, self._joint_by_node):
            for k, v in table.items():
                table[k] = swap.get(id(v), v)
        self._loops[:] = [(swap.get(id(j), j), name) for j, name in self._loops]
        for joint in self.joints:
            if any(b is not None and b.damping for b in joint.brakes):
                self.rebuild_springs(joint)  # a brake's damping set by its controller acts again
        for joint in (j for j in swap.values() if isinstance(j, JointRec)):
            self._joint_kept(joint, *old_joints[id(joint)])
        self._prepare_step_lists()

    def _joint_kept(self, joint: JointRec, positions: list[float], old_ptr: int) -> None:
        """A joint built again below the edited Solid reads on from where it was (its kept load position makes
        resets right): with an ODE joint, whose zero is where it is now, its offsets are those positions (and the
        torque feedback buffer of an enabled motor feedback moves to it); without one, its endPoint (placed where
        it is now) is re-based so that the motion from the load position to those positions leaves it there."""
        joint.positions[:] = positions
        feedback = self._lib.dJointGetFeedback(old_ptr) if old_ptr else None
        if feedback and joint.ptr:
            self._lib.dJointSetFeedback(joint.ptr, feedback)
        if joint.ptr:
            joint.offsets = list(positions)
            self._read_joint(joint, predict=False)
            return
        child = joint.child
        if child is not None:
            motion = self._kinematic_rel(child) * child.rel.inverse()
            child.rel = motion.inverse() * child.rel

    def _all_records(self) -> list[Any]:
        seen: dict[int, Any] = {}
        stack: list[Any] = [*self.solids, *self.bodies, *self.joints, *self.motors, *self.devices, *self.robots,
                            *self.attachments, *self.geoms.values()]
        while stack:
            rec = stack.pop()
            if id(rec) in seen:
                continue
            seen[id(rec)] = rec
            for value in vars(rec).values():
                items = value if isinstance(value, list) else value.values() if isinstance(value, dict) else [value]
                stack.extend(v for v in items if isinstance(v, _RECORDS) and id(v) not in seen)
        return list(seen.values())

    def _motion(self, solid: SolidRec) -> _Motion:
        """Where a Solid's origin is, its velocity and the spin of its body (zero without one)."""
        origin = self.solid_world_pose(solid).t
        body = solid.body
        if body is None or body.removed:
            return origin, m3.ZERO, m3.ZERO
        spin = (body.avel[0], body.avel[1], body.avel[2])
        com = (body.pos[0], body.pos[1], body.pos[2])
        velocity = m3.add((body.lvel[0], body.lvel[1], body.lvel[2]), m3.cross(spin, m3.sub(origin, com)))
        return origin, velocity, spin

    def _keep_motions(self, rebuilt: list[SolidRec], motions: dict[int, _Motion]) -> None:
        """The bodies built again for the Solids below the edited one move on as their Solids moved before
        (the edited Solid itself starts from rest, as Webots' new body does, or becomes static)."""
        lib = self._lib
        for node in (s.node for s in rebuilt):
            solid = self._solid_by_node.get(id(node))  # (the kept record)
            body = solid.body if solid is not None else None
            motion = motions.get(id(node))
            if body is None or body.root is not solid or motion is None:
                continue
            origin, velocity, spin = motion
            com = (body.pos[0], body.pos[1], body.pos[2])
            lib.dBodySetLinearVel(body.ptr, *m3.add(velocity, m3.cross(spin, m3.sub(com, origin))))
            lib.dBodySetAngularVel(body.ptr, *spin)
