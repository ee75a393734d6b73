"""Recursive-descent parser for Webots R2023b ``.wbt`` worlds and ``.proto`` files.

The parser produces a *raw* tree (:class:`RawNode`, :class:`RawUse`, untyped field values) that
keeps source offsets; :mod:`dualtwin.webots.protos` turns it into :class:`~dualtwin.webots.nodes.Node`
objects and expands PROTOs. Values of PROTO instances stay untyped here because their types are
only known once the PROTO file is found; values of base nodes and PROTO interface defaults are
converted (and so checked) right away, so type errors carry their exact location. The tokenizer is
:mod:`dualtwin.webots.lexer`.

Every error is a :class:`~dualtwin.webots.lexer.WebotsSyntaxError` whose message reads ``file:line:col: expected X,
found Y``; no other exception escapes :func:`parse_world`, :func:`parse_proto` or
:func:`parse_proto_body`, whatever the input.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import schema
from dualtwin.webots.lexer import Lexer, SourceText, Token, WebotsSyntaxError, clip, describe_token
from dualtwin.webots.nodes import SourceLocation

__all__ = [
    "MAX_DEPTH",
    "MAX_NODES",
    "ExternProto",
    "IsLink",
    "ListValue",
    "NullValue",
    "ParsedProto",
    "ParsedWorld",
    "ProtoFieldDecl",
    "RawField",
    "RawNode",
    "RawUse",
    "Scalars",
    "convert_value",
    "decode_source",
    "describe_value",
    "parse_proto",
    "parse_proto_body",
    "parse_world",
]

#: Deepest node nesting accepted; real worlds stay far below, and it keeps recursion bounded.
MAX_DEPTH = 100
#: Most nodes a world may hold, counted in each parsed file and again in the expanded world (where each USE
#: and IS is a copy, so nested DEF/USE or PROTOs multiply: ten levels of ten USEs are 10**10 nodes). Large
#: real worlds hold tens of thousands; past this, parsing or expanding would run for minutes and gigabytes.
MAX_NODES = 200_000

_KEYWORDS = frozenset(
    {"DEF", "USE", "IS", "NULL", "TRUE", "FALSE", "PROTO", "EXTERNPROTO", "IMPORTABLE", "hidden"}
)
_FIELD_KEYWORDS = frozenset(
    {"field", "unconnectedField", "hiddenField", "vrmlField", "deprecatedField", "exposedField"}
)

_WBT_HEADER = re.compile(r"#VRML_SIM \S+ utf8[ \t]*")
_PROTO_HEADER = re.compile(r"(?:#VRML_(?:SIM|OBJ) \S+ utf8|#VRML V2\.0 utf8)[ \t]*")
# Possessive, and no lazy group before `\s*`: spaces that two parts may both take made a long header comment
# line quadratic (a 300 kB '# a   ...   b' line hung the load). The line is stripped before matching.
_META = re.compile(r"#\s*+([A-Za-z][A-Za-z ]*+)\s*+:\s*+(.*)")


# --------------------------------------------------------------------------------------------
# raw tree


@dataclass(eq=False)
class IsLink:
    """``field IS protoField`` inside a PROTO body."""

    name: str
    location: SourceLocation


@dataclass(eq=False)
class Scalars:
    """A bracket-less value: one or more numbers, or a single string or boolean."""

    tokens: list[Token]
    location: SourceLocation


@dataclass(eq=False)
class NullValue:
    location: SourceLocation


@dataclass(eq=False)
class ListValue:
    """``[ ... ]``; items are tokens (numbers, strings, booleans), nodes or ``NULL``."""

    items: list[Any]
    location: SourceLocation


@dataclass(eq=False)
class RawField:
    name: str
    value: Any  # IsLink | Scalars | NullValue | ListValue | RawNode | RawUse
    location: SourceLocation
    start: int  # offset of the field name
    end: int  # offset just after the value
    typed: Any = None
    has_typed: bool = False


@dataclass(eq=False)
class RawNode:
    type_name: str
    def_name: str | None
    location: SourceLocation
    fields: dict[str, RawField] = field(default_factory=dict)
    hidden: dict[str, RawField] = field(default_factory=dict)
    start: int = 0  # offset of DEF or of the type name
    body_start: int = 0  # offset just after '{'
    end: int = 0  # offset just after '}'

    @property
    def is_base(self) -> bool:
        return self.type_name in schema.BASE_NODES


@dataclass(eq=False)
class RawUse:
    name: str
    target: RawNode
    location: SourceLocation
    start: int = 0
    end: int = 0


@dataclass(frozen=True)
class ExternProto:
    url: str
    location: SourceLocation
    importable: bool = False

    @property
    def name(self) -> str:
        """PROTO name = file name without ``.proto``, as Webots derives it."""
        base = self.url.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1]
        return base[:-6] if base.endswith(".proto") else base


@dataclass(eq=False)
class ParsedWorld:
    path: str
    header: str
    externprotos: list[ExternProto]
    nodes: list[RawNode | RawUse]
    warnings: list[str] = field(default_factory=list)


@dataclass(eq=False)
class ProtoFieldDecl:
    """One interface field: ``field SFVec3f translation 0 0 0``."""

    keyword: str
    type: str
    name: str
    default: Any  # raw value
    location: SourceLocation
    restrictions: list[Any] | None = None  # typed values (raw nodes for SFNode/MFNode)
    typed_default: Any = None  # converted default for non-node types


@dataclass(eq=False)
class ParsedProto:
    path: str
    header: str
    name: str
    location: SourceLocation
    externprotos: list[ExternProto]
    interface: dict[str, ProtoFieldDecl]
    body: RawNode | None  # None for a procedural PROTO (see ``template``)
    template: str | None = None  # body text between the outer braces, template tokens included
    template_offset: int = 0  # offset of ``template`` in the file, for error locations
    template_language: str | None = None  # "javascript" or "lua" when procedural
    metadata: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    text: str = ""

    def location_of(self, template_offset: int) -> SourceLocation:
        """Location in the PROTO file of an offset inside ``template``."""
        return SourceText(self.text, self.path).loc(self.template_offset + template_offset)


# --------------------------------------------------------------------------------------------
# value conversion (shared with the PROTO expander)


def describe_value(raw: Any) -> str:
    """Short description of a raw value for error messages."""
    if isinstance(raw, Scalars):
        tokens = raw.tokens
        if len(tokens) == 1:
            return describe_token(tokens[0])
        return f"{len(tokens)} numbers"
    if isinstance(raw, ListValue):
        return f"a list of {len(raw.items)} items"
    if isinstance(raw, NullValue):
        return "NULL"
    if isinstance(raw, RawNode):
        return f"node {raw.type_name}"
    if isinstance(raw, RawUse):
        return f"USE {raw.name}"
    if isinstance(raw, IsLink):
        return f"IS {raw.name}"
    return type(raw).__name__


def _is_number(item: Any) -> bool:
    return isinstance(item, Token) and item.kind == "number"


def _is_bool(item: Any) -> bool:
    return isinstance(item, Token) and item.kind == "ident" and item.text in ("TRUE", "FALSE")


def _is_string(item: Any) -> bool:
    return isinstance(item, Token) and item.kind == "string"


def _to_float(tok: Token, loc: SourceLocation, what: str) -> float:
    try:
        return float(tok.value)
    except OverflowError:
        raise WebotsSyntaxError(loc, what, f"out-of-range number {clip(tok.text)}") from None


def _count_desc(items: list[Any]) -> str:
    if all(_is_number(i) for i in items):
        return f"{len(items)} number" + ("" if len(items) == 1 else "s")
    bad = next(i for i in items if not _is_number(i))
    return describe_token(bad) if isinstance(bad, Token) else describe_value(bad)


def _convert_items(items: list[Any], sf_type: str, loc: SourceLocation, what: str) -> list[Any]:
    """Convert a flat item list to SF values of ``sf_type`` (several per list for MF types)."""
    if sf_type == "SFBool":
        for item in items:
            if not _is_bool(item):
                raise WebotsSyntaxError(loc, what, _desc_item(item))
        return [item.text == "TRUE" for item in items]
    if sf_type == "SFString":
        for item in items:
            if not _is_string(item):
                raise WebotsSyntaxError(loc, what, _desc_item(item))
        return [item.value for item in items]
    if sf_type == "SFInt32":
        out: list[Any] = []
        for item in items:
            if not _is_number(item) or not isinstance(item.value, int):
                raise WebotsSyntaxError(loc, what, _desc_item(item))
            if not -(2**31) <= item.value < 2**31:
                raise WebotsSyntaxError(loc, what, f"out-of-range integer {clip(item.text)}")
            out.append(item.value)
        return out
    size = schema.VECTOR_SIZES.get(sf_type, 1)
    if not all(_is_number(i) for i in items) or len(items) % size:
        raise WebotsSyntaxError(loc, what, _count_desc(items))
    floats = [_to_float(i, loc, what) for i in items]
    if size == 1:
        return floats
    return [tuple(floats[k : k + size]) for k in range(0, len(floats), size)]


def _desc_item(item: Any) -> str:
    return describe_token(item) if isinstance(item, Token) else describe_value(item)


def _type_desc(vrml_type: str) -> str:
    sf = schema.mf_element_type(vrml_type) if vrml_type.startswith("MF") else vrml_type
    size = schema.VECTOR_SIZES.get(sf)
    unit = {
        "SFBool": "TRUE or FALSE",
        "SFString": "a string",
        "SFInt32": "an integer",
        "SFFloat": "a number",
    }.get(sf, f"{size} numbers")
    if vrml_type.startswith("MF"):
        unit = f"values of {unit}" if size is None else f"a multiple of {size} numbers"
    return f"{vrml_type} ({unit})"


def convert_value(raw: Any, vrml_type: str) -> Any:
    """Typed Python value of a raw non-node value (see :mod:`dualtwin.webots.nodes` for types).

    Raises:
        WebotsSyntaxError: the value does not fit ``vrml_type``.
    """
    what = _type_desc(vrml_type)
    loc = getattr(raw, "location", SourceLocation("<value>", 0, 0))
    if vrml_type in ("SFNode", "MFNode"):
        raise WebotsSyntaxError(loc, what, describe_value(raw))
    if vrml_type.startswith("SF"):
        if not isinstance(raw, Scalars):
            raise WebotsSyntaxError(loc, what, describe_value(raw))
        values = _convert_items(raw.tokens, vrml_type, loc, what)
        if len(values) != 1:
            raise WebotsSyntaxError(loc, what, _count_desc(raw.tokens))
        return values[0]
    elem = schema.mf_element_type(vrml_type)
    if isinstance(raw, Scalars):
        values = _convert_items(raw.tokens, elem, loc, what)
        if len(values) != 1:  # without brackets an MF field holds exactly one value
            raise WebotsSyntaxError(loc, f"'[' or a single {elem} value", _count_desc(raw.tokens))
        return values
    if isinstance(raw, ListValue):
        return _convert_items(raw.items, elem, loc, what)
    raise WebotsSyntaxError(loc, what, describe_value(raw))


def check_node_value(raw: Any, vrml_type: str) -> None:
    """Shape check of an SFNode/MFNode raw value (nodes are converted by the expander)."""
    loc = getattr(raw, "location", SourceLocation("<value>", 0, 0))
    if isinstance(raw, IsLink):
        return
    if vrml_type == "SFNode":
        if not isinstance(raw, RawNode | RawUse | NullValue):
            raise WebotsSyntaxError(loc, "SFNode (a node or NULL)", describe_value(raw))
        return
    if isinstance(raw, RawNode | RawUse):
        return
    if not isinstance(raw, ListValue):
        raise WebotsSyntaxError(loc, "MFNode (a node or '[' nodes ']')", describe_value(raw))
    for item in raw.items:
        if not isinstance(item, RawNode | RawUse):
            raise WebotsSyntaxError(loc, "MFNode items (nodes)", _desc_item(item))


# --------------------------------------------------------------------------------------------
# parser


class _Parser:
    def __init__(self, text: str, path: str, *, in_proto: bool = False) -> None:
        self.src = SourceText(text, path)
        self.lex = Lexer(self.src)
        self.defs: dict[str, RawNode] = {}
        self.in_proto = in_proto  # IS links are legal only inside a PROTO body
        self.warnings: list[str] = []
        self._last_end = 0  # end offset of the last value parsed, for RawField/RawNode spans
        self._nodes = 0  # nodes parsed so far (MAX_NODES)

    # -- helpers -----------------------------------------------------------------------------
    def error(self, tok: Token, expected: str) -> WebotsSyntaxError:
        return self.src.error(tok.start, expected, describe_token(tok))

    def expect(self, kind: str, expected: str) -> Token:
        tok = self.lex.next()
        if tok.kind != kind:
            raise self.error(tok, expected)
        return tok

    def expect_ident(self, expected: str) -> Token:
        tok = self.lex.next()
        if tok.kind != "ident" or tok.text in _KEYWORDS:
            raise self.error(tok, expected)
        return tok

    def header(self, pattern: re.Pattern[str], expected: str) -> str:
        text = self.src.text
        line = text.split("\n", 1)[0].rstrip("\r")
        if not pattern.fullmatch(line):
            raise self.src.error(0, expected, f"'{clip(line)}'" if line else "an empty first line")
        return line.strip()

    # -- world -------------------------------------------------------------------------------
    def world(self) -> ParsedWorld:
        header = self.header(_WBT_HEADER, "header '#VRML_SIM R2023b utf8'")
        externs: list[ExternProto] = []
        nodes: list[RawNode | RawUse] = []
        while True:
            tok = self.lex.peek()
            if tok.kind == "eof":
                break
            if tok.kind == "ident" and tok.text in ("EXTERNPROTO", "IMPORTABLE"):
                externs.append(self.externproto())
                continue
            if tok.kind == "ident" and tok.text == "PROTO":
                raise self.error(tok, "a node (PROTO definitions belong in their own .proto file)")
            nodes.append(self.node(0))
        return ParsedWorld(self.src.path, header, externs, nodes, self.warnings)

    def externproto(self) -> ExternProto:
        tok = self.lex.next()
        importable = tok.text == "IMPORTABLE"
        if importable:
            tok = self.lex.next()
            if tok.kind != "ident" or tok.text != "EXTERNPROTO":
                raise self.error(tok, "EXTERNPROTO after IMPORTABLE")
        url = self.expect("string", 'the PROTO url string after EXTERNPROTO ("...proto")')
        if not url.value.strip():
            raise self.src.error(url.start, "a non-empty PROTO url", "an empty string")
        return ExternProto(url.value, self.src.loc(tok.start), importable)

    # -- nodes -------------------------------------------------------------------------------
    def node(self, depth: int) -> RawNode | RawUse:
        tok = self.lex.next()
        if depth > MAX_DEPTH:
            raise self.src.error(tok.start, f"node nesting of at most {MAX_DEPTH} levels", "deeper nesting")
        start = tok.start
        def_name: str | None = None
        if tok.kind == "ident" and tok.text == "USE":
            name = self.expect_ident("a DEF name after USE")
            target = self.defs.get(name.text)
            if target is None:
                raise self.src.error(
                    name.start, "the name of a preceding DEF", f"USE of undefined '{clip(name.text)}'"
                )
            if target.type_name in schema.USE_FORBIDDEN_TYPES:
                raise self.src.error(
                    tok.start,
                    "a node that may be USEd (Webots forbids USE of Solid-derived, joint and "
                    "joint-parameters nodes)",
                    f"USE of {target.type_name} '{name.text}'",
                )
            return RawUse(name.text, target, self.src.loc(tok.start), start, name.end)
        if tok.kind == "ident" and tok.text == "DEF":
            def_name = self.expect_ident("a name after DEF").text
            tok = self.lex.next()
        if tok.kind != "ident" or tok.text in _KEYWORDS or tok.text in schema.VRML_TYPES:
            raise self.error(tok, "a node type name")
        self._nodes += 1
        if self._nodes > MAX_NODES:
            raise self.src.error(tok.start, f"at most {MAX_NODES} nodes in a file", "more")
        self.expect("{", f"'{{' after node type {tok.text}")
        node = RawNode(tok.text, def_name, self.src.loc(tok.start), start=start)
        node.body_start = self.lex.resume_offset()
        spec = schema.BASE_NODES.get(tok.text)
        while True:
            ftok = self.lex.next()
            if ftok.kind == "}":
                self._last_end = ftok.end
                break
            if ftok.kind != "ident" or ftok.text in _KEYWORDS - {"hidden"}:
                raise self.error(ftok, f"a field name of {node.type_name} or '}}'")
            if ftok.text == "hidden":
                ntok = self.expect_ident("a hidden field name after 'hidden'")
                value = self.value(depth)
                raw = RawField(ntok.text, value, self.src.loc(ntok.start), ftok.start, self._value_end())
                if ntok.text in node.hidden:
                    self.warnings.append(f"{raw.location}: duplicate hidden field '{ntok.text}'; last one kept")
                node.hidden[ntok.text] = raw
                continue
            if spec is not None and ftok.text not in spec.fields:
                valid = ", ".join(spec.fields)
                raise self.src.error(
                    ftok.start, f"a field of {node.type_name} ({valid})", f"unknown field '{clip(ftok.text)}'"
                )
            value = self.value(depth)
            raw = RawField(ftok.text, value, self.src.loc(ftok.start), ftok.start, self._value_end())
            if spec is not None and not isinstance(value, IsLink):
                ftype = spec.fields[ftok.text].type
                if ftype in ("SFNode", "MFNode"):
                    check_node_value(value, ftype)
                else:
                    raw.typed = convert_value(value, ftype)
                    raw.has_typed = True
            if ftok.text in node.fields:
                self.warnings.append(f"{raw.location}: duplicate field '{ftok.text}'; last one kept")
            node.fields[ftok.text] = raw
        node.end = self._value_end()
        if def_name is not None:
            self.defs[def_name] = node
        return node

    def _value_end(self) -> int:
        return self._last_end

    def value(self, depth: int) -> Any:
        """A field value; types are checked later, once the field's type is known."""
        tok = self.lex.peek()
        loc = self.src.loc(tok.start)
        if tok.kind == "ident":
            if tok.text == "IS":
                self.lex.next()
                if not self.in_proto:
                    raise self.error(tok, "a value (IS is only allowed inside a PROTO body)")
                name = self.expect_ident("a PROTO field name after IS")
                self._last_end = name.end
                return IsLink(name.text, loc)
            if tok.text in ("TRUE", "FALSE"):
                self.lex.next()
                self._last_end = tok.end
                return Scalars([tok], loc)
            if tok.text == "NULL":
                self.lex.next()
                self._last_end = tok.end
                return NullValue(loc)
            if tok.text in ("DEF", "USE") or (
                tok.text not in _KEYWORDS and self.lex.peek(1).kind == "{"
            ):
                node = self.node(depth + 1)
                self._last_end = node.end
                return node
            raise self.error(tok, "a field value")
        if tok.kind == "number":
            tokens = []
            while self.lex.peek().kind == "number":
                tokens.append(self.lex.next())
            self._last_end = tokens[-1].end
            return Scalars(tokens, loc)
        if tok.kind == "string":
            self.lex.next()
            self._last_end = tok.end
            return Scalars([tok], loc)
        if tok.kind == "[":
            self.lex.next()
            items = self.items("]", depth)
            return ListValue(items, loc)
        raise self.error(tok, "a field value")

    def items(self, close: str, depth: int) -> list[Any]:
        """Items up to ``close`` (``]`` for MF values, ``}`` for field restrictions)."""
        items: list[Any] = []
        while True:
            tok = self.lex.peek()
            if tok.kind == close:
                self.lex.next()
                self._last_end = tok.end
                return items
            if tok.kind in ("number", "string") or (tok.kind == "ident" and tok.text in ("TRUE", "FALSE")):
                items.append(self.lex.next())
            elif tok.kind == "ident" and tok.text == "NULL":
                self.lex.next()
                items.append(NullValue(self.src.loc(tok.start)))
            elif tok.kind == "ident" and (
                tok.text in ("DEF", "USE") or (tok.text not in _KEYWORDS and self.lex.peek(1).kind == "{")
            ):
                items.append(self.node(depth + 1))
            else:
                raise self.error(tok, f"a value or '{close}'")

    # -- PROTO -------------------------------------------------------------------------------
    def proto(self) -> ParsedProto:
        header = self.header(_PROTO_HEADER, "header '#VRML_SIM R2023b utf8'")
        externs: list[ExternProto] = []
        while True:
            tok = self.lex.peek()
            if tok.kind == "ident" and tok.text in ("EXTERNPROTO", "IMPORTABLE"):
                externs.append(self.externproto())
                continue
            if tok.kind == "ident" and tok.text == "PROTO":
                break
            raise self.error(tok, "EXTERNPROTO or PROTO")
        proto_tok = self.lex.next()
        metadata = _metadata(self.src.text[: proto_tok.start])
        name = self.expect_ident("the PROTO name")
        self.expect("[", f"'[' opening the interface of PROTO {name.text}")
        interface: dict[str, ProtoFieldDecl] = {}
        while True:
            tok = self.lex.next()
            if tok.kind == "]":
                break
            if tok.kind != "ident" or tok.text not in _FIELD_KEYWORDS:
                raise self.error(tok, "'field', 'unconnectedField', 'hiddenField', 'vrmlField' or ']'")
            decl = self.field_decl(tok.text)
            if decl.name in interface:
                raise self.src.error(
                    tok.start, "each PROTO field declared once", f"duplicate field '{decl.name}'"
                )
            interface[decl.name] = decl
        brace = self.lex.peek()
        if brace.kind != "{":
            raise self.error(brace, f"'{{' opening the body of PROTO {name.text}")
        text = self.src.text
        rest = text[brace.end :]
        proto = ParsedProto(
            self.src.path, header, name.text, self.src.loc(proto_tok.start), externs, interface, None,
            metadata=metadata, warnings=self.warnings, text=text,
        )
        language = metadata.get("template language", "").strip().lower()
        if "%<" in rest or "%{" in rest:
            close = text.rfind("}")
            if close < brace.end:
                raise self.src.error(len(text), f"'}}' closing the body of PROTO {name.text}", "end of file")
            proto.template = text[brace.end : close]
            proto.template_offset = brace.end
            proto.template_language = (
                "lua" if language == "lua" or ("%<" not in rest and "%{" in rest) else "javascript"
            )
            return proto
        self.lex.next()
        self.defs = {}  # the body is its own DEF scope
        self.in_proto = True
        root = self.node(0)
        if isinstance(root, RawUse):
            raise self.src.error(root.start, "a node as PROTO body", f"USE {root.name}")
        self.expect("}", f"'}}' closing the body of PROTO {name.text} (a body holds one node)")
        self.expect("eof", f"end of file after the body of PROTO {name.text}")
        proto.body = root
        return proto

    def field_decl(self, keyword: str) -> ProtoFieldDecl:
        ttok = self.lex.next()
        if ttok.kind != "ident" or ttok.text not in schema.VRML_TYPES:
            raise self.error(ttok, "a field type (SFBool, SFInt32, SFFloat, SFVec2f, SFVec3f, ..., MFNode)")
        restrictions_raw: list[Any] | None = None
        if self.lex.peek().kind == "{":
            brace = self.lex.next()
            restrictions_raw = self.items("}", 0)
            rloc = self.src.loc(brace.start)
        name = self.expect_ident(f"a field name after {ttok.text}")
        default = self.value(0)  # in_proto is False here, so IS is rejected
        decl = ProtoFieldDecl(keyword, ttok.text, name.text, default, self.src.loc(name.start))
        if ttok.text in ("SFNode", "MFNode"):
            check_node_value(default, ttok.text)
            decl.restrictions = restrictions_raw
        else:
            decl.typed_default = convert_value(default, ttok.text)
            if restrictions_raw is not None:
                elem = schema.mf_element_type(ttok.text) if ttok.text.startswith("MF") else ttok.text
                decl.restrictions = _convert_items(
                    restrictions_raw, elem, rloc, f"restrictions of type {elem}"
                )
        return decl


