"""ROS 2 bags in MCAP, written by the real mcap-ros2 writer with real message definitions."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

import dualtwin.robots as robots_pkg
from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.recorded import import_mcap
from tests.support.ros_messages import JOINT_STATE_DEF, ODOMETRY_DEF

PIONEER_SUITE = Path(robots_pkg.__file__).parent / "pioneer3at" / "suite.json"
WHEELS = ["front_left_wheel", "front_right_wheel", "back_left_wheel", "back_right_wheel"]


def _pole(t: np.ndarray, i: int) -> np.ndarray:
    return 0.1 * (i + 1) * np.sin(3 * t)


def _cartpole_bags(folder: Path, bags: Path) -> None:
    shutil.copytree(bags, folder)


CARTPOLE_MAPPING = {
    "files": "bags/scenario_*.mcap",
    "channels": [
        {"name": "pole_angle_rad", "topic": "/joint_states", "field": "position", "element": "pole_hinge",
         "unit": "rad"},
        {"name": "cart_pos_m", "topic": "/odom", "field": "pose.pose.position.x", "unit": "m"},
    ],
}


def _mapping(folder: Path, data: dict) -> Path:
    path = folder / "bag_mapping.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_one_bag_per_scenario(tmp_path: Path, cartpole_suite: Path, cartpole_bags: Path,
                              snapshot: Callable[[Path], dict[str, bytes]]) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    mapping = _mapping(tmp_path, CARTPOLE_MAPPING)
    run = import_mcap(mapping, cartpole_suite, "cartpole", tmp_path / "run")
    loaded = load_run(run)
    assert loaded.kind == "recorded" and set(loaded.channels) == {"pole_angle_rad", "cart_pos_m"}
    for i, entry in enumerate(loaded.scenarios):
        series = loaded.series(entry.id)
        t = series["pole_angle_rad"].t
        assert t[0] == pytest.approx(0.032)
        duration = json.loads(cartpole_suite.read_text())["scenarios"][i]["duration_s"]
        inside = t <= duration  # the last grid point may lie past the last sample: it holds that sample
        assert np.count_nonzero(~inside) <= 1
        np.testing.assert_allclose(series["pole_angle_rad"].y[inside], _pole(t, i)[inside], atol=5e-4)
        np.testing.assert_allclose(series["cart_pos_m"].y[inside], 0.05 * t[inside], atol=1e-6)
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["format"] == "mcap" and manifest["time"]["stamp"] == "log_time"
    assert manifest["scenarios"][0]["raw"] == ["scenarios/00_Step_Response/raw_joint_states.tsv",
                                               "scenarios/00_Step_Response/raw_odom.tsv"]
    assert [s["path"] for s in manifest["sources"]] == [f"bags/scenario_{i}.mcap" for i in range(6)]
    # Same bags, same bytes.
    assert snapshot(run) == snapshot(import_mcap(mapping, cartpole_suite, "cartpole", tmp_path / "again"))


def test_time_ranges_in_one_bag_with_yaw_and_joint_names(tmp_path: Path, write_bag: Callable[..., Path]) -> None:
    scenarios = json.loads(PIONEER_SUITE.read_text())["scenarios"]
    total = sum(sc["duration_s"] + 1.0 for sc in scenarios)
    t = np.arange(0.0, total, 0.01)
    heading = np.unwrap(np.angle(np.exp(1j * 0.8 * t)))  # turns past +-pi: yaw comes back wrapped
    wheels = {name: (k + 1) * 0.5 * t for k, name in enumerate(WHEELS)}
    write_bag(tmp_path / "drive.mcap", t, wheels, odom=(0.3 * t, heading))
    ranges, start = [], 0.0
    for sc in scenarios:
        ranges.append({"start_s": start, "end_s": start + sc["duration_s"]})
        start += sc["duration_s"] + 1.0
    mapping = _mapping(tmp_path, {
        "files": "drive.mcap", "scenarios": ranges, "stamp": "header",
        "channels": [
            {"name": "forward_m", "topic": "/odom", "field": "pose.pose.position.x", "unit": "cm", "scale": 100},
            {"name": "heading_rad", "topic": "/odom", "field": "pose.pose.orientation", "angle": "yaw",
             "unit": "rad"},
            {"name": "left_wheel_rad", "source": "onboard", "topic": "/joint_states", "field": "position",
             "element": "back_left_wheel", "unit": "rad", "scale": -1},
        ]})
    run = load_run(import_mcap(mapping, PIONEER_SUITE, "pioneer3at", tmp_path / "run"))
    for entry, span in zip(run.scenarios, ranges, strict=True):
        series = run.series(entry.id)
        keep = series["forward_m"].t <= span["end_s"] - span["start_s"]  # the range ends the samples
        ts = series["forward_m"].t[keep]
        series = {k: type(v)(t=v.t[keep], y=v.y[keep]) for k, v in series.items()}
        absolute = ts + span["start_s"]
        np.testing.assert_allclose(series["forward_m"].y, 0.3 * absolute, atol=1e-6)  # cm * 100 -> m
        np.testing.assert_allclose(series["onboard/left_wheel_rad"].y, -1.5 * absolute, atol=1e-6)
        expected = np.angle(np.exp(1j * 0.8 * absolute))
        inside = np.abs(np.abs(expected) - math.pi) > 0.05  # away from the wrap, interpolation is exact enough
        np.testing.assert_allclose(series["heading_rad"].y[inside], expected[inside], atol=1e-3)


@pytest.mark.parametrize("case, message", [
    ("topic", r"no topic '/imu' in the bag \(it has: /joint_states, /odom\)"),
    ("element", r"topic /joint_states, message 0: no entry 'pole' in its name list"),
    ("field", r"topic /odom, message 0: the message has no field 'pos'"),
    ("not_number", r"the value is not a number but list"),
    ("garbage", r"scenario_2.mcap: not an MCAP file"),
    ("empty", r"scenario_2.mcap: not an MCAP file"),
    ("truncated", r"scenario_2.mcap: cannot read the bag"),
    ("directory", r"scenario_2.mcap: is a directory"),
    ("ranges", r"time ranges cut one bag into scenarios, but files gives 6"),
    ("unit", r"unit 'deg' cannot be converted to the binding's 'm'"),
    # A range end of 1e308 s passed validation, then overflowed turning into integer nanoseconds (traceback).
    ("range_end", r"bag_mapping.yaml: \$.scenarios\[0\].end_s: Input should be less than or equal to"),
    # An index into a field that is a message: a KeyError, reported as a corrupt bag before.
    ("index_of_message", r"topic /joint_states, message 0: no entry 1 in the field"),
])
def test_bad_bags_are_one_clear_error(tmp_path: Path, cartpole_suite: Path, cartpole_bags: Path,
                                      case: str, message: str) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    data = json.loads(json.dumps(CARTPOLE_MAPPING))
    bag = tmp_path / "bags" / "scenario_2.mcap"
    if case == "topic":
        data["channels"][1]["topic"] = "/imu"
    elif case == "element":
        data["channels"][0]["element"] = "pole"
    elif case == "field":
        data["channels"][1]["field"] = "pose.pos.x"
    elif case == "not_number":
        del data["channels"][0]["element"]
    elif case == "garbage":
        bag.write_bytes(bytes(range(256)) * 8)
    elif case == "empty":
        bag.write_bytes(b"")
    elif case == "truncated":
        bag.write_bytes(bag.read_bytes()[: bag.stat().st_size // 2])
    elif case == "directory":
        bag.unlink()
        bag.mkdir()
    elif case == "ranges":
        data["scenarios"] = [{"start_s": 0, "end_s": 1}] * 6
    elif case == "unit":
        data["channels"][1]["unit"] = "deg"
    elif case == "index_of_message":
        data["channels"][0] = {"name": "pole_angle_rad", "topic": "/joint_states", "field": "header", "index": 1,
                               "unit": "rad"}
    elif case == "range_end":
        data["files"] = "bags/scenario_0.mcap"
        data["scenarios"] = [{"start_s": 0, "end_s": 1e308}] + [{"start_s": 0, "end_s": 1}] * 5
    with pytest.raises(DualtwinError, match=message):
        import_mcap(_mapping(tmp_path, data), cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_header_stamps_that_go_backwards(tmp_path: Path, cartpole_suite: Path, cartpole_bags: Path,
                                         write_bag: Callable[..., Path]) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    t = np.arange(0.0, 1.0, 0.01)
    header = t.copy()
    header[50] = header[10]  # a clock jump in the header stamps; the bag's log times still increase
    write_bag(tmp_path / "bags" / "scenario_4.mcap", t, {"pole_hinge": 0 * t}, header_t_s=header)
    data = {**CARTPOLE_MAPPING, "stamp": "header", "channels": CARTPOLE_MAPPING["channels"][:1]}
    with pytest.raises(DualtwinError, match=r"scenario_4.mcap: topic /joint_states, message 50: stamps must increase"):
        import_mcap(_mapping(tmp_path, data), cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_nan_in_a_bag_makes_the_scenario_unstable(tmp_path: Path, cartpole_suite: Path, cartpole_bags: Path,
                                                  write_bag: Callable[..., Path]) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    t = np.arange(0.0, 4.0 + 1e-9, 0.01)
    pole = np.sin(t)
    pole[150] = np.nan  # 1.5 s
    write_bag(tmp_path / "bags" / "scenario_4.mcap", t, {"pole_hinge": pole}, odom=(0 * t, 0 * t))
    run = import_mcap(_mapping(tmp_path, CARTPOLE_MAPPING), cartpole_suite, "cartpole", tmp_path / "run")
    record = json.loads((run / "manifest.json").read_text())["scenarios"][4]
    assert record["status"] == "unstable" and record["steps"] == 46  # grid points before 1.5 s
    assert "topic /joint_states, message 150" in record["failure"]["message"]
    assert load_run(run).series(record["id"])["pole_angle_rad"].t[-1] < 1.5


def test_messages_stored_out_of_log_time_order_are_sorted(tmp_path: Path, cartpole_suite: Path,
                                                          cartpole_bags: Path, write_bag: Callable[..., Path]) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    t = np.arange(0.0, 1.0 + 1e-9, 0.01)
    order = np.r_[np.arange(50, 101), np.arange(0, 50)]  # the second half written first
    write_bag(tmp_path / "bags" / "scenario_3.mcap", t[order], {"pole_hinge": np.sin(t[order])},
              odom=(t[order], 0 * t))
    run = load_run(import_mcap(_mapping(tmp_path, CARTPOLE_MAPPING), cartpole_suite, "cartpole", tmp_path / "run"))
    series = run.series("03_Step_Response_3")["pole_angle_rad"]
    np.testing.assert_allclose(series.y[series.t <= 1.0], np.sin(series.t[series.t <= 1.0]), atol=1e-4)


def _rewrite_bag(source: Path, target: Path, compression: str = "none",
                 schema_text: dict[str, str] | None = None) -> bytes:
    """The messages of ``source`` written again with the plain MCAP writer: another compression, or a topic's
    message definition replaced (the payloads stay those the real definition encoded)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    with open(source, "rb") as handle:
        records = [(schema.name, schema.data.decode(), channel.topic, message.log_time, message.data)
                   for schema, channel, message in make_reader(handle).iter_messages()]
    with open(target, "wb") as handle:
        writer = Writer(handle, compression=CompressionType[compression.upper()])
        writer.start("ros2", "test")
        channels: dict[str, int] = {}
        for seq, (name, text, topic, log_time, data) in enumerate(records):
            if topic not in channels:
                text = (schema_text or {}).get(topic, text)
                channels[topic] = writer.register_channel(
                    topic, "cdr", writer.register_schema(name, "ros2msg", text.encode()))
            writer.add_message(channels[topic], log_time, data, log_time, seq)
        writer.finish()
    return target.read_bytes()


