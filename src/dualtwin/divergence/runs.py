"""Load suite run directories (comparing two of them is :mod:`dualtwin.divergence.comparison`).

A run directory is written by the suite runner::

    RUN/
      manifest.json
      scenarios/<id>/onboard.tsv        # TestRobot log: on-board sensors
      scenarios/<id>/ground_truth.tsv   # TestOrchestrator log: privileged ground truth

Each TSV has a header row, ``time_s`` first, then one column per channel. The manifest says which file
holds which channel. This module does the I/O only.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import check_size, resolved, verify_logs
from dualtwin.divergence.metrics import (
    FloatArray,
    default_resolution,
)
from dualtwin.errors import DualtwinError
from dualtwin.suite.manifest import ScenarioRecord, read_run_manifest

SOURCES = ("onboard", "ground_truth")


@dataclass(frozen=True, eq=False)
class Series:
    """One channel of one scenario: time stamps and values."""

    t: FloatArray
    y: FloatArray


@dataclass(frozen=True)
class ChannelInfo:
    """Manifest entry of a channel: which log holds it and its unit."""

    name: str
    source: str
    unit: str = ""
    column: str = ""
    #: Declared by the binding (None: `dualtwin.divergence.metrics.default_resolution` of the unit).
    resolution: float | None = None

    @property
    def resolved_resolution(self) -> float:
        """The channel's resolution: declared, else the default for its unit."""
        return self.resolution if self.resolution is not None else default_resolution(self.unit)

    @property
    def log_column(self) -> str:
        """The TSV column holding the channel (both logs may use the same column names)."""
        return self.column or self.name


@dataclass(frozen=True)
class ScenarioEntry:
    """Manifest entry of a scenario; log paths are relative to the run directory (None if absent)."""

    id: str
    index: int
    name: str
    status: str
    failure: Mapping[str, Any] | None = None
    onboard: str | None = None
    ground_truth: str | None = None
    #: Ensemble members 1..N-1 (`dualtwin.suite.ensemble`); member 0 is this entry's own logs.
    members: tuple[MemberEntry, ...] = ()
    #: What an import read from a recording's data about its start (`dualtwin.recorded.carryover`): state
    #: carried over from the previous scenario, or a start away from the twin's reset state.
    state_notes: tuple[str, ...] = ()

    def log(self, source: str) -> str | None:
        return self.onboard if source == "onboard" else self.ground_truth


@dataclass(frozen=True)
class MemberEntry:
    """One perturbed ensemble member of a scenario: its logs (relative to the run) and how it ended."""

    member: int
    status: str
    onboard: str | None = None
    ground_truth: str | None = None

    def log(self, source: str) -> str | None:
        return self.onboard if source == "onboard" else self.ground_truth


@dataclass(frozen=True)
class Run:
    """A loaded run manifest. Logs are read on demand with `series`."""

    path: Path
    twin: str
    robot: str
    suite_name: str
    control_period_s: float | None
    seed: int | None
    scenarios: tuple[ScenarioEntry, ...]
    channels: Mapping[str, ChannelInfo]
    tolerances: Mapping[str, Mapping[str, Mapping[str, float]]] = field(default_factory=dict)
    #: ``simulated`` (a twin ran the suite) or ``recorded`` (imported from logs we did not make).
    kind: str = "simulated"

    def scenario(self, scenario_id: str) -> ScenarioEntry:
        for entry in self.scenarios:
            if entry.id == scenario_id:
                return entry
        raise KeyError(f"{self.path}: no scenario {scenario_id!r}")

    def members(self, scenario_id: str) -> list[dict[str, Series]]:
        """Every ensemble member's series of a scenario, member 0 (the main logs) first; [] without members."""
        entry = self.scenario(scenario_id)
        if not entry.members:
            return []
        return [self.series(scenario_id), *(self._read(m) for m in entry.members)]

    def series(self, scenario_id: str) -> dict[str, Series]:
        """Read the scenario's logs and return every manifest channel found in them.

        A log that the manifest omits or that does not exist contributes nothing, so callers decide
        whether that is an error (it is not for an unstable scenario).
        """
        return self._read(self.scenario(scenario_id))

    def _read(self, entry: ScenarioEntry | MemberEntry) -> dict[str, Series]:
        out: dict[str, Series] = {}
        for source in SOURCES:
            rel = entry.log(source)
            if rel is None or not (self.path / rel).is_file():
                continue
            header, data = load_tsv(self.path / rel)
            columns = {column: i for i, column in enumerate(header)}
            for name, info in self.channels.items():
                col = columns.get(info.log_column)
                if info.source == source and col is not None and col > 0:
                    out[name] = Series(t=data[:, 0].copy(), y=data[:, col].copy())
        return out


#: The largest run log read (bytes). A log is read whole and parsed into Python floats (several times its size
#: in memory), so a larger file is refused before reading rather than exhausting memory. The longest log the
#: project writes has dualtwin.suite.schema.MAX_SUITE_PERIODS (10**6) rows; the widest bundled robot's rows are
#: about 400 bytes (the arm's ground truth), so this leaves room for rows of 1 KiB.
MAX_LOG_BYTES = 1 << 30


