"""ROS 2 bags in MCAP, read with the ``mcap`` and ``mcap-ros2-support`` packages.

A :class:`~dualtwin.recorded.mapping.BagMapping` names, per run channel, a topic and a message field, with an
array element picked by name (``sensor_msgs/msg/JointState``: the ``position`` of the joint whose entry in
``name`` matches) or index, and a quaternion turned into roll, pitch or yaw (``nav_msgs/msg/Odometry``:
``pose.pose.orientation`` → yaw). Scenarios are one bag each, or time ranges of one bag.

ROS time stamps are nanoseconds of whatever clock the robot ran (usually wall-clock). Only differences are
used: a scenario's time 0 is the start of its range (measured from the bag's first message on a mapped topic)
or, with one bag per scenario, that bag's first message on a mapped topic. Stamps are subtracted as integers
before they become seconds, so nothing is lost to float rounding of epoch values.
"""

from __future__ import annotations

import operator
import re
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import check_input_file
from dualtwin.errors import DualtwinError
from dualtwin.geometry import rpy_from_quat
from dualtwin.recorded.build import (
    FloatArray,
    RawLog,
    Recording,
    ScenarioRecording,
    Trace,
    channel_factor,
    ticker,
    write_recording,
)
from dualtwin.recorded.cdr import MessageReader, compile_schema
from dualtwin.recorded.mapping import BagChannel, BagMapping
from dualtwin.recorded.table import mapped_inputs
from dualtwin.reporting.progress import ProgressCallback
from dualtwin.robots.binding import RobotBinding

MCAP_MAGIC = b"\x89MCAP0\r\n"

TIME_DOC = {
    "recorded": "ROS time stamps in nanoseconds (the robot's clock, usually wall-clock)",
    "rebased": "a scenario's time 0 is its range start, measured from the bag's first message on a mapped "
               "topic, or with one bag per scenario that bag's first message on a mapped topic; stamps are "
               "subtracted as integers, then converted to seconds",
}


def _get(value: Any, part: str) -> Any:
    """A field of a decoded message: dicts from the fast reader, objects from ``mcap_ros2``."""
    return value[part] if isinstance(value, dict) else getattr(value, part)


def quaternion_angle(q: Any, angle: str) -> float:
    """Roll, pitch or yaw (radians, ZYX convention as ROS' tf2 ``getRPY``) of a quaternion message."""
    x, y, z, w = (float(_get(q, k)) for k in ("x", "y", "z", "w"))
    return rpy_from_quat(x=x, y=y, z=z, w=w, angle=angle)