def _corrupt_first_frame(data: bytes, magic: bytes) -> bytes:
    """The bag with bytes of its first compressed chunk's payload overwritten (a disk or copy error)."""
    at = data.index(magic) + 16
    return data[:at] + b"\xff" * 16 + data[at + 16:]


@pytest.mark.parametrize(("case", "message"), [
    # The message definition stored in the bag is its own text: mcap_ros2's parser failed on these with
    # NameError, InvalidFieldDefinition and InvalidResourceName tracebacks.
    ("definition_type", r"topic /odom: cannot parse its message definition 'nav_msgs/msg/Odometry' \(NameError"),
    ("definition_line", r"topic /joint_states: cannot parse its message definition 'sensor_msgs/msg/JointState'"),
    ("definition_section", r"topic /odom: cannot parse its message definition"),
    # A definition the parser accepts but the decoder cannot read (NotImplementedError for wstring).
    ("wstring", r"topic /joint_states, message 0: cannot decode it with its definition 'sensor_msgs/msg/JointState'"),
    # Corrupt compressed chunks: ZstdError and lz4's RuntimeError came out as tracebacks.
    ("zstd", r"scenario_2.mcap: cannot read the bag \(truncated or corrupt\?"),
    ("lz4", r"scenario_2.mcap: cannot read the bag \(truncated or corrupt\?"),
])
def test_hostile_bag_contents_are_one_clear_error(tmp_path: Path, cartpole_suite: Path, cartpole_bags: Path,
                                                  case: str, message: str) -> None:
    _cartpole_bags(tmp_path / "bags", cartpole_bags)
    bag = tmp_path / "bags" / "scenario_2.mcap"
    source = tmp_path / "source.mcap"
    shutil.move(bag, source)
    if case == "definition_type":
        _rewrite_bag(source, bag, schema_text={"/odom": ODOMETRY_DEF.replace("float64 y\n", "char std_msgs/Header\n", 1)})
    elif case == "definition_line":
        _rewrite_bag(source, bag, schema_text={"/joint_states": JOINT_STATE_DEF.replace("float64[] position",
                                                                                         "float64", 1)})
    elif case == "definition_section":
        _rewrite_bag(source, bag, schema_text={"/odom": ODOMETRY_DEF.replace("MSG: geometry_msgs/Point", "MSG: x/y/z/w", 1)})
    elif case == "wstring":
        _rewrite_bag(source, bag, schema_text={"/joint_states": JOINT_STATE_DEF.replace("string frame_id",
                                                                                         "wstring frame_id", 1)})
    elif case == "zstd":
        bag.write_bytes(_corrupt_first_frame(_rewrite_bag(source, bag, "zstd"), b"\x28\xb5\x2f\xfd"))
    elif case == "lz4":
        bag.write_bytes(_corrupt_first_frame(_rewrite_bag(source, bag, "lz4"), b"\x04\x22\x4d\x18"))
    source.unlink()
    with pytest.raises(DualtwinError, match=message) as info:
        import_mcap(_mapping(tmp_path, CARTPOLE_MAPPING), cartpole_suite, "cartpole", tmp_path / "run")
    assert "\n" not in str(info.value)  # one line at the CLI, whatever the parser's own message holds
    assert not (tmp_path / "run").exists()
