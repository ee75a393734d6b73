"""A fast reader of ROS 2 messages (CDR, little-endian) for the fields an import needs.

``mcap_ros2``'s decoder is the reference, and the fallback: it builds a Python object per message and unpacks
every array element one ``struct`` call at a time, which costs ~50 µs for an ``nav_msgs/msg/Odometry`` (two
36-element covariances) and makes a 10-minute, 100 Hz bag take longer than the goal of the importer. This
reader compiles each message definition once into closures that unpack arrays in one call and stop after the
last top-level field a mapping uses (an Odometry's twist is never decoded when only its pose is mapped).

It covers what ROS 2 ``.msg`` definitions (``ros2msg`` schemas) use: the primitive types, strings, fixed
arrays, bounded and unbounded sequences, nested messages, constants (ignored) and default values (ignored).
Anything else (``wstring``, IDL schemas, big-endian payloads) returns None from :func:`compile_schema`
or :meth:`MessageReader.read`, and the caller uses ``mcap_ros2``. A test checks both agree on real bags.

Wire rules (OMG XCDR1, as ROS 2 middlewares write it): a 4-byte encapsulation header (``00 01`` for
little-endian), then fields in order, each primitive aligned to its size (at most 8) from the end of the
header; a string is a uint32 length counting its NUL terminator, then the bytes; a sequence is a uint32
count, then its elements.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from typing import Any

Reader = Callable[[memoryview, int], tuple[Any, int]]

PRIMITIVES: dict[str, str] = {
    "bool": "?", "byte": "B", "char": "B", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H",
    "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d",
}
_UINT32 = struct.Struct("<I")
_FIELD = re.compile(r"^([A-Za-z_][\w/]*)(<=\d+)?(\[(<=)?(\d*)\])?$")
_CONSTANT = re.compile(r"^\S+\s+[A-Za-z_]\w*\s*=")


class UnsupportedSchema(Exception):
    """The definition uses something this reader does not handle; decode with ``mcap_ros2`` instead."""


def _normalise(name: str, package: str) -> str:
    parts = name.split("/")
    if len(parts) == 3:  # pkg/msg/Type
        return f"{parts[0]}/{parts[2]}"
    if len(parts) == 1:
        return "std_msgs/Header" if name == "Header" else f"{package}/{name}"
    return name


def parse_definitions(name: str, text: str) -> dict[str, list[tuple[str, str]]]:
    """``{type: [(field type, field name), ...]}`` for the schema's own type and every dependency."""
    root = _normalise(name, "")
    types: dict[str, list[tuple[str, str]]] = {}
    current, package = root, root.split("/")[0]
    types[current] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if set(line) == {"="}:
            current = ""
            continue
        if line.startswith("MSG:"):
            current = _normalise(line[4:].strip(), "")
            package = current.split("/")[0]
            types[current] = []
            continue
        if not current:
            raise UnsupportedSchema(f"a definition section does not start with 'MSG:': {line!r}")
        if _CONSTANT.match(line):
            continue
        tokens = line.split()
        if len(tokens) < 2:
            raise UnsupportedSchema(f"cannot read field line {line!r}")
        match = _FIELD.match(tokens[0])
        if not match:
            raise UnsupportedSchema(f"cannot read field type {tokens[0]!r}")
        base = match.group(1)
        if base not in PRIMITIVES and base != "string":
            base = _normalise(base, package)
        array = match.group(3) or ""
        types[current].append((base + array, tokens[1]))
    return types


def _primitive(fmt: str) -> Reader:
    single = struct.Struct("<" + fmt)
    size = single.size

    def read(buf: memoryview, off: int) -> tuple[Any, int]:
        off += -off % size
        return single.unpack_from(buf, off)[0], off + size

    return read


def _string(buf: memoryview, off: int) -> tuple[str, int]:
    off += -off % 4
    (length,) = _UINT32.unpack_from(buf, off)
    start = off + 4
    if start + length > len(buf):
        raise struct.error("string runs past the end of the message")
    return bytes(buf[start:start + max(length - 1, 0)]).decode("utf-8", "replace"), start + length


def _compile_type(base: str, types: dict[str, list[tuple[str, str]]], cache: dict[str, Reader]) -> Reader:
    if base in PRIMITIVES:
        return _primitive(PRIMITIVES[base])
    if base == "string":
        return _string
    if base not in types:
        raise UnsupportedSchema(f"no definition for {base!r}")
    if base not in cache:
        cache[base] = _struct_reader(types[base], types, cache, None)
    return cache[base]