class _TopicReader:
    """Extracts every mapped channel of one topic from each decoded message, in one pass."""

    def __init__(self, path: Path, topic: str, channels: list[BagChannel], stamp: str) -> None:
        # Channels reading the same field sit together, so that field is looked up once per message.
        groups: dict[tuple[str, ...], list[BagChannel]] = {}
        for ch in channels:
            groups.setdefault(tuple(ch.field.split(".")), []).append(ch)
        channels = [ch for members in groups.values() for ch in members]
        self.path, self.topic, self.channels, self.stamp = path, topic, channels, stamp
        self._plan: list[tuple[tuple[str, ...], Callable[[Any], Any]]] | None = None
        self._plan_for: list[int | None] | None = None
        self.times: list[int] = []
        self.log_times: list[int] = []
        self.values: list[list[float]] = []
        self._names: list[str] | None = None
        self._element_index: list[int | None] = []
        self._resolved = False  # _element_index is valid for _names (None: a message without a name list)
        self._paths = [(ch, tuple(ch.field.split("."))) for ch in self.channels]

    def _fail(self, channel: BagChannel, why: str) -> DualtwinError:
        return DualtwinError(f"{self.path}: topic {self.topic}, message {len(self.times)}: {why} "
                             f"(channel {channel.run_name!r}, field {channel.field!r})")

    def _resolve_elements(self, message: Any) -> list[int | None]:
        try:
            names = _get(message, "name")
        except (AttributeError, KeyError):
            names = None
        if self._resolved and (names is self._names or names == self._names):
            return self._element_index
        out: list[int | None] = []
        for ch in self.channels:
            if ch.element is None:
                out.append(ch.index)
                continue
            if names is None:
                raise self._fail(ch, "'element' needs a message with a 'name' list (sensor_msgs/msg/JointState)")
            try:
                out.append(list(names).index(ch.element))
            except ValueError:
                raise self._fail(ch, f"no entry {ch.element!r} in its name list {list(names)}") from None
        self._names, self._element_index, self._resolved = names, out, True
        return out

    def add(self, message: Any, log_time: int) -> None:
        if self.stamp == "header":
            try:
                stamp = _get(_get(message, "header"), "stamp")
                t = int(_get(stamp, "sec")) * 1_000_000_000 + int(_get(stamp, "nanosec"))
            except (AttributeError, KeyError):
                raise DualtwinError(f"{self.path}: topic {self.topic}: stamp 'header' needs messages with a "
                                    "header (use stamp: log_time)") from None
        else:
            t = log_time
        indices = self._resolve_elements(message)
        if self._plan is not None and indices is self._plan_for:
            try:
                fast: list[float] = []
                for parts, getter in self._plan:
                    value: Any = message
                    for part in parts:
                        value = value[part] if type(value) is dict else getattr(value, part)
                    fast.extend(getter(value))
            except Exception:  # noqa: BLE001  (the checked path below names the problem)
                pass
            else:
                self.times.append(t)
                self.log_times.append(log_time)
                self.values.append(fast)
                return
        self._add_checked(message, t, log_time, indices)
        self._plan, self._plan_for = self._make_plan(indices), indices

    def _make_plan(self, indices: list[int | None]) -> list[tuple[tuple[str, ...], Callable[[Any], Any]]]:
        """Per field path, one getter returning its channels' values in order (checked once already)."""
        plan: list[tuple[tuple[str, ...], Callable[[Any], Any]]] = []
        position = 0
        for parts, members in _grouped(self.channels):
            idx = indices[position:position + len(members)]
            position += len(members)
            if all(i is not None for i in idx) and all(m.angle is None for m in members):
                picks = [int(i) for i in idx if i is not None]
                getter: Callable[[Any], Any] = (operator.itemgetter(*picks) if len(picks) > 1
                                                else operator.itemgetter(slice(picks[0], picks[0] + 1)))
            else:
                steps: list[tuple[int | None, str | None]] = [(i, m.angle) for i, m in zip(idx, members, strict=True)]

                def getter(v: Any, steps: list[tuple[int | None, str | None]] = steps) -> tuple[float, ...]:
                    out = []
                    for i, angle in steps:
                        x = v if i is None else v[i]
                        out.append(float(quaternion_angle(x, angle) if angle else x))
                    return tuple(out)
            plan.append((parts, getter))
        return plan

    def _add_checked(self, message: Any, t: int, log_time: int, indices: list[int | None]) -> None:
        row: list[float] = []
        for (ch, parts), index in zip(self._paths, indices, strict=True):
            value: Any = message
            for part in parts:
                try:
                    value = value[part] if type(value) is dict else getattr(value, part)
                except (AttributeError, KeyError, TypeError):
                    raise self._fail(ch, f"the message has no field {part!r}") from None
            if index is not None:
                try:
                    value = value[index]
                except (IndexError, KeyError, TypeError):  # (a KeyError: the field is a message, not an array)
                    raise self._fail(ch, f"no entry {index} in the field") from None
            if ch.angle is not None:
                try:
                    value = quaternion_angle(value, ch.angle)
                except (AttributeError, KeyError, TypeError, ValueError):
                    raise self._fail(ch, "'angle' needs a quaternion field (x, y, z, w)") from None
            try:
                row.append(float(value))
            except (TypeError, ValueError):
                raise self._fail(ch, f"the value is not a number but {type(value).__name__}; pick an entry with "
                                     "'element' or 'index', or an angle of a quaternion") from None
        self.times.append(t)
        self.log_times.append(log_time)
        self.values.append(row)

    def sort_by_log_time(self) -> None:
        """Messages in the order they were logged (a bag's chunks may hold them out of order)."""
        log_times = np.asarray(self.log_times, dtype=np.int64)
        if log_times.size > 1 and np.any(np.diff(log_times) < 0):
            order = np.argsort(log_times, kind="stable").tolist()
            self.times = [self.times[i] for i in order]
            self.log_times = [self.log_times[i] for i in order]
            self.values = [self.values[i] for i in order]

    def needed_fields(self) -> set[str]:
        """The top-level message fields the mapped channels (and the stamp) read."""
        fields = {ch.field.split(".")[0] for ch in self.channels}
        if any(ch.element is not None for ch in self.channels):
            fields.add("name")
        if self.stamp == "header":
            fields.add("header")
        return fields


