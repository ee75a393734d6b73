"""PROTO expansion: a ``.wbt`` world becomes a tree of base nodes only.

Where each PROTO file is found (the resolution order, stand-ins, the cache) is
:mod:`dualtwin.webots.proto_resolver`; a PROTO still missing is skipped with a warning when it is known to be
visual only (appearances, backgrounds); anything else raises
:class:`~dualtwin.webots.proto_resolver.ProtoNotFoundError`.

Expansion follows Webots: instance values override interface defaults, ``IS`` substitutes (deep
copies of) them, each PROTO body is its own DEF scope, derived PROTOs expand recursively, procedural
PROTOs run their JavaScript template with QuickJS (Webots' TemplateEngine algorithm), and ``hidden``
fields saved in a world override the PROTO body's poses, velocities and joint positions.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import re
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualtwin.artifacts import check_input_file
from dualtwin.errors import DualtwinError
from dualtwin.webots import schema
from dualtwin.webots.js_template import JS_MODULES, VEC_KEYS, js_number, strip_imports
from dualtwin.webots.lexer import WebotsSyntaxError
from dualtwin.webots.nodes import Node, SourceLocation, World, copy_value, values_equal
from dualtwin.webots.parser import (
    MAX_NODES,
    ExternProto,
    IsLink,
    ListValue,
    NullValue,
    ParsedProto,
    ParsedWorld,
    ProtoFieldDecl,
    RawField,
    RawNode,
    RawUse,
    Scalars,
    check_node_value,
    convert_value,
    parse_proto_body,
    parse_world,
)
from dualtwin.webots.proto_cache import WEBOTS_VERSION, is_remote
from dualtwin.webots.proto_resolver import ProtoError, ProtoNotFoundError, ProtoResolver
from dualtwin.webots.standins import STANDIN_PREFIX

__all__ = [
    "TEMPLATE_SECONDS",
    "VISUAL_ONLY_PROTOS",
    "expand_world",
    "load_world",
    "load_world_text",
]

#: Deepest chain of nested PROTO instances (derived PROTOs count too).
MAX_PROTO_DEPTH = 32
# A template is arbitrary code: bound it so a bad PROTO fails with a message instead of hanging.
_JS_TIME_LIMIT = 10  # s of CPU
#: Seconds (wall clock) all the templates of one world may run together: each template's own limit alone let a
#: world of many instances of a 9 s template run for hours.
TEMPLATE_SECONDS = 60.0
_JS_MEMORY_LIMIT = 256 * 1024 * 1024

#: PROTOs that carry no physics, skipped (with a warning) when they cannot be found. Appearances are
#: PBRAppearance-derived; backgrounds and their lights only light the scene. Floors, objects and
#: devices are deliberately absent: they may have boundingObjects or masses we cannot guess.
VISUAL_ONLY_PROTOS = frozenset(
    {
        "TexturedBackground",
        "TexturedBackgroundLight",
        "Asphalt", "BakelitePlastic", "BrushedAluminium", "BrushedSteel", "CarpetFibers", "CementTiles",
        "ChequeredParquetry", "Copper", "CorrodedMetal", "CorrugatedMetal", "DamascusSteel", "DryMud",
        "ElectricConduit", "Fabric", "FlexibleAluminiumDuct", "FormedConcrete", "GalvanizedMetal",
        "GlossyCarPaint", "GlossyPaint", "Grass", "HammeredCopper", "Leather", "LedStrip", "MarbleTiles",
        "MattePaint", "MetalPipePaint", "MetalStainlessSteelCable", "OldPlywood", "OldSteel", "OsbWood",
        "PaintedWood", "Parquetry", "Pavement", "PerforatedMetal", "Plaster", "Plastic",
        "PorcelainChevronTiles", "RedBricks", "ReflectiveSurface", "Roughcast", "RoughConcrete",
        "RoughOak", "RoughPine", "RoughPolymer", "Rubber", "RustyMetal", "SandyGround", "ScrewThread",
        "ShinyLeather", "SlatePavement", "Soil", "SolarCell", "SquareStoneTiles", "StonePavement",
        "StoneBricks", "StoneTiles", "ThreadMetalPlate", "TireRubber", "VarnishedPine", "WaterHexagon",
    }
)
_VISUAL_ONLY_URL_PARTS = ("/projects/appearances/protos/", "/projects/objects/backgrounds/protos/")



# --------------------------------------------------------------------------------------------
# JavaScript templates (the modules and literals live in js_template.py)


def template_to_js(template: str, proto: ParsedProto) -> str:
    """JavaScript statements that build ``___vrml`` from a PROTO body template.

    Raw chunks are emitted as JSON string literals, which escapes backticks, ``${`` and backslashes
    (Webots pastes them into template literals).
    """
    out: list[str] = []
    pos = 0
    while True:
        start = template.find("%<", pos)
        if start < 0:
            out.append(f"___vrml += {json.dumps(template[pos:])};")
            return "\n".join(out)
        out.append(f"___vrml += {json.dumps(template[pos:start])};")
        end = template.find(">%", start + 2)
        if end < 0:
            loc = proto.location_of(start)
            raise ProtoError(f"{loc}: expected '>%' closing this template block, found end of file")
        code = template[start + 2 : end]
        if code.startswith("="):
            expr = code[1:].strip().rstrip(";")
            out.append(f"___vrml += ({expr}\n);")
        else:
            out.append(strip_imports(code))
        pos = end + 2


# --------------------------------------------------------------------------------------------
# expansion


def _declared(externs: list[ExternProto], warnings: list[str]) -> dict[str, ExternProto]:
    """A file's EXTERNPROTO declarations by PROTO name; a name declared by two urls is ambiguous and the first
    declaration wins, as in Webots (a warning says so, once per file)."""
    out: dict[str, ExternProto] = {}
    for e in externs:
        first = out.setdefault(e.name, e)
        if first is not e and first.url != e.url:
            message = (f"{e.location}: PROTO '{e.name}' is ambiguous: declared as \"{first.url}\" and "
                       f"\"{e.url}\"; the first is used")
            if message not in warnings:
                warnings.append(message)
    return out


@dataclass
class _Scope:
    """Where raw nodes come from: the file (DEF scope) and, in a PROTO body, the instance values."""

    file: str
    directory: Path | None
    externs: dict[str, ExternProto]
    proto: ParsedProto | None = None
    values: dict[str, Any] | None = None
    in_world: bool = False
    #: Number of the PROTO instance whose body this is (the key of the ``IS`` links recorded on nodes).
    instance: int | None = None
    expanded: dict[int, Node | None] = field(default_factory=dict)


_HIDDEN_TYPES = (
    (re.compile(r"(translation|linearVelocity|angularVelocity)_(\d+)"), "SFVec3f"),
    (re.compile(r"rotation_(\d+)"), "SFRotation"),
    (re.compile(r"position[23]?_(\d+)_(\d+)"), "SFFloat"),
)


def _hidden_type(name: str) -> str | None:
    for pattern, vrml_type in _HIDDEN_TYPES:
        if pattern.fullmatch(name):
            return vrml_type
    return None


#: The image dimensions of the devices that hold an image buffer (pixels, depths, points), which are allocated
#: from them; and the most each may be. 16384 is OpenGL's usual GL_MAX_TEXTURE_SIZE, the most a Webots render
#: target can have; beyond it a world's ``width 200000`` asked for a buffer of hundreds of GiB (MemoryError, or
#: the machine out of memory once the buffer is written).
IMAGE_SIZE_FIELDS: dict[str, tuple[str, ...]] = {
    "Camera": ("width", "height"),
    "RangeFinder": ("width", "height"),
    "Display": ("width", "height"),
    "Lidar": ("horizontalResolution", "numberOfLayers"),
}
MAX_IMAGE_SIDE = 16384


def _finite(value: Any) -> bool:
    """No NaN or infinity among the numbers of a field value (a number, a vector, or a list of them); nodes,
    strings and booleans count as finite."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, (tuple, list)):
        return all(_finite(v) for v in value)
    return True


def _generic_value(raw: Any) -> Any:
    """Best-effort value of a hidden field whose type is unknown."""
    if isinstance(raw, Scalars):
        toks = raw.tokens
        if len(toks) == 1 and toks[0].kind == "string":
            return toks[0].value
        if len(toks) == 1 and toks[0].kind == "ident":
            return toks[0].text == "TRUE"
        try:
            floats = [float(t.value) for t in toks]
        except OverflowError:
            raise WebotsSyntaxError(raw.location, "a hidden field value", "an out-of-range number") from None
        return floats[0] if len(floats) == 1 else tuple(floats)
    if isinstance(raw, ListValue) and all(getattr(i, "kind", "") == "number" for i in raw.items):
        try:
            return [float(i.value) for i in raw.items]
        except OverflowError:
            raise WebotsSyntaxError(raw.location, "a hidden field value", "an out-of-range number") from None
    found = "a node" if isinstance(raw, RawNode | RawUse | NullValue) else "a list"
    raise WebotsSyntaxError(raw.location, "a hidden field value (numbers, string or boolean)", found)


def _node_items(value: Any) -> Iterator[Node]:
    if isinstance(value, Node):
        yield value
    elif isinstance(value, list):
        yield from (v for v in value if isinstance(v, Node))


def _count_nodes(value: Any) -> int:
    return sum(1 for item in _node_items(value) for _ in item.walk())


_NON_SCENE_FIELDS = frozenset({"boundingObject", "physics"})


def _solids_preorder(root: Node) -> list[Node]:
    out: list[Node] = []

    def visit(node: Node) -> None:
        if node.type_name in schema.SOLID_TYPES:
            out.append(node)
        for name, value in node.fields.items():
            if name not in _NON_SCENE_FIELDS:
                for child in _node_items(value):
                    visit(child)

    visit(root)
    return out


def _joints_of(solid: Node) -> list[Node]:
    out: list[Node] = []

    def visit(node: Node) -> None:
        if node is not solid and node.type_name in schema.SOLID_TYPES:
            return
        if node.type_name in schema.JOINT_TYPES:
            out.append(node)
        for name, value in node.fields.items():
            if name not in _NON_SCENE_FIELDS:
                for child in _node_items(value):
                    visit(child)

    visit(solid)
    return out


def saved_hidden(root: Node) -> dict[str, Any]:
    """The ``hidden`` fields Webots writes for a PROTO instance's internal state, read from its expanded body's
    current fields: ``translation_N``/``rotation_N`` of the Solids inside it (N their pre-order index; the root's
    own, 0, only where no interface field carries it), ``linearVelocity_N``/``angularVelocity_N`` where a Solid
    moves, and ``position[2|3]_N_M`` of every joint (M its index among Solid N's joints). The inverse of
    :meth:`_Expander._apply_hidden`, so a saved or exported instance loads back in the same state."""
    hidden: dict[str, Any] = {}
    for n, solid in enumerate(_solids_preorder(root)):
        for name in ("translation", "rotation"):
            if name in solid.fields and (n > 0 or name not in solid.is_links):
                hidden[f"{name}_{n}"] = solid.fields[name]
        for name in ("linearVelocity", "angularVelocity"):
            value = solid.fields.get(name)
            if value is not None and any(v != 0.0 for v in value):
                hidden[f"{name}_{n}"] = value
        for m, joint in enumerate(_joints_of(solid)):
            for suffix in ("", "2", "3"):
                params = joint.fields.get("jointParameters" + suffix)
                if isinstance(params, Node) and "position" in params.fields:
                    hidden[f"position{suffix}_{n}_{m}"] = params.fields["position"]
    return hidden


# Process-wide, so a node imported at run time never shares an instance number with one already loaded.
_INSTANCE_NUMBERS = itertools.count(1)


class _Expander:
    def __init__(
        self, resolver: ProtoResolver, world_path: str, warnings: list[str], template_seconds: float = TEMPLATE_SECONDS
    ) -> None:
        self.resolver = resolver
        self.template_seconds = template_seconds
        self._template_spent = 0.0  # s the templates have run so far (template_seconds)
        self.world_path = world_path
        self.warnings = warnings
        self._stack: list[str] = []
        self._ids = itertools.count(1)
        self._by_name: dict[str, ParsedProto] = {}
        self._undeclared_warned: set[tuple[str, str]] = set()
        self._tmpdir: str | None = None
        self._nodes = 0  # nodes of the expanded world so far (MAX_NODES)

    def _grow(self, count: int, location: SourceLocation) -> None:
        """Count ``count`` more nodes of the expanded world (a new node, or a USE or IS copy) against MAX_NODES.

        Counted before a copy is made, so a world whose DEF/USE or PROTO nesting multiplies its nodes stops at
        the limit instead of copying for minutes (a copied subtree was counted already, so it is smaller).
        """
        self._nodes += count
        if self._nodes > MAX_NODES:
            raise WebotsSyntaxError(
                location,
                f"a world of at most {MAX_NODES} nodes once its USEs, IS fields and PROTOs are expanded",
                "more (nested DEF/USE or PROTO instances multiply them)",
            )

    # -- nodes -------------------------------------------------------------------------------
    def expand_ref(self, raw: RawNode | RawUse, scope: _Scope) -> Node | None:
        if isinstance(raw, RawUse):
            key = id(raw.target)
            src = scope.expanded[key] if key in scope.expanded else self.expand_node(raw.target, scope)
            if src is None:
                return None
            if src.type_name in schema.USE_FORBIDDEN_TYPES:
                what = src.type_name if src.proto_name is None else f"{src.proto_name} (a {src.type_name})"
                raise WebotsSyntaxError(
                    raw.location,
                    "a node that may be USEd (Webots forbids USE of Solid-derived, joint and "
                    "joint-parameters nodes)",
                    f"USE of {what} '{raw.name}'",
                )
            self._grow(_count_nodes(src), raw.location)
            copy = src.copy()
            for inner in copy.walk():
                if inner.def_name is not None or inner.proto_def_name is not None:
                    inner.use_name = inner.def_name or inner.proto_def_name
                    inner.def_name = inner.proto_def_name = None
            copy.use_name = raw.name
            return copy
        node = self.expand_node(raw, scope)
        scope.expanded[id(raw)] = node
        return node

    def expand_node(self, raw: RawNode, scope: _Scope) -> Node | None:
        if raw.is_base:
            return self.expand_base(raw, scope)
        return self.expand_instance(raw, scope)

    @staticmethod
    def _set_def(node: Node, def_name: str | None, scope: _Scope) -> None:
        if def_name is not None:
            node.def_group = next(_INSTANCE_NUMBERS)
        if scope.in_world:
            node.def_name, node.proto_def_name = def_name, None
        else:
            node.def_name, node.proto_def_name = None, def_name

    def expand_base(self, raw: RawNode, scope: _Scope) -> Node:
        spec = schema.BASE_NODES[raw.type_name]
        self._grow(1, raw.location)
        fields = spec.defaults()
        locations: dict[str, SourceLocation] = {}
        for name, rf in raw.fields.items():
            value = self.field_value(rf, spec.fields[name].type, scope)
            if not _finite(value):
                # The tokenizer reads nan and inf (a world written from a diverged simulation holds them), but
                # no Webots field takes one, and ODE aborts the whole process on a non-finite anchor, centre of
                # mass or pose: the field keeps its default, and the world says so once.
                self.warnings.append(f"{rf.location}: {raw.type_name}.{name} holds a non-finite number; using "
                                     "its default")
                continue
            if name in IMAGE_SIZE_FIELDS.get(raw.type_name, ()) and value > MAX_IMAGE_SIDE:
                self.warnings.append(f"{rf.location}: {raw.type_name}.{name} {value} is larger than "
                                     f"{MAX_IMAGE_SIDE}; using its default")
                continue
            fields[name] = value
            locations[name] = rf.location
        node = Node(raw.type_name, fields, location=raw.location, field_locations=locations)
        node.is_links = self.links_of(raw, scope)
        self._set_def(node, raw.def_name, scope)
        node.hidden = self.hidden_values(raw)
        return node

    @staticmethod
    def links_of(raw: RawNode, scope: _Scope) -> dict[str, tuple[int, str]]:
        """The fields of ``raw`` written ``<field> IS <interface field>`` (Webots propagates edits through them)."""
        if scope.instance is None:
            return {}
        return {name: (scope.instance, rf.value.name) for name, rf in raw.fields.items() if isinstance(rf.value, IsLink)}

    def field_value(self, rf: RawField, vrml_type: str, scope: _Scope) -> Any:
        if isinstance(rf.value, IsLink):
            return self.is_value(rf.value, vrml_type, scope)
        if rf.has_typed:
            return copy_value(rf.typed)
        return self.convert(rf.value, vrml_type, scope)

    def convert(self, raw: Any, vrml_type: str, scope: _Scope) -> Any:
        if vrml_type == "SFNode":
            check_node_value(raw, vrml_type)
            return None if isinstance(raw, NullValue) else self.expand_ref(raw, scope)
        if vrml_type == "MFNode":
            check_node_value(raw, vrml_type)
            items = raw.items if isinstance(raw, ListValue) else [raw]
            return [n for n in (self.expand_ref(i, scope) for i in items) if n is not None]
        return convert_value(raw, vrml_type)

    def is_value(self, link: IsLink, vrml_type: str, scope: _Scope) -> Any:
        proto, values = scope.proto, scope.values
        if proto is None or values is None:
            raise WebotsSyntaxError(link.location, "a value (IS is only allowed inside a PROTO body)", "IS")
        decl = proto.interface.get(link.name)
        if decl is None:
            raise WebotsSyntaxError(
                link.location,
                f"a field of PROTO {proto.name} ({', '.join(proto.interface) or 'none'})",
                f"IS {link.name}",
            )
        if decl.type != vrml_type:
            raise WebotsSyntaxError(
                link.location, f"IS to a field of type {vrml_type}", f"'{link.name}' of type {decl.type}"
            )
        self._grow(_count_nodes(values[link.name]), link.location)
        return copy_value(values[link.name])

    def hidden_values(self, raw: RawNode) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name, rf in raw.hidden.items():
            if isinstance(rf.value, IsLink):
                raise WebotsSyntaxError(rf.location, "a hidden field value", "IS")
            vrml_type = _hidden_type(name)
            value = _generic_value(rf.value) if vrml_type is None else convert_value(rf.value, vrml_type)
            if not _finite(value):  # (a diverged simulation's saved state: the instance starts as if unsaved)
                self.warnings.append(f"{rf.location}: hidden field '{name}' holds a non-finite number; ignored")
                continue
            out[name] = value
        return out

    # -- PROTO instances ---------------------------------------------------------------------
    def resolve(self, raw: RawNode, scope: _Scope) -> ParsedProto | None:
        name = raw.type_name
        ext = scope.externs.get(name)
        url = ext.url if ext is not None else None
        found, tried = self.resolver.find(
            name, url, scope.directory, scope.file if is_remote(scope.file) else None
        )
        if found is None:
            if name in VISUAL_ONLY_PROTOS or any(p in (url or "") for p in _VISUAL_ONLY_URL_PARTS):
                self.warnings.append(
                    f"{raw.location}: PROTO '{name}' not found; skipped because it is visual only"
                )
                return None
            where = f" (EXTERNPROTO \"{url}\")" if url else " (no EXTERNPROTO declares it)"
            raise ProtoNotFoundError(
                f"{raw.location}: PROTO '{name}'{where} not found. Searched: {'; '.join(tried)}. "
                f"Provide {name}.proto in a folder listed in DUALTWIN_PROTO_PATH, "
                "set WEBOTS_HOME to a Webots installation, or run 'dualtwin webots fetch WORLD' where the "
                "network is reachable (DUALTWIN_PROTO_MIRROR points at a fetched folder or a mirror)."
            )
        if ext is None and (scope.file, name) not in self._undeclared_warned:
            self._undeclared_warned.add((scope.file, name))
            self.warnings.append(f"{raw.location}: PROTO '{name}' used without an EXTERNPROTO declaration")
        proto = self.resolver.load(found, raw.location)
        if proto.name != name:
            raise WebotsSyntaxError(proto.location, f"PROTO {name} (as the file name says)", f"PROTO {proto.name}")
        self._by_name[name] = proto
        return proto

    def _proto_scope(self, proto: ParsedProto) -> _Scope:
        remote_or_standin = proto.path.startswith(STANDIN_PREFIX) or is_remote(proto.path)
        directory = None if remote_or_standin else Path(proto.path).parent
        return _Scope(proto.path, directory, _declared(proto.externprotos, self.warnings))

    def default_value(self, decl: ProtoFieldDecl, proto: ParsedProto) -> Any:
        if decl.type in ("SFNode", "MFNode"):
            return self.convert(decl.default, decl.type, self._proto_scope(proto))
        return copy_value(decl.typed_default)

    def expand_instance(self, raw: RawNode, scope: _Scope) -> Node | None:
        proto = self.resolve(raw, scope)
        if proto is None:
            return None
        if proto.path in self._stack:
            chain = " -> ".join(Path(p).stem for p in [*self._stack, proto.path])
            raise ProtoError(f"{raw.location}: PROTO {proto.name} instantiates itself ({chain})")
        if len(self._stack) >= MAX_PROTO_DEPTH:
            raise ProtoError(f"{raw.location}: PROTOs nested deeper than {MAX_PROTO_DEPTH} levels")
        values: dict[str, Any] = {}
        for fname, rf in raw.fields.items():
            decl = proto.interface.get(fname)
            if decl is None:
                valid = ", ".join(proto.interface) or "none"
                raise WebotsSyntaxError(
                    rf.location, f"a field of PROTO {proto.name} ({valid})", f"unknown field '{fname}'"
                )
            values[fname] = self.field_value(rf, decl.type, scope)
            self._check_restriction(decl, values, rf.location, proto)
        for fname, decl in proto.interface.items():
            if fname not in values:
                values[fname] = self.default_value(decl, proto)
        values = {fname: values[fname] for fname in proto.interface}
        defaults = {
            fname: copy_value(values[fname]) if fname not in raw.fields else copy_value(decl.typed_default)
            for fname, decl in proto.interface.items()
            if fname not in raw.fields or decl.type not in ("SFNode", "MFNode")
        }
        instance = next(_INSTANCE_NUMBERS)
        self._stack.append(proto.path)
        try:
            if proto.template is not None:
                body = self.render(proto, values, raw)
            else:
                assert proto.body is not None
                body = proto.body
            body_scope = self._proto_scope(proto)
            body_scope.proto, body_scope.values, body_scope.instance = proto, values, instance
            root = self.expand_node(body, body_scope)
        finally:
            self._stack.pop()
        if root is None:
            return None
        root.proto_name = raw.type_name
        root.location = raw.location
        root.proto_fields = values
        root.proto_defaults = defaults
        root.instance_links = [
            (outer, outer_field, instance, name)
            for name, (outer, outer_field) in self.links_of(raw, scope).items()
        ] + root.instance_links
        root.proto_instance = instance
        if proto.template is not None:
            root.template_fields = frozenset(re.findall(r"\bfields\.(\w+)", proto.template)) & set(values)
        self._set_def(root, raw.def_name, scope)
        hidden = self.hidden_values(raw)
        if hidden:
            root.hidden = hidden
            self._apply_hidden(root, hidden, raw.location)
        return root

    def _check_restriction(
        self, decl: ProtoFieldDecl, values: dict[str, Any], loc: SourceLocation, proto: ParsedProto
    ) -> None:
        if not decl.restrictions or decl.type in ("SFNode", "MFNode"):
            return
        value = values[decl.name]
        items = value if decl.type.startswith("MF") else [value]
        allowed = decl.restrictions
        if all(any(values_equal(i, a) for a in allowed) for i in items):
            return
        # Webots refuses a value outside the declared restrictions and keeps the default.
        self.warnings.append(
            f"{loc}: value of '{decl.name}' is not one of the values allowed by PROTO {proto.name}; "
            "default used"
        )
        values[decl.name] = copy_value(decl.typed_default)

    def _apply_hidden(self, root: Node, hidden: dict[str, Any], loc: SourceLocation) -> None:
        """Saved state of a PROTO instance overrides its body (Webots' hidden parameters)."""
        solids = _solids_preorder(root)
        for name, value in hidden.items():
            m = re.fullmatch(r"(translation|rotation|linearVelocity|angularVelocity)_(\d+)", name)
            if m and int(m.group(2)) < len(solids):
                solids[int(m.group(2))].fields[m.group(1)] = value
                continue
            m = re.fullmatch(r"(position[23]?)_(\d+)_(\d+)", name)
            if m and int(m.group(2)) < len(solids):
                joints = _joints_of(solids[int(m.group(2))])
                if int(m.group(3)) < len(joints):
                    joint = joints[int(m.group(3))]
                    kind = m.group(1)  # position, position2 or position3
                    params = joint.fields.get("jointParameters" + kind[len("position") :])
                    if isinstance(params, Node) and "position" in params.fields:
                        params.fields["position"] = value
                        continue
                    if kind in joint.fields:  # no parameters node: the joint's own hidden field
                        joint.fields[kind] = value
                        continue
            self.warnings.append(f"{loc}: hidden field '{name}' matches nothing in {root.proto_name}; ignored")

    # -- templates ---------------------------------------------------------------------------
    def render(self, proto: ParsedProto, values: dict[str, Any], raw: RawNode) -> RawNode:
        assert proto.template is not None
        if proto.template_language == "lua":
            raise ProtoError(
                f"{raw.location}: PROTO {proto.name} ({proto.path}) uses a legacy Lua template (%{{ }}%); "
                "only JavaScript templates are supported: use a JavaScript version of this PROTO"
            )
        try:
            import quickjs
        except ImportError as exc:
            raise ProtoError(
                f"{raw.location}: PROTO {proto.name} is procedural (JavaScript template) and needs the "
                f"'quickjs' package, which cannot be imported ({exc}); pip install quickjs"
            ) from None
        js_fields = ", ".join(
            f"{json.dumps(name)}: {{value: {self.js_value(values[name], decl.type)}, "
            f"defaultValue: {self.js_value(self.default_value(decl, proto), decl.type)}}}"
            for name, decl in proto.interface.items()
        )
        program = "\n".join(
            [
                JS_MODULES,
                "(function () {",
                f"const fields = {{{js_fields}}};",
                f"const context = {self.js_context(proto)};",
                "let ___vrml = '';",
                template_to_js(proto.template, proto),
                "return ___vrml;",
                "})()",
            ]
        )
        over_budget = ProtoError(
            f"{raw.location}: template of PROTO {proto.name} ({proto.path}) failed: the templates of this world "
            f"ran longer than {self.template_seconds:g} s in total"
        )
        left = self.template_seconds - self._template_spent
        if left <= 0:
            raise over_budget
        ctx = quickjs.Context()
        ctx.set_memory_limit(_JS_MEMORY_LIMIT)
        ctx.set_time_limit(min(_JS_TIME_LIMIT, left))  # (CPU seconds: at most the wall-clock time left)
        started = time.monotonic()
        try:
            text = ctx.eval(program)
        except Exception as exc:  # JSException, StackOverflow, interruption: all template failures
            # The JS stack points into our generated program, not the PROTO file: keep the message only.
            message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            if "interrupted" in message:
                if left < _JS_TIME_LIMIT:
                    raise over_budget from None
                message += f" (the template ran longer than {_JS_TIME_LIMIT} s)"
            raise ProtoError(
                f"{raw.location}: template of PROTO {proto.name} ({proto.path}) failed: {message}"
            ) from None
        finally:
            self._template_spent += time.monotonic() - started
        if self._template_spent > self.template_seconds:
            raise over_budget
        if not isinstance(text, str):
            raise ProtoError(f"{raw.location}: template of PROTO {proto.name} produced no VRML text")
        return parse_proto_body(text, f"{proto.path}[generated]")

    def js_context(self, proto: ParsedProto) -> str:
        world = Path(self.world_path)
        project = world.parent.parent if world.parent.name == "worlds" else world.parent
        if self._tmpdir is None:
            self._tmpdir = tempfile.gettempdir()
        home = self.resolver.webots_home
        ctx = {
            "world": self.world_path,
            "proto": proto.path,
            "project_path": str(project),
            "id": str(next(self._ids)),
            "coordinate_system": "ENU",
            "webots_version": {"major": WEBOTS_VERSION, "revision": 0},
            "webots_home": str(home) if home else "",
            "temporary_files_path": self._tmpdir,
            "temporary_fields_path": self._tmpdir,
            "os": "linux",
        }
        return json.dumps(ctx)

    def js_value(self, value: Any, vrml_type: str) -> str:
        """Webots' JavaScript representation of a field value."""
        if vrml_type.startswith("MF"):
            elem = schema.mf_element_type(vrml_type)
            items = value if isinstance(value, list) else []
            return "[" + ", ".join(self.js_value(v, elem) for v in items) + "]"
        if vrml_type == "SFNode":
            return "undefined" if value is None else self.js_node(value)
        if vrml_type == "SFBool":
            return "true" if value else "false"
        if vrml_type == "SFString":
            return json.dumps(value)
        if vrml_type in ("SFInt32", "SFFloat"):
            return js_number(value)
        keys = VEC_KEYS.get(vrml_type, "xyza")
        return "{" + ", ".join(f"{k}: {js_number(v)}" for k, v in zip(keys, value, strict=False)) + "}"

    def js_node(self, node: Node) -> str:
        proto = self._by_name.get(node.proto_name or "")
        if node.proto_fields is not None and proto is not None:
            parts = []
            for name, decl in proto.interface.items():
                default = "undefined" if decl.typed_default is None else self.js_value(decl.typed_default, decl.type)
                value = self.js_value(node.proto_fields.get(name), decl.type)
                parts.append(f"{json.dumps(name)}: {{value: {value}, defaultValue: {default}}}")
            return f"{{node_name: {json.dumps(proto.name)}, fields: {{{', '.join(parts)}}}}}"
        spec = schema.BASE_NODES[node.type_name]
        parts = [
            f"{json.dumps(name)}: {{value: {self.js_value(node.fields[name], fs.type)}, "
            f"defaultValue: {self.js_value(fs.default, fs.type)}}}"
            for name, fs in spec.fields.items()
        ]
        return f"{{node_name: {json.dumps(node.type_name)}, fields: {{{', '.join(parts)}}}}}"


# --------------------------------------------------------------------------------------------
# public API


def expand_world(
    parsed: ParsedWorld,
    world_path: str | os.PathLike[str] | None = None,
    proto_paths: Sequence[str | os.PathLike[str]] = (),
    *,
    resolver: ProtoResolver | None = None,
    template_seconds: float = TEMPLATE_SECONDS,
) -> World:
    """Expand every PROTO instance of a parsed world; the result holds base nodes only.

    ``template_seconds`` bounds the time all its JavaScript templates may run together.

    Raises:
        WebotsSyntaxError: a malformed value, unknown field or forbidden USE.
        ProtoNotFoundError: a physics-relevant PROTO cannot be found.
        ProtoError: any other PROTO expansion failure.
    """
    path = Path(world_path) if world_path is not None else None
    if resolver is None:
        resolver = ProtoResolver(path, proto_paths)
    warnings = list(parsed.warnings)
    expander = _Expander(resolver, str(path) if path is not None else parsed.path, warnings, template_seconds)
    scope = _Scope(
        parsed.path,
        path.parent if path is not None else None,
        _declared(parsed.externprotos, warnings),
        in_world=True,
    )
    nodes: list[Node] = []
    try:
        for raw in parsed.nodes:
            node = expander.expand_ref(raw, scope)
            if node is not None:
                nodes.append(node)
    except RecursionError:
        raise ProtoError(f"{parsed.path}: world nesting too deep to expand") from None
    for proto in resolver._parsed.values():
        for w in proto.warnings:
            if w not in warnings:
                warnings.append(w)
    return World(
        path=parsed.path,
        header=parsed.header,
        nodes=nodes,
        externprotos=[e.url for e in parsed.externprotos if not e.importable],
        importable_externprotos=[e.url for e in parsed.externprotos if e.importable],
        warnings=warnings,
    )


def load_world_text(
    text: str | bytes,
    path: str | os.PathLike[str] = "<string>",
    proto_paths: Sequence[str | os.PathLike[str]] = (),
) -> World:
    """Parse and expand world text; ``path`` names it in messages and anchors relative PROTO lookups."""
    parsed = parse_world(text, str(path))
    is_file_like = str(path) != "<string>"
    return expand_world(parsed, path if is_file_like else None, proto_paths)


def load_world(path: str | os.PathLike[str], proto_paths: Sequence[str | os.PathLike[str]] = ()) -> World:
    """Load a ``.wbt`` world and expand its PROTOs (see the module docstring for the search order).

    Raises:
        DualtwinError: the world file cannot be read.
        WebotsSyntaxError: malformed world or PROTO (message ``file:line:col: expected X, found Y``).
        ProtoNotFoundError: a physics-relevant PROTO was found nowhere.
        ProtoError: another PROTO expansion failure.
    """
    check_input_file(Path(path), "world")  # a folder or a pipe (which would block the read) is one error
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise DualtwinError(f"{path}: cannot read world: {exc.strerror or exc}") from None
    return load_world_text(data, path, proto_paths)
