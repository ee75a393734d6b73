"""Where an edit of a PROTO instance's interface field goes: the internal fields linked to it by ``IS``.

Webots propagates a PROTO field's value to every field of its body written ``<field> IS <protoField>``,
through nested PROTO instances whose own interface fields are ``IS`` the outer one. The expansion
(:mod:`.protos`) records those links on the nodes; this module follows them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from dualtwin.webots.nodes import Node

__all__ = ["feeds_template", "insert_linked_nodes", "linked_fields", "remove_linked_nodes"]


def _reached(root: Node, name: str) -> Iterator[tuple[Node, tuple[int, str], list[tuple[int, str]]]]:
    """Every node of ``root``'s body that ``root``'s field ``name`` reaches, with the ``(instance, field)`` it
    is reached as there and the ``(inner instance, inner field)`` of each nested instance's link that carries
    it further in (followed too). Nothing when ``root`` is not a PROTO instance."""
    if root.proto_instance is None:
        return
    pending = [(root, root.proto_instance, name)]
    while pending:
        top, instance, field = pending.pop()
        for node in top.walk():
            inward = [(inner, inner_field) for outer, outer_field, inner, inner_field in node.instance_links
                      if (outer, outer_field) == (instance, field)]
            yield node, (instance, field), inward
            pending.extend((node, inner, inner_field) for inner, inner_field in inward)


def linked_fields(root: Node, name: str) -> tuple[list[tuple[Node, str]], list[tuple[Node, str]]]:
    """The base-node fields and the nested instances' interface fields that ``IS`` ``root``'s field ``name``.

    Returns ``(base, interfaces)``: ``base`` are ``(node, field)`` pairs of ``node.fields`` to update,
    ``interfaces`` are ``(nested root, field)`` pairs of ``proto_fields`` to update (the nested instance
    whose expanded root is also this PROTO's root, a derived PROTO, keeps no interface values of its own).
    Empty when ``root`` is not a PROTO instance.
    """
    base: list[tuple[Node, str]] = []
    interfaces: list[tuple[Node, str]] = []
    for node, link, inward in _reached(root, name):
        base.extend((node, f) for f, is_link in node.is_links.items() if is_link == link)
        if node.proto_fields is not None:
            interfaces.extend((node, inner_field) for inner, inner_field in inward if node.proto_instance == inner)
    return base, interfaces


def feeds_template(root: Node, name: str) -> bool:
    """Whether a procedural PROTO's template reads ``root``'s interface field ``name``: its own template, or that
    of an instance in its body (or the PROTO it derives from) that the field reaches through ``IS`` links. Such
    an edit makes Webots regenerate the instance."""
    if root.proto_instance is None:
        return False
    return name in root.template_fields or any(
        inner_field in node.template_fields for node, _, inward in _reached(root, name) for _, inner_field in inward)


def insert_linked_nodes(root: Node, name: str, at: int | None, nodes: list[Node]) -> list[Node]:
    """Put copies of ``nodes``, just added at index ``at`` of ``root``'s node-valued interface field ``name``
    (``at`` None: an SFNode field), at the same place of every field ``IS`` that field, as Webots' IS link gives
    the PROTO body its own copy of the value. Returns the copies now in the scene tree (the base nodes' fields):
    they, not the interface's nodes, are what the physics must take in."""
    base, interfaces = linked_fields(root, name)
    for node, field in interfaces:
        assert node.proto_fields is not None
        _insert(node.proto_fields, field, at, [n.copy() for n in nodes])
    placed: list[Node] = []
    for node, field in base:
        copies = [n.copy() for n in nodes]
        _insert(node.fields, field, at, copies)
        placed.extend(copies)
    return placed


def remove_linked_nodes(root: Node, name: str, at: int | None) -> list[Node]:
    """Take the node at index ``at`` (None: the node of an SFNode field) out of every field ``IS`` ``root``'s
    interface field ``name``, which holds a copy of it in the same place. Returns those removed from the scene
    tree (the base nodes' fields): the physics must let them go."""
    base, interfaces = linked_fields(root, name)
    for node, field in interfaces:
        assert node.proto_fields is not None
        _pop(node.proto_fields, field, at)
    return [n for node, field in base if (n := _pop(node.fields, field, at)) is not None]


def _insert(values: dict[str, Any], field: str, at: int | None, nodes: list[Node]) -> None:
    if at is None:
        values[field] = nodes[0] if nodes else None
        return
    items = values.get(field)
    if not isinstance(items, list):
        items = values[field] = []
    items[at:at] = nodes


def _pop(values: dict[str, Any], field: str, at: int | None) -> Node | None:
    if at is None:
        item, values[field] = values.get(field), None
        return item if isinstance(item, Node) else None
    items = values.get(field)
    if not isinstance(items, list) or not 0 <= at < len(items):
        return None
    item = items.pop(at)
    return item if isinstance(item, Node) else None