def _grouped(channels: list[BagChannel]) -> list[tuple[tuple[str, ...], list[BagChannel]]]:
    groups: dict[tuple[str, ...], list[BagChannel]] = {}
    for ch in channels:
        groups.setdefault(tuple(ch.field.split(".")), []).append(ch)
    return list(groups.items())


def _decoder(schema: Any, channel: Any, topic_reader: _TopicReader) -> tuple[MessageReader | None,
                                                                             Callable[[bytes], Any]]:
    """The fast reader when the schema allows it, and ``mcap_ros2``'s decoder as the reference and fallback."""
    from mcap_ros2.decoder import DecoderFactory

    where = f"{topic_reader.path}: topic {topic_reader.topic}"
    if schema is None:
        raise DualtwinError(f"{where} has no schema; cannot decode it")
    try:
        decode = DecoderFactory().decoder_for(channel.message_encoding, schema)
    except Exception as exc:  # noqa: BLE001  (see _untrusted: the bag's own text, parsed by mcap_ros2)
        raise _untrusted(f"{where}: cannot parse its message definition {schema.name!r}", exc) from None
    if decode is None:
        raise DualtwinError(f"{where}: messages are {channel.message_encoding!r} with a {schema.encoding!r} "
                            "schema, not ROS 2 CDR")

    def reference(data: bytes) -> Any:
        try:
            return decode(data)
        except Exception as exc:  # noqa: BLE001  (see _untrusted)
            raise _untrusted(f"{where}, message {len(topic_reader.times)}: cannot decode it with its "
                             f"definition {schema.name!r}", exc) from None

    fast = None
    if schema.encoding == "ros2msg" and channel.message_encoding == "cdr":
        fast = compile_schema(schema.name, schema.data.decode("utf-8", "replace"), topic_reader.needed_fields())
    return fast, reference


def _untrusted(what: str, exc: Exception) -> DualtwinError:
    """A bag's message definition (text inside the bag) and its payloads are untrusted input, and
    ``mcap_ros2``'s vendored rosidl parser and its decoder fail on bad ones with whatever they hit first
    (their own InvalidSpecification classes, but also NameError, TypeError, NotImplementedError for
    wstring...): no narrower set names them all, so any error from those two calls is the bag's."""
    detail = " ".join(str(exc).split())[:200]  # (one line: the parsers quote the offending definition line)
    return DualtwinError(f"{what} ({type(exc).__name__}: {detail or 'no detail'})")


def _codec_errors() -> tuple[type[Exception], ...]:
    """zstandard's error for a corrupt chunk; mcap reads zstd chunks only when zstandard is installed (without
    it, it refuses them with an McapError), so it is looked up, not imported unconditionally."""
    try:
        from zstandard import ZstdError
    except ImportError:
        return ()
    return (ZstdError,)


