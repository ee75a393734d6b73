"""Write a :class:`~dualtwin.webots.nodes.World` / :class:`Node` tree back to ``.wbt`` text, and edit fields.

``parse -> write -> parse`` gives an equal tree (:func:`dualtwin.webots.nodes.tree_equal`): floats are
written with ``repr`` precision, defaults are omitted (the parser fills them back in), and a node
that came from ``USE`` is written as ``USE name`` only when the last written ``DEF name`` has the
same content (otherwise it is written out in full, which reparses to the same values).

:func:`set_field` edits one field either in a parsed tree or directly in ``.wbt`` text; the text
form keeps everything else byte for byte (comments, PROTO instances, formatting), which is what a
"world with its fields edited" needs.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, overload

from dualtwin.webots import schema
from dualtwin.webots.nodes import Node, World, values_equal
from dualtwin.webots.parser import (
    ListValue,
    ParsedWorld,
    RawField,
    RawNode,
    RawUse,
    parse_world,
)

__all__ = ["coerce_value", "format_float", "format_value", "set_field", "write_node", "write_world"]

_INDENT = "  "
_DEFAULT_HEADER = "#VRML_SIM R2023b utf8"
_ITEMS_PER_LINE = 8


def format_float(value: float) -> str:
    """Shortest text that reads back to the same float (``1.0`` -> ``1``)."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if value == int(value) and abs(value) < 1e16:
        return str(int(value)) if value or math.copysign(1.0, value) > 0 else "-0"
    return repr(value)


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _scalar(value: Any) -> str:
    if value is None:
        return "NULL"
    if isinstance(value, bool):
        return "TRUE" if value else "FALSE"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return format_float(float(value))
    if isinstance(value, str):
        return _quote(value)
    if isinstance(value, tuple):
        return " ".join(_scalar(v) for v in value)
    raise TypeError(f"cannot write a {type(value).__name__} as a VRML value")


class _Writer:
    def __init__(self, defaults: bool, protos: bool = False) -> None:
        self.defaults = defaults
        self.protos = protos
        self.last_def: dict[str, Node] = {}

    def value(self, value: Any, indent: int) -> str:
        pad = _INDENT * indent
        if isinstance(value, Node):
            return self.node(value, indent)
        if isinstance(value, list):
            if not value:
                return "[]"
            if any(isinstance(v, Node) for v in value):
                inner = "\n".join(pad + _INDENT + self.node(v, indent + 1) for v in value if isinstance(v, Node))
                return f"[\n{inner}\n{pad}]"
            if isinstance(value[0], str):  # one string per line, as Webots writes them
                body = "\n".join(pad + _INDENT + _scalar(v) for v in value)
                return f"[\n{body}\n{pad}]"
            sep = ", " if isinstance(value[0], tuple) else " "
            if len(value) <= _ITEMS_PER_LINE:
                return "[ " + sep.join(_scalar(v) for v in value) + " ]"
            chunks = [
                sep.join(_scalar(v) for v in value[k : k + _ITEMS_PER_LINE])
                for k in range(0, len(value), _ITEMS_PER_LINE)
            ]
            body = (sep.rstrip() + "\n").join(pad + _INDENT + chunk for chunk in chunks)
            return f"[\n{body}\n{pad}]"
        return _scalar(value)

    def _usable(self, node: Node) -> bool:
        if node.use_name is None or node.type_name in schema.USE_FORBIDDEN_TYPES:
            return False
        original = self.last_def.get(node.use_name)
        if original is None or original.type_name != node.type_name:
            return False
        return all(values_equal(original.fields.get(k), v) for k, v in node.fields.items()) and (
            original.fields.keys() == node.fields.keys()
            and original.hidden.keys() == node.hidden.keys()
            and all(values_equal(original.hidden[k], v) for k, v in node.hidden.items())
        )

    def node(self, node: Node, indent: int) -> str:
        if self._usable(node):
            return f"USE {node.use_name}"
        if self.protos and node.proto_name is not None and node.proto_fields is not None:
            return self.proto_instance(node, indent)
        pad = _INDENT * indent
        head = f"DEF {node.def_name} {node.type_name} {{" if node.def_name else f"{node.type_name} {{"
        spec = schema.BASE_NODES.get(node.type_name)
        lines = [head]
        names = list(spec.fields) if spec is not None else []
        names += [n for n in node.fields if n not in names]
        for name in names:
            if name not in node.fields:
                continue
            value = node.fields[name]
            fspec = spec.fields.get(name) if spec is not None else None
            if not self.defaults and fspec is not None and values_equal(value, fspec.default):
                continue
            lines.append(f"{pad}{_INDENT}{name} {self.value(value, indent + 1)}")
        for name, value in node.hidden.items():
            lines.append(f"{pad}{_INDENT}hidden {name} {self.value(value, indent + 1)}")
        lines.append(pad + "}")
        if node.def_name:
            self.last_def[node.def_name] = node
        return "\n".join(lines)


    def proto_instance(self, node: Node, indent: int) -> str:
        """A PROTO instance as Webots saves it: its name and the interface fields that differ from the PROTO's
        defaults (its body is not written: it is expanded again at load), then its ``hidden`` fields."""
        pad = _INDENT * indent
        assert node.proto_fields is not None
        lines = [f"DEF {node.def_name} {node.proto_name} {{" if node.def_name else f"{node.proto_name} {{"]
        defaults = node.proto_defaults or {}
        for name, value in node.proto_fields.items():
            if not self.defaults and name in defaults and values_equal(value, defaults[name]):
                continue
            lines.append(f"{pad}{_INDENT}{name} {self.value(value, indent + 1)}")
        for name, value in node.hidden.items():
            lines.append(f"{pad}{_INDENT}hidden {name} {self.value(value, indent + 1)}")
        lines.append(pad + "}")
        return "\n".join(lines)


