"""CSV/TSV logs, one file per scenario, described by a :class:`~dualtwin.recorded.mapping.TableMapping`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import check_output_dir
from dualtwin.errors import DualtwinError
from dualtwin.recorded.build import (
    KIND,
    FloatArray,
    RawLog,
    Recording,
    ScenarioRecording,
    Trace,
    channel_factor,
    check_suite,
    quantum,
    ticker,
    write_recording,
)
from dualtwin.recorded.delimited import Table, read_table
from dualtwin.recorded.mapping import MAX_BAG_TIME_S, BagMapping, TableMapping, load_mapping, resolve_files
from dualtwin.reporting.progress import ProgressCallback
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.loader import load_suite
from dualtwin.suite.schema import Suite

TIME_FACTORS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: ``origin: auto`` re-bases a file whose first stamp is later than this many control periods: a log in
#: simulation time starts within a period or two of its scenario, so a later stamp comes from a clock that
#: started earlier (wall-clock, or a simulation clock running across the whole suite).
AUTO_REBASE_PERIODS = 10

TIME_DOC = {
    "simulation": "stamps already count simulation time from the scenario's start and are kept",
    "rebased": "stamps came from another clock (wall-clock, or a simulation clock running across scenarios): "
               "each file is shifted so its first sample is at first_sample_s; only differences of stamps "
               "are used, so jitter and irregular spacing are kept and interpolated over",
}


def resolve_inputs(suite_path: Path, robot: str | Path | RobotBinding) -> tuple[Suite, RobotBinding]:
    """Load the suite and the binding and check that they fit each other."""
    binding = robot if isinstance(robot, RobotBinding) else resolve_robot(str(robot))
    suite = load_suite(Path(suite_path))
    check_suite(suite, Path(suite_path), binding)
    return suite, binding


@dataclass
class MappedInputs:
    """What a mapping-driven import reads before its first sample: the mapping, suite, binding and files."""

    spec: TableMapping | BagMapping
    suite: Suite
    binding: RobotBinding
    mapping_path: Path
    files: list[Path]
    names: list[str]  # each file relative to the data folder, as the manifest records it


def mapped_inputs(mapping: Path, model: type[TableMapping] | type[BagMapping], suite: Path,
                  robot: str | Path | RobotBinding, out: Path, data_dir: Path | None) -> MappedInputs:
    """Check the output folder, load and validate the mapping, the suite and the binding, and resolve the
    mapping's files inside the data folder (default: the mapping's folder); nothing is created."""
    check_output_dir(Path(out), KIND, resume=True, resumable=True)
    mapping_path = Path(mapping)
    spec = load_mapping(mapping_path, model)
    suite_model, binding = resolve_inputs(Path(suite), robot)
    root = Path(data_dir) if data_dir is not None else mapping_path.parent
    if not root.is_dir():
        raise DualtwinError(f"--data-dir {root}: not a folder")
    files = resolve_files(spec.files, root, str(mapping_path))
    names = [str(f.relative_to(root.resolve())) for f in files]
    return MappedInputs(spec, suite_model, binding, mapping_path, files, names)


def _time_axis(table: Table, mapping: TableMapping, period: float) -> tuple[FloatArray, dict[str, Any]]:
    spec = mapping.time
    stamps = table.column(spec.column, "the time column") * TIME_FACTORS[spec.unit]
    col = table.header.index(spec.column) + 1
    bad = np.flatnonzero(~np.isfinite(stamps))
    if bad.size:
        i = int(bad[0])
        raise DualtwinError(f"{table.path}:{table.line(i)}: time stamp {float(stamps[i])!r} is not a finite number "
                            f"(column {col}, {spec.column!r})")
    far = np.flatnonzero(np.abs(stamps) > MAX_BAG_TIME_S)
    if far.size:
        # No recording's clock reads more than the bags' int64 nanoseconds hold (about 292 years; wall-clock
        # stamps are about 1.7e9 s): a stamp beyond is a typo, and 1e308 s overflowed the resampling to inf,
        # which the manifest's JSON cannot hold (a traceback after warnings)
        i = int(far[0])
        raise DualtwinError(f"{table.path}:{table.line(i)}: time stamp {float(stamps[i])!r} s is beyond "
                            f"±{MAX_BAG_TIME_S:g} s, more than any recording's clock reads "
                            f"(column {col}, {spec.column!r})")
    steps = np.diff(stamps)
    back = np.flatnonzero(steps <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise DualtwinError(f"{table.path}:{table.line(i)}: time stamps must increase: {float(stamps[i])!r} s after "
                            f"{float(stamps[i - 1])!r} s (column {col}, {spec.column!r})")
    rebase = spec.origin == "rebase" or (spec.origin == "auto" and stamps[0] > AUTO_REBASE_PERIODS * period)
    if not rebase and stamps[0] < 0:
        # Scenario time starts at 0: a negative stamp is a sample from before the scenario began (or a clock
        # that is not scenario time, which origin: rebase states explicitly).
        raise DualtwinError(f"{table.path}:{table.line(0)}: first time stamp {float(stamps[0])!r} s is negative "
                            f"(column {col}, {spec.column!r}); scenario time starts at 0 (a log on another "
                            "clock needs origin: rebase)")
    t = stamps - stamps[0] + spec.first_sample_s if rebase else stamps
    if rebase and t.size > 1 and not (np.diff(t) > 0).all():
        # a huge first_sample_s (1e308) swallows the differences of stamps: every sample at one time, silently
        raise DualtwinError(f"{table.path}: the mapping's time.first_sample_s {spec.first_sample_s!r} is too large: "
                            "the stamps moved there no longer increase")
    timing: dict[str, Any] = {"origin": "rebased" if rebase else "simulation",
                              "first_stamp_s": float(stamps[0]), "first_sample_s": float(t[0]),
                              "samples": int(t.size)}
    if steps.size:
        timing.update(median_dt_s=float(np.median(steps)), min_dt_s=float(steps.min()),
                      max_dt_s=float(steps.max()))
    return t, timing


def scenario_from_table(path: Path, name: str, mapping: TableMapping, factors: dict[str, float],
                        period: float) -> ScenarioRecording:
    """Read one scenario's file into traces (binding units, scenario seconds) and its raw log."""
    table = read_table(path, mapping.delimiter)
    t, timing = _time_axis(table, mapping, period)
    columns: dict[str, FloatArray] = {}
    resolution: dict[str, float] = {}
    for ch in mapping.channels:
        recorded = table.column(ch.column, f"channel {ch.run_name!r}")
        columns[ch.run_name] = recorded * factors[ch.run_name]
        step = quantum(recorded)
        if step is not None and step < 1.0:
            resolution[ch.run_name] = step
    if resolution:
        timing["rounded_to"] = resolution  # in the recorded unit: the log's own precision, kept as it is

    def located(column: str) -> Any:
        col = table.header.index(column) + 1
        return lambda i: f"{path}:{table.line(i)}:{col}"

    traces = [Trace(ch.run_name, t, columns[ch.run_name], located(ch.column)) for ch in mapping.channels]
    return ScenarioRecording(traces=traces, raw=[RawLog("log", t, columns)], sources=[name], timing=timing,
                             notes=list(table.notes))