def read_bag(path: Path, mapping: BagMapping, where: str,
             progress: ProgressCallback | None = None) -> dict[str, _TopicReader]:
    """Decode every mapped topic of one bag: per topic, integer stamps (ns) and a row of channel values.

    Raises:
        DualtwinError: Not an MCAP file, unreadable or truncated, a mapped topic absent, a field that does
            not exist, or stamps that go backwards or repeat.
    """
    try:
        from mcap.exceptions import McapError
        from mcap.reader import make_reader
    except ImportError:  # pragma: no cover - the extra is part of every install that CI makes
        raise DualtwinError("reading MCAP bags needs the 'recorded' extra: pip install 'dualtwin[recorded]'") from None

    path = check_input_file(path, "MCAP bag")
    corrupt: tuple[type[Exception], ...] = (McapError, ValueError, KeyError, EOFError, OSError, AssertionError,
                                            struct.error, OverflowError, RuntimeError, *_codec_errors())
    by_topic: dict[str, list[BagChannel]] = {}
    for ch in mapping.channels:
        by_topic.setdefault(ch.topic, []).append(ch)
    readers = {topic: _TopicReader(path, topic, chans, mapping.stamp) for topic, chans in by_topic.items()}
    decoders: dict[int, tuple[MessageReader | None, Callable[[bytes], Any]]] = {}
    with open(path, "rb") as handle:
        if handle.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise DualtwinError(f"{path}: not an MCAP file (no MCAP magic at its start)")
        handle.seek(0)
        try:
            reader = make_reader(handle)
            summary = reader.get_summary()
            total = None
            if summary is not None and summary.statistics is not None:
                counts = summary.statistics.channel_message_counts
                total = sum(n for cid, n in counts.items()
                            if cid in summary.channels and summary.channels[cid].topic in readers)
            tick = ticker(progress, f"read {path.name}", total)
            count = 0
            if summary is not None:
                present = {c.topic: c for c in summary.channels.values()}
                for topic in readers:
                    if topic not in present:
                        raise DualtwinError(f"{path}: no topic {topic!r} in the bag (it has: "
                                            f"{', '.join(sorted(present)) or 'no topics'}); {where}")
            # File order, sorted by log time per topic afterwards: cheaper than the reader's merged order.
            for schema, channel, message in reader.iter_messages(topics=list(readers), log_time_order=False):
                decoder = decoders.get(channel.id)
                if decoder is None:
                    decoder = decoders[channel.id] = _decoder(schema, channel, readers[channel.topic])
                fast, reference = decoder
                decoded = fast.read(message.data) if fast is not None else None
                if decoded is None:
                    decoded = reference(message.data)
                readers[channel.topic].add(decoded, message.log_time)
                count += 1
                if count % 5000 == 0:
                    tick(count)
            tick(total or count)
        except DualtwinError:
            raise
        except corrupt as exc:
            # A corrupt chunk: zstandard raises its ZstdError, lz4 a plain RuntimeError, and a record length
            # past what a file read takes an OverflowError; all three mean the bytes are bad.
            raise DualtwinError(f"{path}: cannot read the bag (truncated or corrupt? the MCAP CLI's 'mcap recover' "
                                f"rebuilds a cut bag): {exc or type(exc).__name__}") from None
    for topic, topic_reader in readers.items():
        if not topic_reader.times:
            raise DualtwinError(f"{path}: topic {topic!r} has no messages; {where}")
        topic_reader.sort_by_log_time()
        stamps = np.asarray(topic_reader.times, dtype=np.int64)
        back = np.flatnonzero(np.diff(stamps) <= 0)
        if back.size:
            i = int(back[0]) + 1
            raise DualtwinError(f"{path}: topic {topic}, message {i}: stamps must increase "
                                f"({stamps[i]} ns after {stamps[i - 1]} ns)")
    return readers