def write_node(node: Node, indent: int = 0, *, defaults: bool = False, protos: bool = False) -> str:
    """VRML text of one node (first line not indented, following lines at ``indent`` levels); with ``protos``,
    PROTO instances as Webots writes them (name and interface fields, see :func:`write_world`)."""
    return _Writer(defaults, protos).node(node, indent)


def format_value(value: Any, indent: int = 0) -> str:
    """VRML text of a field value (node, list, tuple, string, number, boolean or None = NULL)."""
    return _Writer(False).value(value, indent)


def write_world(world: World, *, defaults: bool = False, externprotos: bool = True, protos: bool = False) -> str:
    """``.wbt`` text of a world; reparsing it gives an equal tree.

    Args:
        defaults: also write fields equal to their default.
        externprotos: keep the world's EXTERNPROTO lines (needed with ``protos``; harmless without).
        protos: write each PROTO instance as Webots saves it (its name and interface fields, not its expanded
            body), as ``Supervisor.worldSave`` does.
    """
    header = world.header if world.header.startswith("#VRML_SIM ") else _DEFAULT_HEADER
    out = [header, ""]
    if externprotos and (world.externprotos or world.importable_externprotos):
        out += [f"EXTERNPROTO {_quote(url)}" for url in world.externprotos]
        out += [f"IMPORTABLE EXTERNPROTO {_quote(url)}" for url in world.importable_externprotos]
        out.append("")
    writer = _Writer(defaults, protos)
    out += [writer.node(node, 0) for node in world.nodes]
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------------------------
# field edits


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def coerce_value(value: Any, vrml_type: str) -> Any:
    """Check and normalise a Python value for a field of ``vrml_type`` (tuples of floats, etc.).

    Raises:
        ValueError: the value does not fit the type.
    """
    if vrml_type.startswith("MF"):
        if isinstance(value, str | bytes) or not isinstance(value, Sequence):
            raise ValueError(f"expected a list for {vrml_type}, got {value!r}")
        elem = schema.mf_element_type(vrml_type)
        return [coerce_value(v, elem) for v in value]
    size = schema.VECTOR_SIZES.get(vrml_type)
    ok = True
    result: Any = value
    if vrml_type == "SFBool":
        ok = isinstance(value, bool)
    elif vrml_type == "SFInt32":
        ok = _is_real(value) and float(value) == int(value) and -(2**31) <= int(value) < 2**31
        result = int(value) if ok else value
    elif vrml_type == "SFFloat":
        ok = _is_real(value)
        result = float(value) if ok else value
    elif size is not None:
        ok = (
            isinstance(value, Sequence)
            and not isinstance(value, str)
            and len(value) == size
            and all(_is_real(v) for v in value)
        )
        result = tuple(float(v) for v in value) if ok else value
    elif vrml_type == "SFString":
        ok = isinstance(value, str)
    elif vrml_type == "SFNode":
        ok = value is None or isinstance(value, Node)
    if not ok:
        raise ValueError(f"expected a {vrml_type} value, got {value!r}")
    return result


