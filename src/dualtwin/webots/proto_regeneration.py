"""Regenerating a procedural PROTO instance when a field its template reads changes, as Webots does.

A procedural PROTO (``# template language: javascript``) computes its body from its fields, so a value its
template reads cannot simply be copied along ``IS`` links: Webots expands the instance again from its interface
fields and its current pose and puts the new node in the old one's place (``WbTemplateManager``). Here:

* the instance is written as Webots saves it (PROTO name, interface fields with the new value, current pose),
  expanded again like an imported node, and its physics rebuilt: new geometry, mass and contacts act from the
  next step (the body starts at rest);
* the scene-tree node object is kept (its content replaced), so it keeps its place in its parent, its DEF, its
  unique id and every handle a supervisor holds on it; handles on nodes *inside* it name the old body, as in
  Webots, where the instance's internal nodes are new;
* ``simulationReset`` restores the load-time content with the other fields (the reset puts every field back)
  and rebuilds its physics;
* an instance that holds a Robot or is part of one is not regenerated (the robot's devices, and in Webots its
  controller, would have to start again with it): the caller says so and follows the ``IS`` links only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.nodes import path_to_node
from dualtwin.webots.physics import Simulation
from dualtwin.webots.physics.records import is_robot
from dualtwin.webots.schema import SOLID_TYPES

__all__ = ["join_physics", "regenerate"]


def join_physics(sim: Simulation, top: SceneNode) -> str | None:
    """Build the physics of a subtree now in the scene tree: a Solid subtree joins the bodies, a part of a
    bounding object rebuilds its Solid's geoms. Returns where it is when it has Solids but nothing there for them
    to join (a Slot with no joint, a parent outside the physics), else None."""
    chain = path_to_node(sim.world.nodes, top)
    ancestors = chain[:-1] if chain is not None else []
    owner = next((n for n in reversed(ancestors) if n.type_name in SOLID_TYPES), None)
    bounds = owner.fields.get("boundingObject") if owner is not None else None
    if owner is not None and isinstance(bounds, SceneNode) and any(n is top for n in bounds.walk()):
        sim.bounding_object_changed(owner)  # its shape changed: its geoms are built again
    elif chain is not None and sim.can_add(ancestors):
        sim.add_nodes(top, ancestors)
    elif any(n.type_name in SOLID_TYPES for n in top.walk()):
        return " > ".join(n.type_name for n in ancestors) or "the scene root"
    return None


@dataclass
class _Regenerated:
    """An instance regenerated during the run: its load-time content, and its nodes now."""

    node: SceneNode
    original: dict[str, Any]  # vars() of the node at load
    inner: list[SceneNode]  # the nodes of its current content below it (their Solids are in the physics)


def regenerate(sim: Simulation, node: SceneNode, text: str, parse: Callable[[str], list[SceneNode]],
               number: Callable[[list[SceneNode]], None]) -> bool:
    """Replace ``node``'s content by the expansion of ``text`` (the instance as saved, with its new field value)
    and rebuild its physics. ``parse`` turns VRML text into scene nodes like an import; ``number`` gives new
    nodes their unique ids. False, with nothing changed, for an instance that holds a Robot or is part of one, or
    text that does not expand to one node (the caller then warns)."""
    chain = path_to_node(sim.world.nodes, node) or [node]
    if any(is_robot(n) for n in node.walk()) or any(is_robot(n) for n in chain):
        return False  # a robot's devices (and Webots: its controller) would have to start again with it
    fresh = parse(text)
    if len(fresh) != 1:
        return False
    records = _registry(sim)
    record = records.get(id(node))
    if record is None:
        record = records[id(node)] = _Regenerated(node, dict(vars(node)), [])
    _remove(sim, node, record)
    vars(node).update(vars(fresh[0]))  # the same object: handles and the parent's field still hold it
    record.inner = [n for n in node.walk() if n is not node]
    number([node])
    sim.scene_version += 1  # its nodes are new (join_physics may build nothing of them)
    join_physics(sim, node)
    return True


def _remove(sim: Simulation, node: SceneNode, record: _Regenerated) -> None:
    """Take the instance's current Solids out of the physics: its own and those of its current content, which
    after a reset may no longer be below it in the tree."""
    if record.inner:
        sim.remove_nodes(SceneNode("Group", {"children": record.inner}))
    if path_to_node(sim.world.nodes, node) is not None:
        sim.remove_nodes(node)


def _registry(sim: Simulation) -> dict[int, _Regenerated]:
    records: dict[int, _Regenerated] | None = sim.extensions.get("regenerated_protos")
    if records is None:
        records = sim.extensions["regenerated_protos"] = {}
        sim.reset_hooks.append(lambda: _restore(sim))
    return records


def _restore(sim: Simulation) -> None:
    """After ``simulationReset`` restored every field: each regenerated instance gets its load-time content back
    (with the restored field values) and its physics is built from it again."""
    records: dict[int, _Regenerated] = sim.extensions["regenerated_protos"]
    removed = sim.extensions.get("removed_nodes", [])  # a supervisor removed them: they stay out (scene_api)
    for record in records.values():
        node = record.node
        fields, interface = dict(node.fields), None if node.proto_fields is None else dict(node.proto_fields)
        _remove(sim, node, record)
        vars(node).update(record.original)
        node.fields.clear()
        node.fields.update(fields)  # the reset wrote the load values into the regenerated node's dicts
        if interface is not None and node.proto_fields is not None:
            node.proto_fields.clear()
            node.proto_fields.update(interface)
        if not any(node is n for n in removed):
            join_physics(sim, node)
    records.clear()