def _metadata(prefix: str) -> dict[str, str]:
    meta: dict[str, str] = {}
    for line in prefix.splitlines()[1:]:
        m = _META.match(line.strip())
        if m:
            meta.setdefault(m.group(1).strip().lower(), m.group(2))
    return meta


def _guard(parser: _Parser, func: Any) -> Any:
    try:
        return func()
    except RecursionError:  # safety net: MAX_DEPTH normally stops first
        tok = parser.lex.peek() if parser.lex._buf else Token("eof", "", parser.lex.pos, parser.lex.pos)
        raise parser.src.error(tok.start, "a less deeply nested file", "too deep nesting") from None


def decode_source(data: bytes, path: str) -> str:
    """UTF-8 text of a file (BOM dropped); invalid bytes become a located syntax error."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        good = data[: exc.start].decode("utf-8", errors="replace")
        raise SourceText(good, path).error(
            len(good), "UTF-8 text", f"byte 0x{data[exc.start]:02x}"
        ) from None
    return text[1:] if text.startswith("\ufeff") else text


def _as_text(source: str | bytes, path: str) -> str:
    if isinstance(source, bytes):
        return decode_source(source, path)
    return source[1:] if source.startswith("\ufeff") else source


def parse_world(source: str | bytes, path: str = "<string>") -> ParsedWorld:
    """Parse a ``.wbt`` world into a raw tree (PROTO instances not expanded)."""
    parser = _Parser(_as_text(source, path), path)
    result: ParsedWorld = _guard(parser, parser.world)
    return result


def parse_proto(source: str | bytes, path: str = "<string>") -> ParsedProto:
    """Parse a ``.proto`` file: header, EXTERNPROTOs, interface and (non-procedural) body."""
    parser = _Parser(_as_text(source, path), path)
    result: ParsedProto = _guard(parser, parser.proto)
    return result


def parse_proto_body(text: str, path: str) -> RawNode:
    """Parse the VRML produced by a procedural PROTO template: exactly one node."""
    parser = _Parser(text, path, in_proto=True)

    def run() -> RawNode:
        root = parser.node(0)
        if isinstance(root, RawUse):
            raise parser.src.error(root.start, "a node as PROTO body", f"USE {root.name}")
        parser.expect("eof", "end of the generated PROTO body (a body holds one node)")
        return root

    result: RawNode = _guard(parser, run)
    return result