def _find_def_node(root: Node, name: str) -> Node | None:
    return next((n for n in root.walk() if n.def_name == name), None)


def _descend(node: Node, path: list[str], def_name: str) -> tuple[Node, str]:
    for seg in path[:-1]:
        child = node.fields.get(seg)
        if not isinstance(child, Node):
            raise ValueError(f"DEF {def_name}: field '{seg}' of {node.type_name} holds no node to edit inside")
        node = child
    return node, path[-1]


def _set_in_tree(node: Node, path: list[str], def_name: str, value: Any) -> None:
    target, name = _descend(node, path, def_name)
    spec = schema.BASE_NODES.get(target.type_name)
    if spec is not None:
        if name not in spec.fields:
            raise ValueError(
                f"DEF {def_name}: {target.type_name} has no field '{name}' (fields: {', '.join(spec.fields)})"
            )
        value = coerce_value(value, spec.fields[name].type)
    elif name not in target.fields:
        raise ValueError(f"DEF {def_name}: {target.type_name} has no field '{name}'")
    target.fields[name] = value


def _raw_children(raw: RawNode) -> list[RawNode]:
    out: list[RawNode] = []
    for rf in raw.fields.values():
        value = rf.value
        items = value.items if isinstance(value, ListValue) else [value]
        out += [i for i in items if isinstance(i, RawNode)]
    return out


def _find_raw_def(nodes: Sequence[RawNode | RawUse], name: str) -> RawNode | None:
    stack = [n for n in reversed(nodes) if isinstance(n, RawNode)]
    while stack:
        node = stack.pop()
        if node.def_name == name:
            return node
        stack += reversed(_raw_children(node))
    return None


def _line_indent(text: str, offset: int) -> str:
    start = text.rfind("\n", 0, offset) + 1
    line = text[start:offset]
    return line[: len(line) - len(line.lstrip(" \t"))]


def _set_in_text(text: str, def_name: str, path: list[str], value: Any) -> str:
    parsed: ParsedWorld = parse_world(text, "<set_field>")
    raw = _find_raw_def(parsed.nodes, def_name)
    if raw is None:
        raise ValueError(f"no DEF {def_name} in the world text")
    for seg in path[:-1]:
        rf = raw.fields.get(seg)
        if rf is None or not isinstance(rf.value, RawNode):
            raise ValueError(
                f"DEF {def_name}: field '{seg}' of {raw.type_name} is not written as a node in the file; "
                "cannot edit inside it"
            )
        raw = rf.value
    name = path[-1]
    spec = schema.BASE_NODES.get(raw.type_name)
    if spec is not None:  # PROTO instances are not checked: their interface is in another file
        if name not in spec.fields:
            raise ValueError(
                f"DEF {def_name}: {raw.type_name} has no field '{name}' (fields: {', '.join(spec.fields)})"
            )
        value = coerce_value(value, spec.fields[name].type)
    indent = _line_indent(text, raw.start) + _INDENT
    level = len(indent.expandtabs(2)) // len(_INDENT)
    new_field = f"{name} {format_value(value, level)}"
    existing: RawField | None = raw.fields.get(name)
    if existing is not None:
        result = text[: existing.start] + new_field + text[existing.end :]
    else:
        result = text[: raw.body_start] + "\n" + indent + new_field + text[raw.body_start :]
    parse_world(result, "<set_field result>")  # an edit must never produce an unreadable world
    return result


@overload
def set_field(target: str, def_name: str, field: str, value: Any) -> str: ...
@overload
def set_field(target: World, def_name: str, field: str, value: Any) -> World: ...
@overload
def set_field(target: Node, def_name: str, field: str, value: Any) -> Node: ...


