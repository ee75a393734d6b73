"""A Solid's mass, centre of mass and inertia computed again while the simulation runs, when what they come from
changes: a supervisor's edit of a ``Physics`` field (``mass``, ``density``, ``centerOfMass``,
``inertiaMatrix``), of a boundingObject primitive's dimensions (``Box.size``, ``Sphere.radius``,
``Cylinder``/``Capsule`` ``radius``/``height``, a mesh's points), or a boundingObject imported or removed
(:mod:`.scene_changes`).

Webots recomputes a Solid's mass properties whenever its Physics fields or its bounding geometry change
(``WbSolid::updateMass`` is connected to both), with the rules it applies at load (§3.2, :mod:`..mass_rules`):
with ``density`` (``mass`` -1) the mass follows the shape's volume, with ``mass`` given the mass stays and the
inertia follows the shape, an ``inertiaMatrix`` (with ``mass`` and ``centerOfMass``) replaces it. Here the
body's mass is summed again from its Solids' current fields (:meth:`MassEdits._remass`): the Solids stay where
they are, the body's origin (ODE's centre of mass) moves to the new centre of mass with that point's velocity,
and the joints on the body are anchored again where the Solids are now. A DEF Physics node shared by USE is
one node in Webots: an edit reaches every Solid using it.

A body's damping (§1.4: its Solids' ``Damping`` nodes weighted by volume, else the world's
``WorldInfo.defaultDamping``) is set again in the same way when a Damping node's field is edited or a Damping
node comes or goes (:meth:`MassEdits._refresh_damping`), as Webots re-applies it to ODE at once.
"""

from __future__ import annotations

from ctypes import byref

from dualtwin.webots import _math3 as m3
from dualtwin.webots._math3 import Pose
from dualtwin.webots.mass_rules import rot_matrix
from dualtwin.webots.nodes import Node, copy_value
from dualtwin.webots.physics.geometry_edits import GeometryEdits
from dualtwin.webots.physics.records import BodyRec, damping_per_step
from dualtwin.webots.physics.records import field_or as _f

__all__ = ["MASS_FIELDS", "MassEdits"]

#: The Physics fields a Solid's mass properties come from (§3.2).
MASS_FIELDS = frozenset({"mass", "density", "centerOfMass", "inertiaMatrix"})


class MassEdits(GeometryEdits):
    """Mass properties following their sources (see the module docstring)."""

    def _apply_physics_mass(self, node: Node, name: str) -> bool:
        """A ``Physics`` mass field was edited: copy it to the node's DEF/USE copies and sum the mass of every
        body whose Solids use one of them again. False when no body uses the node."""
        linked = self.linked_nodes(node)
        value = node.fields.get(name)
        for other in linked[1:]:
            other.fields[name] = copy_value(value)
        ids = {id(n) for n in linked}
        bodies = [b for b in self.bodies if not b.removed
                  and any(id(m.node.fields.get("physics")) in ids for m in b.members)]  # fmt: skip
        for body in bodies:
            self._remass(body)
        return bool(bodies)

    def _apply_geometry(self, node: Node, name: str) -> bool:
        """Resize the geoms (:class:`GeometryEdits`), then sum again the mass of every body one of whose Solids
        has the edited node (or a DEF/USE copy of it) in its boundingObject."""
        applied = super()._apply_geometry(node, name)
        bounded = {id(s) for s in self._bounded_by({id(n) for n in self.linked_nodes(node)})}
        for body in self.bodies:
            if not body.removed and any(id(member) in bounded for member in body.members):
                self._remass(body)
        return applied

    def _apply_damping(self, node: Node, name: str) -> bool:
        """A ``Damping`` node's ``linear`` or ``angular`` was edited (or a Damping node came or went): copy the
        value to its DEF/USE copies and set the damping of the world and of every body again (§1.4)."""
        if name:
            value = node.fields.get(name)
            for other in self.linked_nodes(node)[1:]:
                other.fields[name] = copy_value(value)
        self._refresh_damping()
        return True

    def _refresh_damping(self) -> None:
        """Set the world's damping from ``WorldInfo.defaultDamping`` and every body's from its Solids' Damping
        nodes (§1.4, as the load does): ODE copies the world's values into a body only when told
        (``dBodySetDampingDefaults``), so the bodies falling back to them are set again too."""
        info = self.world.world_info()
        default = info.fields.get("defaultDamping") if info is not None else None
        self.world_damping = (
            (damping_per_step(float(_f(default, "linear", 0.2)), self.dt),
             damping_per_step(float(_f(default, "angular", 0.2)), self.dt))
            if isinstance(default, Node) else (0.0, 0.0)
        )  # fmt: skip
        self._lib.dWorldSetDamping(self._world, *self.world_damping)
        for body in self.bodies:
            if not body.removed:
                weights = [(m.volume, _f(m.node.fields.get("physics"), "damping", None)) for m in body.members]
                self._set_damping(body, weights)

    def _remass(self, body: BodyRec) -> None:
        """Sum the mass of a body whose merged Solids or their mass sources changed (§3.2, §3.3) and set it: the
        root Solid frame stays where it is, the body origin moves to the new centre of mass with the velocity
        of that point, and every geom on the body keeps its place in the world."""
        lib = self._lib
        now, load = body.pose(), Pose(body.load_R, m3.sub(body.load_pos, m3.mat_vec(body.load_R, body.com)))
        old_com_world = now.apply(body.com)
        lvel, avel = tuple(body.lvel[:3]), tuple(body.avel[:3])
        old_com = body.com
        total, weights = self._centred_mass(body)
        lib.dBodySetMass(body.ptr, byref(total))
        new_com_world = now.apply(body.com)
        lib.dBodySetPosition(body.ptr, *new_com_world)
        v = m3.add(lvel, m3.cross(avel, m3.sub(new_com_world, old_com_world)))
        lib.dBodySetLinearVel(body.ptr, *v)
        body.load_pos = load.apply(body.com)  # a reset places the root Solid where it was at load
        self._set_damping(body, weights)
        for g in (g for m in body.members for g in m.geoms if g.body is body):
            world = self.solid_world_pose(g.solid) * g.local
            lib.dGeomSetOffsetWorldPosition(g.ptr, *world.t)
            lib.dGeomSetOffsetWorldRotation(g.ptr, rot_matrix(world.R))
        if body.com != old_com:
            self._rejoin(body)
        self._wake_body(body.index)

    def _rejoin(self, body: BodyRec) -> None:
        """ODE keeps a joint's anchors and a fixed joint's offset relative to each body's origin, the centre of
        mass: once that moved, the joints on the body are set again from where the Solids are now (their ODE
        zero re-based on the current positions, as a teleport does, §6)."""
        for joint in list(body.joints):
            if joint.ptr:
                self._anchor_joint(joint)
                for i in range(len(joint.params)):
                    self._set_stops(joint, i)
                self.rebuild_springs(joint)
        for other in self.bodies:
            if other.fixed_joint and not other.removed and (other is body or other.fixed_to is body):
                self._lib.dJointSetFixed(other.fixed_joint)
