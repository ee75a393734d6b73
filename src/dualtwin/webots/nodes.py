"""The in-memory scene tree shared by the Webots parser, the ODE builder and the converter.

Values use plain Python types so every consumer can read them without knowing the parser:

=============  ==========================================
VRML type      Python value
=============  ==========================================
SFBool         ``bool``
SFInt32        ``int``
SFFloat        ``float``
SFVec2f        ``tuple[float, float]``
SFVec3f        ``tuple[float, float, float]``
SFColor        ``tuple[float, float, float]``
SFRotation     ``tuple[float, float, float, float]`` (axis x y z, angle rad)
SFString       ``str``
SFNode         ``Node | None``
MFxxx          ``list`` of the SF values above
=============  ==========================================
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class SourceLocation:
    """Where a node or value was written: used in every error message as ``file:line:col``."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


@dataclass(eq=False)
class Node:
    """One node of an expanded Webots scene.

    After PROTO expansion only base nodes remain (``Solid``, ``HingeJoint``, ``Box`` ...). A node that
    is the root of an expanded PROTO instance keeps the instance's name in ``proto_name`` and its DEF
    in ``def_name`` so a supervisor can still find it with ``getFromDef``.

    ``fields`` holds every field of the node type, defaults filled in, so consumers never need to
    know the defaults themselves.
    """

    type_name: str
    fields: dict[str, Any]
    def_name: str | None = None
    location: SourceLocation | None = None
    proto_name: str | None = None
    field_locations: dict[str, SourceLocation] = field(default_factory=dict)
    #: ``hidden <name> <value>`` lines of a saved PROTO instance (``translation_1``, ``position_0_0``...),
    #: kept verbatim; ``fields`` only ever holds the base node's own fields.
    hidden: dict[str, Any] = field(default_factory=dict)
    #: Set on a node produced by ``USE name`` (a copy of the DEF'd node; ``def_name`` stays None).
    use_name: str | None = None
    #: DEF written inside a PROTO body: like Webots' getFromProtoDef scope, invisible to ``find_def``.
    proto_def_name: str | None = None
    #: Interface values of the PROTO instance this node is the expanded root of (``proto_name``).
    proto_fields: dict[str, Any] | None = field(default=None, repr=False)
    #: The PROTO's default of each interface field (node-typed fields written in the instance are absent:
    #: always written back), so a saved world writes only the fields that differ, as Webots does.
    proto_defaults: dict[str, Any] | None = field(default=None, repr=False)
    #: Numbers the PROTO instance this node is the expanded root of (the key of the ``IS`` links below).
    proto_instance: int | None = None
    #: Shared by a DEF'd node and its USE copies (Webots' same node; DEF names alone repeat across PROTO
    #: instances and may be redefined).
    def_group: int | None = None
    #: Interface fields a procedural PROTO's template reads (Webots regenerates the instance when they change).
    template_fields: frozenset[str] = frozenset()
    #: ``IS`` links of this node's own fields: field name -> (PROTO instance number, interface field name).
    is_links: dict[str, tuple[int, str]] = field(default_factory=dict, repr=False)
    #: ``IS`` links of the interface values of a PROTO instance written in another PROTO's body (this node
    #: is its expanded root): (outer instance, outer field, inner instance, inner field).
    instance_links: list[tuple[int, str, int, str]] = field(default_factory=list, repr=False)

    def get(self, name: str, default: Any = None) -> Any:
        return self.fields.get(name, default)

    def __getitem__(self, name: str) -> Any:
        return self.fields[name]

    def children(self) -> list[Node]:
        """The node's ``children`` field, or an empty list."""
        value = self.fields.get("children")
        return [c for c in value if c is not None] if isinstance(value, list) else []

    def walk(self):  # type: ignore[no-untyped-def]
        """Pre-order traversal over this node and every node reachable through SFNode/MFNode fields."""
        yield self
        for value in self.fields.values():
            if isinstance(value, Node):
                yield from value.walk()
            elif isinstance(value, list):
                for item in value:
                    if isinstance(item, Node):
                        yield from item.walk()

    def copy(self) -> Node:
        """A deep copy of this subtree (locations are shared, they are immutable)."""
        return Node(
            type_name=self.type_name,
            fields={k: copy_value(v) for k, v in self.fields.items()},
            def_name=self.def_name,
            location=self.location,
            proto_name=self.proto_name,
            field_locations=dict(self.field_locations),
            hidden={k: copy_value(v) for k, v in self.hidden.items()},
            use_name=self.use_name,
            proto_def_name=self.proto_def_name,
            proto_fields=None
            if self.proto_fields is None
            else {k: copy_value(v) for k, v in self.proto_fields.items()},
            proto_defaults=None
            if self.proto_defaults is None
            else {k: copy_value(v) for k, v in self.proto_defaults.items()},
            proto_instance=self.proto_instance,
            def_group=self.def_group,
            template_fields=self.template_fields,
            is_links=dict(self.is_links),
            instance_links=list(self.instance_links),
        )


def path_to_node(tops: list[Node], target: Node) -> list[Node] | None:
    """The nodes from one of the top-level nodes ``tops`` down to ``target`` (inclusive), through every SFNode
    and MFNode field; None when ``target`` is not in the tree."""

    def search(node: Node, path: list[Node]) -> list[Node] | None:
        path.append(node)
        if node is target:
            return path
        for value in node.fields.values():
            for child in value if isinstance(value, list) else [value]:
                if isinstance(child, Node) and search(child, path) is not None:
                    return path
        path.pop()
        return None

    for top in tops:
        found = search(top, [])
        if found is not None:
            return found
    return None


def copy_value(value: Any) -> Any:
    """Deep copy of a field value (nodes, lists; tuples and scalars are immutable)."""
    if isinstance(value, Node):
        return value.copy()
    if isinstance(value, list):
        return [copy_value(v) for v in value]
    return value


def values_equal(a: Any, b: Any) -> bool:
    """Structural equality of two field values; NaN equals NaN so a written world compares equal."""
    if isinstance(a, Node) or isinstance(b, Node):
        return isinstance(a, Node) and isinstance(b, Node) and tree_equal(a, b)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return (
            isinstance(a, list) == isinstance(b, list)
            and len(a) == len(b)
            and all(values_equal(x, y) for x, y in zip(a, b, strict=True))
        )
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    if isinstance(a, bool) != isinstance(b, bool):
        return False
    if isinstance(a, int | float) and isinstance(b, int | float):
        return a == b
    return type(a) is type(b) and bool(a == b)


def tree_equal(a: Node, b: Node) -> bool:
    """Same type, DEF, fields and hidden fields, recursively (locations and PROTO origin ignored)."""
    return (
        a.type_name == b.type_name
        and a.def_name == b.def_name
        and a.fields.keys() == b.fields.keys()
        and all(values_equal(a.fields[k], b.fields[k]) for k in a.fields)
        and a.hidden.keys() == b.hidden.keys()
        and all(values_equal(a.hidden[k], b.hidden[k]) for k in a.hidden)
    )


@dataclass
class World:
    """A parsed and expanded ``.wbt`` world."""

    path: str
    header: str
    nodes: list[Node]
    externprotos: list[str] = field(default_factory=list)
    importable_externprotos: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def find_def(self, name: str) -> Node | None:
        """The node with DEF ``name`` (first in pre-order), searching the whole scene."""
        for top in self.nodes:
            for node in top.walk():
                if node.def_name == name:
                    return node
        return None

    def world_info(self) -> Node | None:
        return next((n for n in self.nodes if n.type_name == "WorldInfo"), None)