def set_field(target: str | World | Node, def_name: str, field: str, value: Any) -> str | World | Node:
    """Set ``field`` of the node ``DEF def_name`` to ``value``.

    ``field`` may be a dotted path through SFNode fields (``"jointParameters.position"``). With
    ``.wbt`` text the edited text is returned (everything else untouched; a field not yet written
    is inserted). With a ``World``/``Node`` tree the tree is edited in place and returned. Values of
    base-node fields are checked against the schema and normalised (``[1, 2, 3]`` -> ``(1.0, 2.0,
    3.0)``); fields of unexpanded PROTO instances (text form) are written as given.

    Raises:
        ValueError: unknown DEF or field, or a value of the wrong type.
    """
    path = field.split(".")
    if not all(path):
        raise ValueError(f"bad field path {field!r}")
    if isinstance(target, str):
        return _set_in_text(target, def_name, path, value)
    if isinstance(target, World):
        node = target.find_def(def_name)
    else:
        node = _find_def_node(target, def_name)
    if node is None:
        raise ValueError(f"no DEF {def_name} in the tree")
    _set_in_tree(node, path, def_name, value)
    return target


def _raw_nodes(nodes: list[Any]) -> Iterator[Any]:
    """Pre-order walk over a raw (unexpanded) parse tree, this file's nodes only."""
    from dualtwin.webots.parser import ListValue, RawNode

    for node in nodes:
        if not isinstance(node, RawNode):
            continue
        yield node
        for raw_field in node.fields.values():
            value = raw_field.value
            items = value.items if isinstance(value, ListValue) else [value]
            yield from _raw_nodes([v for v in items if isinstance(v, RawNode)])


def patch_webots_world(world_path: str | Path, knobs: Mapping[str, float]) -> str:
    """The world's text with the fitted Webots-twin knobs written into its fields.

    Joint and body knobs address their node by DEF; ``motor.*.gain`` is controller-side and skipped. Motors, ContactProperties and WorldInfo usually have no
    DEF; they get one (``DUALTWIN_<kind>_<n>``) so the edit stays a plain, reviewable field change. Only
    nodes written in the world file itself can be edited (not nodes inside PROTOs).
    """
    path = Path(world_path)
    text = path.read_text(encoding="utf-8")
    for name, value in knobs.items():
        kind, _, rest = name.partition(".")
        target, _, prop = rest.rpartition(".")
        if kind == "motor" and prop == "gain":
            continue  # a controller-side command gain: nothing in the world file changes
        if kind == "joint":
            field = {"damping": "jointParameters.dampingConstant", "friction": "jointParameters.staticFriction"}
            text = set_field(text, target, field[prop], float(value))
        elif kind == "body" and prop == "mass":
            text = set_field(text, target, "physics.mass", float(value))
        elif kind in ("motor", "contact", "world"):
            text = _set_by_matching_node(text, str(path), kind, target, prop, float(value))
        else:
            raise ValueError(f"knob {name!r} has no .wbt field to write")
    return text


def _set_by_matching_node(text: str, origin: str, kind: str, target: str, prop: str, value: float) -> str:
    from dualtwin.webots.parser import parse_world

    parsed = parse_world(text, origin)
    field_by_prop = {
        "max_torque": "maxTorque", "max_velocity": "maxVelocity", "friction": "coulombFriction",
        "bounce": "bounce", "soft_erp": "softERP", "soft_cfm": "softCFM", "erp": "ERP", "cfm": "CFM",
    }
    field = field_by_prop.get(prop)
    if field is None:
        raise ValueError(f"knob '{kind}.{target}.{prop}' has no .wbt field to write")

    def string(node: Any, name: str, default: str) -> str:
        raw = node.fields.get(name)
        return str(raw.value.tokens[0].value) if raw is not None else default

    def matches(node: Any) -> bool:
        if kind == "motor":
            return node.type_name in ("RotationalMotor", "LinearMotor") and string(node, "name", "") == target
        if kind == "contact":
            pair = f"{string(node, 'material1', 'default')}:{string(node, 'material2', 'default')}"
            return node.type_name == "ContactProperties" and pair == target
        return node.type_name == "WorldInfo"

    node = next((n for n in _raw_nodes(parsed.nodes) if matches(n)), None)
    if node is None:
        raise ValueError(f"{origin}: no node for knob '{kind}.{target}.{prop}' in the world file")
    if node.def_name is None:
        node_def = f"DUALTWIN_{kind.upper()}_{node.start}"
        text = text[:node.start] + f"DEF {node_def} " + text[node.start:]
    else:
        node_def = node.def_name
    return set_field(text, node_def, field, [value] if field == "coulombFriction" else value)