def _slug(topic: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", topic).strip("_") or "topic"


def _scenario(path: Path, name: str, readers: dict[str, _TopicReader], factors: dict[str, float],
              origin_ns: int, start_ns: int, end_ns: int | None, label: str) -> ScenarioRecording:
    traces: list[Trace] = []
    raw: list[RawLog] = []
    for topic, topic_reader in readers.items():
        stamps = np.asarray(topic_reader.times, dtype=np.int64) - origin_ns
        keep = stamps >= start_ns
        if end_ns is not None:
            keep &= stamps <= end_ns
        idx = np.flatnonzero(keep)
        if idx.size == 0:
            raise DualtwinError(f"{path}: topic {topic} has no message in {label}")
        t: FloatArray = (stamps[idx] - start_ns).astype(np.float64) / 1e9
        block = np.asarray(topic_reader.values, dtype=np.float64)[idx]
        columns: dict[str, FloatArray] = {}
        for j, ch in enumerate(topic_reader.channels):
            columns[ch.run_name] = block[:, j] * factors[ch.run_name]

            def where(i: int, topic: str = topic, t: FloatArray = t, first: int = int(idx[0])) -> str:
                return f"{path}, topic {topic}, message {first + i} (t = {t[i]:.6f} s)"

            traces.append(Trace(ch.run_name, t, columns[ch.run_name], where))
        raw.append(RawLog(_slug(topic), t, columns))
    dts = [np.diff(tr.t) for tr in traces if tr.t.size > 1]
    timing: dict[str, Any] = {"origin": "rebased", "start_s": start_ns / 1e9,
                              "samples": {tr.run_name: int(tr.t.size) for tr in traces}}
    if dts:
        timing["median_dt_s"] = float(np.median(np.concatenate(dts)))
    return ScenarioRecording(traces=traces, raw=raw, sources=[name], timing=timing)


def import_mcap(mapping: Path, suite: Path, robot: str | Path | RobotBinding, out: Path,
                data_dir: Path | None = None, progress: ProgressCallback | None = None,
                invalid: str = "error") -> Path:
    """Import ROS 2 bags (MCAP) described by a YAML :class:`BagMapping`; returns the run folder.

    Args:
        mapping: The YAML mapping file.
        suite: The suite the bags were recorded from.
        robot: A bundled robot name, a binding file or a loaded binding.
        out: The run folder to write (absent, empty, or an earlier import).
        data_dir: Where the mapping's bag names are resolved and confined; default the mapping's folder.
        progress: Receives progress events (`dualtwin.reporting.progress`) while files are read and written.
        invalid: What infinite or absurd values do (`dualtwin.recorded.build.INVALID_TREATMENTS`).
    """
    inputs = mapped_inputs(mapping, BagMapping, suite, robot, out, data_dir)
    spec, suite_model, binding, mapping_path, files, names = (
        inputs.spec, inputs.suite, inputs.binding, inputs.mapping_path, inputs.files, inputs.names)
    assert isinstance(spec, BagMapping)
    where = str(mapping_path)
    factors = {ch.run_name: channel_factor(binding, ch, where) for ch in spec.channels}
    count = len(suite_model.scenarios)
    ids = suite_model.scenario_ids()
    scenarios: list[ScenarioRecording] = []
    if spec.scenarios is not None:
        if len(files) != 1:
            raise DualtwinError(f"{where}: time ranges cut one bag into scenarios, but files gives {len(files)}")
        if len(spec.scenarios) != count:
            raise DualtwinError(f"{where}: $.scenarios: {len(spec.scenarios)} time range(s) for {count} "
                                f"scenario(s) in {suite}")
        readers = read_bag(files[0], spec, where, progress)
        origin = min(r.times[0] for r in readers.values())
        for sid, span in zip(ids, spec.scenarios, strict=True):
            start, end = round(span.start_s * 1e9), round(span.end_s * 1e9)
            scenarios.append(_scenario(files[0], names[0], readers, factors, origin, start, end,
                                       f"scenario {sid}'s range {span.start_s:g} to {span.end_s:g} s"))
    else:
        if len(files) != count:
            raise DualtwinError(f"{where}: {len(files)} bag(s) for {count} scenario(s) in {suite}; give one "
                                "bag per scenario, or one bag and time ranges in 'scenarios'")
        for sid, path, name in zip(ids, files, names, strict=True):
            readers = read_bag(path, spec, where, progress)
            origin = min(r.times[0] for r in readers.values())
            scenarios.append(_scenario(path, name, readers, factors, origin, 0, None, f"scenario {sid}"))
    recording = Recording(format="mcap", suite_path=Path(suite), suite=suite_model, robot=binding, mapping=spec,
                          mapping_path=mapping_path, channels=list(spec.channels), scenarios=scenarios,
                          sources=dict(zip(names, files, strict=True)), time={"stamp": spec.stamp, **TIME_DOC},
                          invalid=invalid)
    return write_recording(recording, Path(out), progress)
