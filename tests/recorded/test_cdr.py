"""The fast CDR reader agrees with mcap_ros2's decoder (the reference) on real bags."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.recorded.cdr import compile_schema, parse_definitions

# A definition with what real ones use: constants, defaults, comments, fixed arrays, bounded sequences and
# strings, nested sequences of messages, every primitive width (so alignment is exercised).
ODD_DEF = """# leading comment
uint8 MODE_A=1
uint8 MODE_B = 2
byte flag
string<=8 label
int16[3] small
float32 gain 1.5
pkg/Sample[] samples
Sample[<=4] bounded
uint64 count
bool done
================================================================================
MSG: pkg/Sample
int8 tag
float64 value
string name
uint32[] ids
"""


def _as_plain(value: Any) -> Any:
    """A decoded message (objects or dicts) as plain dicts and lists, to compare the two decoders."""
    if isinstance(value, dict):
        return {k: _as_plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_as_plain(v) for v in value]
    if hasattr(value, "__slots__"):
        return {k: _as_plain(getattr(value, k)) for k in value.__slots__}
    if isinstance(value, bytes):
        return list(value)
    return value


def _decode_both(path: Path) -> list[tuple[dict, dict]]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    pairs = []
    with open(path, "rb") as handle:
        for schema, channel, message in make_reader(handle).iter_messages():
            reference = DecoderFactory().decoder_for(channel.message_encoding, schema)
            definitions = parse_definitions(schema.name, schema.data.decode())
            fields = {name for _, name in definitions[next(iter(definitions))]}
            fast = compile_schema(schema.name, schema.data.decode(), fields)
            assert fast is not None and reference is not None
            pairs.append((fast.read(message.data), _as_plain(reference(message.data))))
    return pairs


def test_joint_state_and_odometry_decode_like_the_reference(tmp_path: Path,
                                                           write_bag: Callable[..., Path]) -> None:
    t = np.arange(0.0, 0.2, 0.01)
    joints = {"a": t, "a_much_longer_joint_name": -t, "c": 2 * t}
    bag = write_bag(tmp_path / "b.mcap", t, joints, odom=(t, 0.5 * t))
    pairs = _decode_both(bag)
    assert len(pairs) == 2 * t.size
    for fast, reference in pairs:
        assert fast == reference


def test_odd_definition_decodes_like_the_reference(tmp_path: Path) -> None:
    from mcap_ros2.writer import Writer

    messages = [
        {"flag": 7, "label": "ab", "small": [1, -2, 3], "gain": 0.25, "count": 2**40 + 3, "done": True,
         "samples": [{"tag": -1, "value": 1.5, "name": "x", "ids": [1, 2, 3]},
                     {"tag": 2, "value": -2.0, "name": "", "ids": []}],
         "bounded": [{"tag": 0, "value": 0.0, "name": "yz", "ids": [9]}]},
        {"flag": 0, "label": "", "small": [0, 0, 0], "gain": 1.5, "count": 0, "done": False,
         "samples": [], "bounded": []},
    ]
    with open(tmp_path / "odd.mcap", "wb") as handle:
        writer = Writer(handle)
        schema = writer.register_msgdef("pkg/msg/Odd", ODD_DEF)
        for k, msg in enumerate(messages):
            writer.write_message("/odd", schema, msg, log_time=k + 1)
        writer.finish()
    pairs = _decode_both(tmp_path / "odd.mcap")
    assert [fast for fast, _ in pairs] == [reference for _, reference in pairs]
    assert pairs[0][0]["samples"][0]["ids"] == [1, 2, 3] and pairs[0][0]["count"] == 2**40 + 3


def test_only_the_needed_prefix_is_decoded_and_unsupported_falls_back() -> None:
    import struct

    payload = b"\x00\x01\x00\x00" + struct.pack("<iI", 5, 2) + struct.pack("<2d", 1.0, 2.0)
    reader = compile_schema("pkg/msg/T", "int32 a\nfloat64[] b\nstring c\n", {"a"})
    assert reader is not None and reader.read(payload) == {"a": 5}  # b and c are never read
    reader = compile_schema("pkg/msg/T", "int32 a\nfloat64[] b\nstring c\n", {"b"})
    assert reader is not None and reader.read(payload) == {"a": 5, "b": [1.0, 2.0]}
    assert reader.read(b"\x00\x00\x00\x00" + payload[4:]) is None  # big-endian: the reference decodes it
    with pytest.raises(struct.error):
        reader.read(payload[:10])  # cut short: the importer reports a corrupt bag
    assert compile_schema("pkg/msg/T", "wstring w\n", {"w"}) is None
    assert compile_schema("pkg/msg/T", "int32 a\n", {"missing"}) is None