def _array_reader(base: str, count: int | None, types: dict[str, list[tuple[str, str]]],
                  cache: dict[str, Reader]) -> Reader:
    """A fixed array (``count``) or a sequence (``count`` None): primitives unpack in one call."""
    if base in PRIMITIVES:
        fmt = PRIMITIVES[base]
        size = struct.calcsize(fmt)

        def read_primitives(buf: memoryview, off: int) -> tuple[Any, int]:
            n = count
            if n is None:
                off += -off % 4
                (n,) = _UINT32.unpack_from(buf, off)
                off += 4
            if n == 0:
                return [], off
            off += -off % size
            values = struct.unpack_from(f"<{n}{fmt}", buf, off)
            return list(values), off + n * size

        return read_primitives
    if base == "string":
        return _string_array_reader(count)
    element = _compile_type(base, types, cache)

    def read_elements(buf: memoryview, off: int) -> tuple[Any, int]:
        n = count
        if n is None:
            off += -off % 4
            (n,) = _UINT32.unpack_from(buf, off)
            off += 4
        out = []
        for _ in range(n):
            value, off = element(buf, off)
            out.append(value)
        return out, off

    return read_elements


def _string_array_reader(count: int | None) -> Reader:
    """Strings in a loop without a call each; a list equal to the previous message's is returned as is.

    A ``JointState`` repeats the same joint names in every message: comparing the bytes is cheaper than
    decoding them, and handing back the same list lets the importer reuse its name lookup.
    """
    last: list[Any] = [-1, b"", []]  # offset, bytes, value

    def read(buf: memoryview, off: int) -> tuple[Any, int]:
        start = off
        size = len(last[1])
        if start == last[0] and size and buf[start:start + size] == last[1]:
            return last[2], start + size
        n = count
        if n is None:
            off += -off % 4
            (n,) = _UINT32.unpack_from(buf, off)
            off += 4
        out = []
        unpack = _UINT32.unpack_from
        for _ in range(n):
            off += -off % 4
            (length,) = unpack(buf, off)
            begin = off + 4
            off = begin + length
            if off > len(buf):
                raise struct.error("string runs past the end of the message")
            out.append(bytes(buf[begin:off - 1]).decode("utf-8", "replace") if length else "")
        last[:] = [start, bytes(buf[start:off]), out]
        return out, off

    return read


def _field_reader(spec: str, types: dict[str, list[tuple[str, str]]], cache: dict[str, Reader]) -> Reader:
    if spec == "wstring" or spec.startswith("wstring"):
        raise UnsupportedSchema("wstring fields")
    if "[" in spec:
        base, rest = spec.split("[", 1)
        bound = rest.rstrip("]")
        count = int(bound) if bound and not bound.startswith("<=") else None
        return _array_reader(base, count, types, cache)
    return _compile_type(spec, types, cache)


def _struct_reader(fields: list[tuple[str, str]], types: dict[str, list[tuple[str, str]]],
                   cache: dict[str, Reader], stop_after: int | None) -> Reader:
    readers = [(name, _field_reader(spec, types, cache)) for spec, name in fields]
    if stop_after is not None:
        readers = readers[:stop_after + 1]
    if not fields:
        # An empty message is one uint8 on the wire (the IDL mapping of ROS 2 adds a dummy member).
        readers = [("structure_needs_at_least_one_member", _primitive("B"))]

    def read(buf: memoryview, off: int) -> tuple[dict[str, Any], int]:
        out: dict[str, Any] = {}
        for name, reader in readers:
            out[name], off = reader(buf, off)
        return out, off

    return read


class MessageReader:
    """Decodes the top-level fields a mapping needs, as nested dicts and lists."""

    def __init__(self, read: Reader) -> None:
        self._read = read

    def read(self, data: bytes) -> dict[str, Any] | None:
        """The decoded prefix of the message; None for a payload this reader does not handle (big-endian).

        Raises:
            struct.error: The payload is shorter than its definition says (a corrupt message).
        """
        if len(data) < 4 or data[1] != 1:
            return None
        value, _ = self._read(memoryview(data)[4:], 0)
        return value  # type: ignore[no-any-return]


def compile_schema(name: str, text: str, needed: set[str]) -> MessageReader | None:
    """A reader for schema ``name`` that decodes through the last of the ``needed`` top-level fields.

    Returns None when the definition uses anything unsupported, or a needed field is not in it (the
    reference decoder then reports the problem in its own terms).
    """
    try:
        types = parse_definitions(name, text)
        root = types[_normalise(name, "")]
        names = [field for _, field in root]
        if not needed <= set(names):
            return None
        last = max(names.index(n) for n in needed) if needed else 0
        return MessageReader(_struct_reader(root, types, {}, last))
    except (UnsupportedSchema, KeyError, ValueError, struct.error):
        return None