def recording_from_tables(files: Sequence[Path], names: Sequence[str], mapping: TableMapping, suite: Suite,
                          suite_path: Path, robot: RobotBinding, fmt: str, mapping_path: Path | None,
                          where: str, time_doc: dict[str, Any],
                          progress: ProgressCallback | None = None) -> Recording:
    """Read every scenario's file (one per scenario, in order) into a validated :class:`Recording`."""
    if len(files) != len(suite.scenarios):
        raise DualtwinError(f"{where}: {len(files)} file(s) for {len(suite.scenarios)} scenario(s) in "
                            f"{suite_path}; give one file per scenario, in the suite's order")
    factors = {ch.run_name: channel_factor(robot, ch, where) for ch in mapping.channels}
    period = suite.global_settings.control_period_s
    tick = ticker(progress, "read the logs", len(files))
    scenarios = []
    for i, (path, name) in enumerate(zip(files, names, strict=True)):
        scenarios.append(scenario_from_table(path, name, mapping, factors, period))
        tick(i + 1, name)
    return Recording(format=fmt, suite_path=Path(suite_path), suite=suite, robot=robot, mapping=mapping,
                     mapping_path=mapping_path, channels=list(mapping.channels), scenarios=scenarios,
                     sources=dict(zip(names, files, strict=True)), time=time_doc)


def import_table(mapping: Path, suite: Path, robot: str | Path | RobotBinding, out: Path,
                 data_dir: Path | None = None, progress: ProgressCallback | None = None,
                 invalid: str = "error") -> Path:
    """Import CSV/TSV logs described by a YAML :class:`TableMapping`; returns the run folder.

    Args:
        mapping: The YAML mapping file.
        suite: The suite the logs were recorded from (scenarios are paired with files in order).
        robot: A bundled robot name, a binding file or a loaded binding (channels and units come from it).
        out: The run folder to write (absent, empty, or an earlier import).
        data_dir: Where the mapping's file names are resolved and confined; default the mapping's folder.
        progress: Receives progress events (`dualtwin.reporting.progress`) while files are read and written.
        invalid: What infinite or absurd values do (`dualtwin.recorded.build.INVALID_TREATMENTS`).
    """
    inputs = mapped_inputs(mapping, TableMapping, suite, robot, out, data_dir)
    spec, suite_model, binding, mapping_path, files, names = (
        inputs.spec, inputs.suite, inputs.binding, inputs.mapping_path, inputs.files, inputs.names)
    assert isinstance(spec, TableMapping)
    time_doc = {"column": spec.time.column, "unit": spec.time.unit, "origin": spec.time.origin,
                "rule": f"origin auto re-bases a file whose first stamp is later than {AUTO_REBASE_PERIODS} "
                        "control periods", **TIME_DOC}
    recording = recording_from_tables(files, names, spec, suite_model, Path(suite), binding, "table",
                                      mapping_path, str(mapping_path), time_doc, progress)
    recording.invalid = invalid
    return write_recording(recording, Path(out), progress)
