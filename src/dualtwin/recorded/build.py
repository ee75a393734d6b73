"""From per-scenario recordings to a run folder: the control-period grid, statuses, the manifest, the write.

Every importer (paper, table, MCAP) reads and validates its inputs into a :class:`Recording`: per scenario,
each channel's samples in the binding's unit on a scenario-time axis (seconds from the scenario's start).
This module then does what is common:

* **The grid.** A twin run logs the state after each control period, at ``t_k = k * period`` for
  ``k = 1 .. ceil(duration / period)``. A recording is put on the same grid by linear interpolation
  (``numpy.interp``) of its samples, so jittered or irregular stamps land on the twin's instants. Grid points
  before the first sample hold the first value (a log that started late); the grid ends at the last sample
  (plus half a period, for jitter), so a recording shorter than its scenario gives a shorter log, noted.
  The raw samples are kept beside the resampled logs (``raw_<name>.tsv``) for anyone who distrusts the grid.
* **Statuses**, exactly as the suite runner decides them: the first non-finite value makes the scenario
  ``unstable`` (the log stops before it), the first ground-truth sample past a failure threshold of the suite
  makes it ``failed`` (the log stops after it), otherwise it is ``completed``.
* **The write.** Nothing is created until every input is read and checked. The run is staged in a hidden
  sibling folder and renamed into place, so the folder appears whole or not at all; a folder is only replaced
  when it is an earlier import holding nothing but what that import wrote.
* **Byte-identical output** for the same inputs: no clock, no absolute output path, floats as ``repr``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml
from pydantic import BaseModel

from dualtwin.artifacts import (
    check_output_dir,
    current_umask,
    package_versions,
    read_json,
    sha256_file,
    write_failed,
)
from dualtwin.divergence.metrics import default_resolution
from dualtwin.errors import DualtwinError
from dualtwin.recorded.carryover import state_continuity
from dualtwin.recorded.clock import clock_note, sampling_clock
from dualtwin.recorded.mapping import ChannelBase
from dualtwin.recorded.units import conversion_factor
from dualtwin.reporting.progress import ProgressCallback, ProgressEvent
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.runner import MANIFEST_VERSION, check_against_binding
from dualtwin.suite.schema import Suite

FloatArray = npt.NDArray[np.float64]
KIND = "recorded"

#: How far a recording's first sample may be from the suite's initial condition before the manifest says the
#: state may have carried over from the previous scenario (in the channel's unit; a heuristic, noted as one).
CARRY_OVER_TOLERANCE = 0.05

RESAMPLING = {
    "method": "linear interpolation (numpy.interp) of the raw samples at the twin's logging instants",
    "grid": "t_k = k * control_period_s for k = 1 .. ceil(duration_s / control_period_s), as the suite runner logs",
    "before_first_sample": "grid points before a channel's first sample hold that sample's value",
    "end": "the grid stops at the last sample plus half a control period (a shorter recording gives a "
           "shorter log) and at the scenario's duration (later samples stay in the raw log only)",
    "non_finite": "the first NaN or infinite value makes the scenario unstable; the log stops before it",
    "failure": "the suite's failure thresholds apply to the resampled ground truth as in a twin run",
    "raw": "raw_<name>.tsv beside the logs: every recorded sample, on the re-based time axis, in the "
           "binding's units (scale and unit conversion applied)",
}


@dataclass(eq=False)
class Trace:
    """One run channel's samples in one scenario: scenario seconds and values in the binding's unit."""

    run_name: str
    t: FloatArray
    y: FloatArray
    where: Callable[[int], str]  # names the sample's origin (file:line, bag topic and time) in messages


@dataclass(eq=False)
class RawLog:
    """Samples sharing one time axis (a table file, or a bag topic), kept beside the resampled logs."""

    name: str
    t: FloatArray
    columns: dict[str, FloatArray]


@dataclass(eq=False)
class ScenarioRecording:
    traces: list[Trace]
    raw: list[RawLog]
    sources: list[str]
    timing: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


@dataclass(eq=False)
class Recording:
    """Everything an importer read, validated, ready to be written as a run."""

    format: str
    suite_path: Path
    suite: Suite
    robot: RobotBinding
    mapping: BaseModel
    mapping_path: Path | None
    channels: list[ChannelBase]
    scenarios: list[ScenarioRecording]
    sources: dict[str, Path]  # the name recorded in the manifest -> the file
    time: dict[str, Any]
    #: What to do with values no sensor produces (see :func:`screen_trace`): error, mask or unstable.
    invalid: str = "error"


def check_suite(suite: Suite, suite_path: Path, robot: RobotBinding) -> None:
    """The suite must resolve through the binding, as for a twin run."""
    check_against_binding(suite, suite_path, robot)


def channel_factor(robot: RobotBinding, channel: ChannelBase, where: str) -> float:
    """The factor taking a recorded value to the binding's unit (``scale`` included).

    Raises:
        DualtwinError: The binding has no such channel for that source, or the units cannot be converted.
    """
    spec = robot.spec
    section = spec.ground_truth if channel.source == "ground_truth" else spec.onboard
    if channel.name not in section:
        raise DualtwinError(f"{where}: robot {robot.name!r} has no {channel.source} channel {channel.name!r}; "
                            f"it has: {', '.join(section)}")
    unit = section[channel.name].unit
    factor = conversion_factor(channel.unit, unit, f"{where}: channel {channel.run_name!r}")
    return factor * channel.scale


def unit_record(robot: RobotBinding, channel: ChannelBase) -> dict[str, Any]:
    spec = robot.spec
    section = spec.ground_truth if channel.source == "ground_truth" else spec.onboard
    target = section[channel.name].unit
    return {"recorded": channel.unit, "binding": target, "scale": channel.scale,
            "factor": conversion_factor(channel.unit, target, channel.run_name)}


def quantum(values: FloatArray) -> float | None:
    """The decimal step the values were rounded to (``0.001`` for 3 decimals), if any up to 6 decimals."""
    finite = values[np.isfinite(values)]
    if finite.size < 2:
        return None
    for decimals in range(7):
        scaled = finite * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-6 * np.maximum(1.0, np.abs(scaled))):
            return float(10.0**-decimals)
    return None


def grid_times(duration_s: float, period: float) -> FloatArray:
    steps = math.ceil(duration_s / period - 1e-9)
    return np.round(np.arange(1, steps + 1) * period, 9)


def initial_state_notes(recording: ScenarioRecording, robot: RobotBinding, inputs: dict[str, Any]) -> dict[str, Any]:
    """Compare each initial condition the scenario sets with the recording's first sample of that quantity.

    The paper's orchestrator does not always reset between scenarios, so a recording may start where the
    previous scenario ended. This cannot be proven from the log; a first sample far from the suite's value
    is reported, not corrected.
    """
    spec = robot.spec
    traces = {tr.run_name: tr for tr in recording.traces}
    checks: dict[str, Any] = {}
    for key, ic in spec.initial_conditions.items():
        if key not in inputs or not isinstance(inputs[key], float):
            continue
        for name, ch in spec.ground_truth.items():
            same = (ic.joint is not None and ch.joint == ic.joint and ch.quantity == ic.quantity) or (
                ic.body is not None and ch.body == ic.body and ch.axis == ic.axis and ch.quantity == "position"
                and ic.quantity == "position")
            if same and name in traces and traces[name].y.size and math.isfinite(float(traces[name].y[0])):
                first = float(traces[name].y[0])
                checks[key] = {"suite": inputs[key], "recorded_first": first, "channel": name,
                               "matches": abs(first - inputs[key]) <= CARRY_OVER_TOLERANCE}
                break
    return checks


@dataclass
class _Assembled:
    record: dict[str, Any]
    files: dict[str, bytes]


#: A recorded value beyond this magnitude (in the binding's unit: rad, m, m/s ...) is not a measurement: no
#: sensor of a robot we model reads a billion of anything. Infinities are not measurements either. NaN keeps
#: its meaning in a simulator's log, as in our own runs: the recorded simulation went unstable there.
MAX_RECORDED_MAGNITUDE = 1e9
#: ``--invalid``: how an import treats such values. ``error`` (the default) refuses the recording, naming file,
#: line and column; ``mask`` drops those samples (interpolated over) and ``unstable`` ends the scenario there
#: as a NaN would; both say in the scenario's manifest notes what they did and where.
INVALID_TREATMENTS = ("error", "mask", "unstable")


def screen_trace(tr: Trace, invalid: str, notes: list[str]) -> Trace:
    """``tr`` with its infinite and absurd values treated as ``invalid`` says (see INVALID_TREATMENTS)."""
    y = tr.y
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(np.isinf(y) | (np.abs(y) > MAX_RECORDED_MAGNITUDE))
    if not bad.size:
        return tr
    i = int(bad[0])
    what = "infinite" if math.isinf(float(y[i])) else f"beyond ±{MAX_RECORDED_MAGNITUDE:g}"
    if invalid == "mask":
        keep = np.ones(y.size, dtype=bool)
        keep[bad] = False
        index = np.flatnonzero(keep)
        notes.append(f"masked {bad.size} sample(s) of {tr.run_name} that no sensor produces (infinite or beyond "
                     f"±{MAX_RECORDED_MAGNITUDE:g}), the first at {tr.where(i)}; interpolated over")
        return Trace(tr.run_name, tr.t[keep], y[keep], lambda k: tr.where(int(index[k])))
    if invalid == "unstable":
        notes.append(f"{bad.size} sample(s) of {tr.run_name} that no sensor produces (infinite or beyond "
                     f"±{MAX_RECORDED_MAGNITUDE:g}) treated as NaN (--invalid unstable), the first at {tr.where(i)}")
        y = y.copy()
        y[bad] = np.nan
        return Trace(tr.run_name, tr.t, y, tr.where)
    raise DualtwinError(f"{tr.where(i)}: {tr.run_name} = {float(y[i])!r} is {what}: no sensor reads that; "
                        "fix the log, or import with --invalid mask (drop such samples) or --invalid unstable "
                        "(end the scenario there)")


def _assemble(index: int, sid: str, rec: ScenarioRecording, recording: Recording,
              period: float) -> _Assembled:
    suite, robot = recording.suite, recording.robot
    scenario = suite.scenarios[index]
    grid = grid_times(scenario.duration_s, period)
    notes = list(rec.notes)
    unstable: tuple[float, str] | None = None
    cut: dict[str, tuple[FloatArray, FloatArray]] = {}
    for tr in (screen_trace(tr, recording.invalid, notes) for tr in rec.traces):
        bad = np.flatnonzero(~np.isfinite(tr.y))
        t, y = tr.t, tr.y
        if bad.size:
            i = int(bad[0])
            if unstable is None or tr.t[i] < unstable[0]:
                unstable = (float(tr.t[i]), f"non-finite value of {tr.run_name} at {tr.where(i)}")
            t, y = t[:i], y[:i]
        cut[tr.run_name] = (t, y)
    n = grid.size
    for t, _ in cut.values():
        covered = 0 if t.size == 0 else int(np.searchsorted(grid, t[-1] + period / 2, side="right"))
        n = min(n, covered)
    if unstable is not None:
        n = min(n, int(np.searchsorted(grid, unstable[0], side="left")))
    status, failure = "completed", None
    values = {name: np.interp(grid[:n], t, y) if t.size else np.zeros(0) for name, (t, y) in cut.items()}
    first_fail: tuple[int, dict[str, Any]] | None = None
    for key, limit in suite.global_settings.thresholds.items():
        channel = robot.spec.failures[key].channel
        if channel not in values:
            continue
        over = np.flatnonzero(np.abs(values[channel]) > limit)
        if over.size and (first_fail is None or over[0] < first_fail[0]):
            k = int(over[0])
            first_fail = (k, {"key": key, "channel": channel, "time_s": float(grid[k]), "threshold": limit})
    if first_fail is not None:
        n = first_fail[0] + 1
        status, failure = "failed", first_fail[1]
        values = {name: v[:n] for name, v in values.items()}
    elif unstable is not None:
        status, failure = "unstable", {"time_s": round(unstable[0], 9), "message": unstable[1]}
    if n == 0 and status != "unstable":
        first = rec.traces[0]
        raise DualtwinError(f"{first.where(0)}: the recording of scenario {sid!r} covers less than one control "
                            f"period ({period:g} s)")

    timing = dict(rec.timing)
    timing["grid_samples"] = n
    timing["scenario_samples"] = int(grid.size)
    held = {name: int(np.count_nonzero(grid[:n] < t[0] - 1e-12)) for name, (t, _) in cut.items() if t.size}
    if any(held.values()):
        timing["held_before_first_sample"] = held
        k = max(held.values())
        first_s = min(float(t[0]) for t, _ in cut.values() if t.size)
        notes.append(f"{k} grid point(s) before the first sample (at {first_s:.4g} s) hold its value")
    beyond = {name: int(np.count_nonzero(t > grid[-1] + period / 2)) for name, (t, _) in cut.items()}
    if any(beyond.values()):
        timing["samples_after_duration"] = beyond
        notes.append(f"{max(beyond.values())} sample(s) after the scenario's {scenario.duration_s:g} s are in "
                     "the raw log only")
    if status == "completed" and n < grid.size:
        end = min(float(t[-1]) for t, _ in cut.values() if t.size)
        notes.append(f"the recording ends at {end:.4g} s, before the scenario's {scenario.duration_s:g} s: the "
                     f"scenario ended early ({n} of {grid.size} control periods logged)")
    checks = initial_state_notes(rec, robot, scenario.inputs)
    differs = [k for k, c in checks.items() if not c["matches"]]
    for key in differs:
        c = checks[key]
        notes.append(f"starts at {c['channel']} = {c['recorded_first']:.6g} where the suite sets {key} = "
                     f"{c['suite']:.6g}: the state may have carried over from the previous scenario (no reset)")

    folder = f"scenarios/{sid}"
    record: dict[str, Any] = {"id": sid, "index": index, "name": scenario.name, "seed": None,
                              "reset": "as recorded", "onboard": None, "ground_truth": None}
    files: dict[str, bytes] = {}
    for source, section in (("onboard", robot.spec.onboard), ("ground_truth", robot.spec.ground_truth)):
        names = [k for k in section if (k if source == "ground_truth" else f"onboard/{k}") in values]
        if not names:
            continue
        cols = [values[k if source == "ground_truth" else f"onboard/{k}"] for k in names]
        rows = np.column_stack([grid[:n], *cols]).tolist() if n else []
        rel = f"{folder}/{source}.tsv"
        files[rel] = tsv_text(names, rows).encode()
        record[source] = rel
    raw_files = []
    for raw in rec.raw:
        rel = f"{folder}/raw_{raw.name}.tsv"
        rows = np.column_stack([raw.t, *raw.columns.values()]).tolist()
        files[rel] = tsv_text(list(raw.columns), rows).encode()
        raw_files.append(rel)
    record.update(status=status, failure=failure, steps=n, raw=raw_files, sources=rec.sources,
                  timing=timing, initial_state=checks, notes=notes)
    return _Assembled(record, files)


def tsv_text(names: list[str], rows: list[list[float]]) -> str:
    """The suite runner's log format (`dualtwin.suite.runner.format_rows`), built in a few C-level calls.

    ``repr`` of a list of floats writes each float as its shortest round-trip ``repr``, exactly as the
    runner does one float at a time; only the brackets and separators are then rewritten.
    """
    head = "\t".join(["time_s", *names]) + "\n"
    if not rows:
        return head
    return head + repr(rows)[2:-2].replace("], [", "\n").replace(", ", "\t") + "\n"


def _resolutions(channels: dict[str, Any], recording: Recording, records: list[dict[str, Any]]) -> None:
    """Carry the binding's declared resolution, raised to the recording's rounding when that is coarser.

    A log rounded to 3 decimals cannot show a difference below 0.001 of its unit; comparisons must not rank
    one (`dualtwin.divergence.metrics.significance`). The rounding is converted to the binding's unit, and
    the resolution written only when it is declared or the rounding exceeds the unit's default.
    """
    spec = recording.robot.spec
    for ch in recording.channels:
        name = ch.run_name
        declared = (spec.ground_truth if ch.source == "ground_truth" else spec.onboard)[ch.name].resolution
        steps = [r["timing"]["rounded_to"][name] for r in records
                 if name in r.get("timing", {}).get("rounded_to", {})]
        rounding = max(steps) * abs(unit_record(recording.robot, ch)["factor"] * ch.scale) if steps else None
        if rounding is not None:
            channels[name]["recorded_rounding"] = rounding
        base = declared if declared is not None else default_resolution(channels[name]["unit"])
        if declared is not None or (rounding is not None and rounding > base):
            channels[name]["resolution"] = max(base, rounding or 0.0)


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _log_record(data: bytes) -> dict[str, Any]:
    """The record `dualtwin.artifacts.log_record` makes of a written log, from the bytes about to be written."""
    return {"rows": max(data.count(b"\n") - 1, 0), "bytes": len(data), "sha256": _sha256_bytes(data)}


def ticker(progress: ProgressCallback | None, stage: str, total: int | None) -> Callable[..., None]:
    """Report ``done`` of ``total`` at most ~40 times a stage (a 1,000-file import is not 1,000 lines)."""
    step = max(1, (total or 0) // 40)

    def tick(done: int, message: str = "") -> None:
        if progress is not None and (done % step == 0 or done == total):
            progress(ProgressEvent(stage, done, total, message))

    return tick


def build_files(recording: Recording, progress: ProgressCallback | None = None) -> dict[str, bytes]:
    """Every file of the run, in memory: validation ends here, before anything is written."""
    suite, robot = recording.suite, recording.robot
    period = suite.global_settings.control_period_s
    ids = suite.scenario_ids()
    files: dict[str, bytes] = {}
    records = []
    tick = ticker(progress, "resample onto the control grid", len(ids))
    for index, (sid, rec) in enumerate(zip(ids, recording.scenarios, strict=True)):
        assembled = _assemble(index, sid, rec, recording, period)
        files.update(assembled.files)
        records.append(assembled.record)
        tick(index + 1, sid)
    time_doc = {**recording.time, **evidence_from_data(recording, ids, records, period)}
    imported = {c.run_name for c in recording.channels}
    channels: dict[str, Any] = {}
    for name, ch in robot.spec.ground_truth.items():
        if name in imported:
            channels[name] = {"source": "ground_truth", "unit": ch.unit}
    for key, ch in robot.spec.onboard.items():
        if f"onboard/{key}" in imported:
            channels[f"onboard/{key}"] = {"source": "onboard", "column": key, "unit": ch.unit}
    _resolutions(channels, recording, records)
    tolerances: dict[str, Any] = {}
    for sid, scenario in zip(ids, suite.scenarios, strict=True):
        kept = {k: v.model_dump(exclude_none=True) for k, v in scenario.tolerances.items() if k in channels}
        if kept:
            tolerances[sid] = kept
    mapping_yaml = yaml.safe_dump(recording.mapping.model_dump(mode="json"), sort_keys=False,
                                  allow_unicode=True).encode()
    config = {
        "config/suite.json": recording.suite_path.read_bytes(),
        "config/binding.yaml": robot.path.read_bytes(),
        "config/mapping.yaml": mapping_yaml,
    }
    inputs: dict[str, Any] = {
        "suite": {"path": str(recording.suite_path), "sha256": _sha256_bytes(config["config/suite.json"])},
        "binding": {"path": str(robot.path), "sha256": _sha256_bytes(config["config/binding.yaml"])},
    }
    if recording.mapping_path is not None:
        inputs["mapping"] = {"path": str(recording.mapping_path), "sha256": sha256_file(recording.mapping_path)}
    used_by: dict[str, list[str]] = {name: [] for name in recording.sources}
    for record in records:
        for name in record["sources"]:
            used_by[name].append(record["id"])
    sources = [{"path": name, "sha256": sha256_file(path), "bytes": path.stat().st_size,
                "scenarios": used_by[name]} for name, path in recording.sources.items()]
    logs = {rel: _log_record(data) for rel, data in sorted(files.items())}
    manifest: dict[str, Any] = {
        "manifest_version": MANIFEST_VERSION,
        "kind": KIND,
        "format": recording.format,
        "suite_name": suite.suite_name,
        "twin": "recorded",
        "robot": robot.name,
        "seed": None,
        "control_period_s": period,
        "inputs": inputs,
        "sources": sources,
        "mapping": recording.mapping.model_dump(mode="json"),
        "units": {c.run_name: unit_record(robot, c) for c in recording.channels},
        "time": time_doc,
        "invalid_values": {"treatment": recording.invalid, "max_magnitude": MAX_RECORDED_MAGNITUDE},
        "resampling": RESAMPLING,
        "versions": package_versions(),
        "channels": channels,
        "tolerances": tolerances,
        "scenarios": records,
        "logs": logs,
    }
    files.update(config)
    files["manifest.json"] = (json.dumps(manifest, indent=2, allow_nan=False) + "\n").encode()
    return files


def evidence_from_data(recording: Recording, ids: list[str], records: list[dict[str, Any]],
                       period: float) -> dict[str, Any]:
    """What the data says that the suite does not: state carried over between scenarios
    (`dualtwin.recorded.carryover`) and wall-clock stamps (`dualtwin.recorded.clock`), written into each
    scenario's record and notes; returns the run-level summary for the manifest's ``time``."""
    inputs = [scenario.inputs for scenario in recording.suite.scenarios]
    continuities = state_continuity(recording.robot, ids, inputs, [rec.traces for rec in recording.scenarios])
    wall: list[str] = []
    for record, rec, continuity in zip(records, recording.scenarios, continuities, strict=True):
        stats = sampling_clock([raw.t for raw in rec.raw], period)
        if stats is not None:
            record["timing"]["clock"] = stats
            if stats["clock"] == "wall-clock":
                wall.append(record["id"])
                if record["timing"].get("origin") == "simulation":
                    record["timing"]["origin"] = "wall-clock"
                record["notes"].append(clock_note(stats))
        if continuity:
            record["state_continuity"] = continuity
            carried = set(continuity.get("carried_over", {}).get("channels", {}))
            # The suite-key check above said "may have carried over" for a channel the data now settles.
            record["notes"][:] = [n for n in record["notes"]
                                  if not any(n.startswith(f"starts at {c} =") for c in carried)]
            record["notes"].extend(part["note"] for part in continuity.values())
    summary: dict[str, Any] = {"clock": "wall-clock" if wall else "simulation"}
    if wall:
        summary["wall_clock_scenarios"] = wall
    return summary


def _own_files(out: Path) -> set[str]:
    """What an earlier import in ``out`` wrote, per its manifest."""
    manifest = read_json(out / "manifest.json", "run manifest")
    logs = manifest.get("logs") if isinstance(manifest, dict) else None
    own = {"manifest.json", "config/suite.json", "config/binding.yaml", "config/mapping.yaml"}
    return own | set(logs or {})


def publish(out: Path, files: dict[str, bytes], option: str = "--out") -> None:
    """Write ``files`` as the folder ``out``, whole or not at all.

    ``out`` may be absent, empty, or an earlier import that holds only what it wrote (it is then replaced);
    anything else is refused before a byte is written (`dualtwin.artifacts.check_output_dir`).
    """
    out = Path(out)
    replacing = check_output_dir(out, KIND, resume=True, resumable=True, option=option)
    if replacing:
        own = _own_files(out)
        foreign = sorted(str(p.relative_to(out)) for p in out.rglob("*")
                         if p.is_file() and str(p.relative_to(out)) not in own)
        if foreign:
            raise DualtwinError(f"{option} {out}: holds {foreign[0]}, which the earlier import did not write; "
                                "choose an empty folder (nothing is overwritten or deleted)")
    parent = out.absolute().parent
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.import-", dir=parent))
    old: Path | None = None
    try:
        os.chmod(stage, 0o777 & ~current_umask())  # mkdtemp makes 0700; a run folder is as shareable as any
        made: set[Path] = set()
        for rel, data in files.items():
            path = stage / rel
            if path.parent not in made:
                path.parent.mkdir(parents=True, exist_ok=True)
                made.add(path.parent)
            try:
                with open(path, "wb") as handle:
                    handle.write(data)
            except OSError as exc:  # a full disk names the run's file, not the staging folder's
                raise write_failed(exc, out / rel) from None
        os.sync()  # one flush for the whole folder instead of one fsync per file, then one atomic rename
        if out.exists():
            if replacing:
                old = Path(tempfile.mkdtemp(prefix=f".{out.name}.replaced-", dir=parent))
                os.rename(out, old / "run")
            else:
                out.rmdir()
        os.rename(stage, out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        if old is not None and not out.exists() and (old / "run").exists():
            os.rename(old / "run", out)
        raise
    if old is not None:
        shutil.rmtree(old)


def write_recording(recording: Recording, out: Path, progress: ProgressCallback | None = None,
                    option: str = "--out") -> Path:
    """Validate the output folder, assemble every file, then publish; returns the run folder."""
    out = Path(out)
    check_output_dir(out, KIND, resume=True, resumable=True, option=option)
    files = build_files(recording, progress)
    tick = ticker(progress, "write the run", 1)
    publish(out, files, option)
    tick(1, str(out))
    return out