def load_tsv(path: Path) -> tuple[list[str], FloatArray]:
    """Read a run log.

    Returns:
        The header names (first is ``time_s``) and an ``(n_rows, n_columns)`` float64 array; zero rows
        when the log holds only a header.

    Raises:
        DualtwinError: On a file larger than :data:`MAX_LOG_BYTES`, bytes that are not UTF-8, a missing
            ``time_s`` column, a malformed row, an unparsable value, or a time stamp that is not finite or does
            not increase. A short last row without a trailing newline is dropped: a run that crashed mid-write
            leaves one.
    """
    check_size(path, "run log", MAX_LOG_BYTES)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DualtwinError(f"{path}: not a UTF-8 text run log (binary data at byte {exc.start})") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise DualtwinError(f"{path}: empty log, expected a header row")
    header = lines[0].split("\t")
    if header[0] != "time_s":
        raise DualtwinError(f"{path}: first column must be 'time_s', got {header[0]!r}")
    if len(set(header)) != len(header):
        raise DualtwinError(f"{path}: duplicate columns in header {header}")
    rows: list[list[float]] = []
    body = lines[1:]
    for lineno, line in enumerate(body, start=2):
        if not line.strip():
            continue
        cells = line.split("\t")
        truncated_tail = lineno == len(lines) and not text.endswith("\n")
        if len(cells) != len(header):
            if truncated_tail:
                break
            raise DualtwinError(f"{path}:{lineno}: expected {len(header)} columns, got {len(cells)}")
        try:
            rows.append([float(c) for c in cells])
        except ValueError as exc:
            if truncated_tail:
                break
            raise DualtwinError(f"{path}:{lineno}: {exc}") from None
    data = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(header))
    _check_time(path, data[:, 0], [lineno for lineno, line in enumerate(body, start=2) if line.strip()])
    return header, data


def _check_time(path: Path, t: FloatArray, linenos: list[int]) -> None:
    """Every writer of run logs (the suite runner, the importers, lockstep) stamps rows on a clock that only
    moves forward: a NaN or a stamp that repeats or goes back was written in by hand or by another tool, and
    would reach the metrics as a silent NaN or a resampling error that names no file."""
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise DualtwinError(f"{path}:{linenos[i]}: time_s {float(t[i])} is not a finite number")
    back = np.diff(t) <= 0
    if back.any():
        i = int(np.argmax(back)) + 1
        raise DualtwinError(f"{path}:{linenos[i]}: time_s must increase: {float(t[i])!r} s after {float(t[i - 1])!r} s")


def _confined(root: Path, rel: str | None, where: str, source: str) -> str | None:
    """``rel`` if it names a path inside the run folder: a manifest is data and must not point readers elsewhere."""
    if rel is not None and not resolved(root / rel).is_relative_to(resolved(root)):
        raise DualtwinError(f"{where}: {source} log {rel!r} is outside the run folder")
    return rel


def _members(record: ScenarioRecord, root: Path, manifest_path: Path) -> tuple[MemberEntry, ...]:
    """A scenario's ensemble members; their log paths must stay inside the run folder."""
    out: list[MemberEntry] = []
    for j, m in enumerate(record.members or []):
        where = f"{manifest_path}: scenario {record.id!r}: members[{j}]"
        out.append(MemberEntry(member=m.member, status=m.status,
                               onboard=_confined(root, m.onboard, where, "onboard"),
                               ground_truth=_confined(root, m.ground_truth, where, "ground_truth")))
    return tuple(out)


def load_run(path: Path) -> Run:
    """Load and validate ``path/manifest.json``.

    Raises:
        DualtwinError: If the manifest does not have the shape of `RunManifest` (naming the JSON path), a
            log path leaves the run folder, scenario ids repeat or a log differs from its record.
    """
    path = Path(path)
    manifest_path = path / "manifest.json"
    if not path.is_dir() or not manifest_path.exists():
        raise DualtwinError(f"{path}: not a run directory (no manifest.json)")
    raw, manifest = read_run_manifest(manifest_path)

    channels = {name: ChannelInfo(name=name, source=spec.source, unit=spec.unit, column=spec.column,
                                  resolution=spec.resolution)
                for name, spec in manifest.channels.items()}
    scenarios: list[ScenarioEntry] = []
    for i, sc in enumerate(manifest.scenarios):
        where = f"{manifest_path}: scenario {sc.id!r}"
        scenarios.append(
            ScenarioEntry(
                id=sc.id,
                index=i if sc.index is None else sc.index,
                name=sc.id if sc.name is None else sc.name,
                status=sc.status,
                failure=sc.failure,
                onboard=_confined(path, sc.onboard, where, "onboard"),
                ground_truth=_confined(path, sc.ground_truth, where, "ground_truth"),
                members=_members(sc, path, manifest_path),
                state_notes=tuple(part.note for part in (sc.state_continuity or {}).values()),
            )
        )
    ids = [s.id for s in scenarios]
    dupes = sorted({i for i in ids if ids.count(i) > 1})
    if dupes:
        raise DualtwinError(f"{manifest_path}: duplicate scenario ids {dupes}")
    # Logs are verified against the manifest's row counts and hashes (dualtwin.artifacts.log_record) before
    # anything is compared. Runs written before manifests recorded them (no 'logs') load unverified.
    if "logs" in raw:
        verify_logs(path, raw["logs"], manifest_path)

    # A recorded run was made by no twin of ours: its "twin" is optional and only labels it.
    twin = manifest.twin or ("recorded" if manifest.kind == "recorded" else None)
    if twin is None:
        raise DualtwinError(f"{manifest_path}: manifest has no 'twin'")
    return Run(
        path=path,
        twin=twin,
        kind=manifest.kind,
        robot=manifest.robot,
        suite_name=manifest.suite_name,
        control_period_s=manifest.control_period_s,
        seed=manifest.seed,
        scenarios=tuple(scenarios),
        channels=channels,
        tolerances=manifest.tolerances or {},
    )
