"""``Node.saveState`` / ``Node.loadState``: a snapshot of a node's subtree and its restore.

A state is the subtree's field values, its Solids' poses and body velocities and its joints' positions. Webots saves
a state field by field and restores it as field changes (the state ``"__init__"`` is the one at load, the state
``simulationReset`` restores, §6), so a restored field acts as a supervisor's write of it would: a motor's
``maxVelocity``, a DistanceSensor's ``lookupTable``, an Emitter's ``channel`` written since the save are taken back by
the motor and the devices, not only by the field. Here each restored value that differs from the current one goes
through ``Simulation.field_changed`` (physics and the devices' edit stamps), except the poses and joint positions,
which are queued teleports as a write of them is.

The nodes of the subtree stay the nodes: node-valued fields (children, endPoint, device...) are not replaced by
copies of the saved nodes (the physics and the devices know the nodes themselves; a copy would be a stranger to
them), each saved node's own values being restored instead. Nodes added since the save keep their values.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.nodes import Node, copy_value, values_equal
from dualtwin.webots.physics import Simulation, SolidRec
from dualtwin.webots.schema import JOINT_PARAMETER_TYPES

__all__ = ["load_state", "save_state"]

_KEY = "node_states"

#: what a state holds: each node's values, each moving Solid's (record, local pose, velocity or None), each joint's
#: (record, positions)
State = tuple[list[tuple[Node, dict[str, Any]]], list[tuple[SolidRec, m3.Pose, Any]], list[tuple[Any, list[float]]]]


def _states(sim: Simulation) -> dict[tuple[int, str], State]:
    states: dict[tuple[int, str], State] | None = sim.extensions.get(_KEY)
    if states is None:
        states = sim.extensions[_KEY] = {}
    return states


def save_state(sim: Simulation, top: Node, name: str) -> None:
    """Remember ``top``'s subtree under ``name``: its nodes' (non-node) field values, its Solids' poses and body
    velocities, its joints' positions."""
    values = [(n, {k: copy_value(v) for k, v in n.fields.items() if not _holds_nodes(v)}) for n in top.walk()]
    motion = []
    for n in top.walk():
        solid = sim.solid_for(n)
        if solid is not None:
            moving = solid.body is not None and solid.body.root is solid
            motion.append((solid, sim.solid_local_pose(solid), sim.solid_velocity(solid) if moving else None))
    joints = [(j, list(j.positions)) for n in top.walk() if (j := sim.joint_for(n)) is not None]
    _states(sim)[(id(top), name)] = (values, motion, joints)


def load_state(sim: Simulation, top: Node, name: str) -> str | None:
    """Restore the state ``name`` of ``top``'s subtree, its poses and joint positions at the next step. Returns
    ``"saved"``, or ``"load"`` for ``"__init__"`` never saved (the load's state; the caller resets the subtree's
    physics), or None when there is no such state."""
    saved = _states(sim).get((id(top), name))
    if saved is None and name == "__init__":
        _restore_values(sim, [(n, load) for n in top.walk() if (load := sim.load_fields(n)) is not None])
        for n in top.walk():
            solid = sim.solid_for(n)
            if solid is not None and _moves_by_pose(solid):
                rotation = m3.axis_angle_from_mat(solid.load_rel.R)  # (the translation in the field's units)
                sim.queue_set_pose(solid, m3.scale(solid.load_rel.t, 1.0 / solid.scale), rotation)
            joint = sim.joint_for(n)
            if joint is not None:
                for axis, initial in enumerate(joint.initial_positions):
                    sim.queue_set_joint_position(joint, axis, initial)
        return "load"
    if saved is None:
        return None
    values, motion, joints = saved
    _restore_values(sim, values)  # (first: a restored velocity field must not override the saved body velocity)
    for solid, local, velocity in motion:
        if _moves_by_pose(solid):
            sim.queue_set_pose(solid, tuple(local.t), m3.axis_angle_from_mat(local.R))
        if velocity is not None:
            sim.set_body_velocity(solid, list(velocity))
    for joint, positions in joints:
        for axis, position in enumerate(positions):
            sim.queue_set_joint_position(joint, axis, position)
    return "saved"


def _restore_values(sim: Simulation, saved: list[tuple[Node, dict[str, Any]]]) -> None:
    """Put back each saved value that differs from the node's current one, as a field change (see the module
    docstring); node-valued fields keep their nodes."""
    for node, values in saved:
        for name, value in values.items():
            now = node.fields.get(name)
            if _holds_nodes(value) or _holds_nodes(now) or values_equal(value, now):
                continue
            node.fields[name] = copy_value(value)
            if not _restored_by_teleport(sim, node, name):
                sim.field_changed(node, name)


def _restored_by_teleport(sim: Simulation, node: Node, name: str) -> bool:
    """Whether the state restores this field through a queued teleport (a moving Solid's pose, a joint's position)
    rather than as a field change."""
    if name in ("translation", "rotation"):
        solid = sim.solid_for(node)
        return solid is not None and (_moves_by_pose(solid) or solid.joint is not None)
    return name == "position" and node.type_name in JOINT_PARAMETER_TYPES and sim.joint_for(node) is not None


def _moves_by_pose(solid: SolidRec) -> bool:
    """A Solid placed by its own pose: not a joint's endPoint (its joint's positions place it) nor merged into the
    body of a Solid above it (its restored fields give it its place in that body, as after a reset)."""
    body = solid.body
    return solid.joint is None and (body is None or body.root is solid or body.removed)


def _holds_nodes(value: Any) -> bool:
    return isinstance(value, Node) or (isinstance(value, list) and any(isinstance(v, Node) for v in value))
