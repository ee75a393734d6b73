"""What a reference offers an alignment: the scenarios and channels it shares with the suite, its ensemble.

A recording usually logs fewer channels than the twin and may cover only some scenarios: alignment fits what
is shared and lists what it left out, with why, and stops with one line only when nothing is shared. An
ensemble reference run (``suite run --ensemble``) also offers its members' initial-condition shifts, so the
target can be simulated under the same shifts (``align(..., ensemble="mean")``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualtwin.align.simulate import Traces, ensemble_offsets, load_member_traces
from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding


@dataclass(frozen=True)
class SharedWithReference:
    """The scenarios and channels that both the suite/robot and the reference have, and what was left out."""

    scenarios: list[str]
    channels: list[str]
    left_out: dict[str, dict[str, str]]


def shared_with_reference(reference: Traces, ids: Sequence[str], channels: Sequence[str],
                          where: Path) -> SharedWithReference:
    """Scenarios (suite order) and channels (binding order) both sides have; what one side lacks, with why.

    A recording usually logs fewer channels than the twin, and may cover only some scenarios: alignment fits
    what is shared and says what it left out.

    Raises:
        DualtwinError: One line naming both sides when no scenario or no channel is shared.
    """
    scenarios = [s for s in ids if s in reference]
    if not scenarios:
        raise DualtwinError(f"{where}: the reference shares no scenario with the suite: the suite has {list(ids)}, "
                            f"the reference has {sorted(reference)}")
    logged = [c for c in dict.fromkeys(c for sid in scenarios for c in reference[sid].series)]
    shared = [c for c in channels if c in logged]
    if not shared and not all(reference[s].status == "unstable" for s in scenarios):
        raise DualtwinError(f"{where}: the reference shares no channel with the robot binding: the binding logs "
                            f"{list(channels)}, the reference {logged}")
    left: dict[str, dict[str, str]] = {"scenarios": {}, "channels": {}}
    for sid in ids:
        if sid not in reference:
            left["scenarios"][sid] = "not in the reference: simulated, not fitted"
    for sid in reference:
        if sid not in ids:
            left["scenarios"][sid] = "not in the suite: nothing to simulate"
    for c in channels:
        if c not in logged:
            left["channels"][c] = "not logged by the reference"
    for c in logged:
        if c not in channels:
            left["channels"][c] = "not a channel of the robot binding"
    return SharedWithReference(scenarios, shared, {k: v for k, v in left.items() if v})


def check_reference_run(path: Path, channel_info: Mapping[str, Mapping[str, Any]], scenarios: Sequence[str]) -> None:
    """What the comparisons after the fit would refuse in a reference run, refused before the output folder is
    made: a channel the binding shares in another unit, or one the manifest declares and a fitted scenario's
    logs lack (before, both stopped align after it had written its configuration and simulated runs/before).

    Raises:
        DualtwinError: One line naming the reference run and the channels.
    """
    run = load_run(path)
    shared = [c for c in run.channels if c in channel_info]
    units = sorted(f"{c}: {run.channels[c].unit!r} (binding {channel_info[c].get('unit')!r})" for c in shared
                   if run.channels[c].unit != channel_info[c].get("unit"))
    if units:
        raise DualtwinError(f"{path}: the reference logs channels in other units than the robot binding: {units}")
    for sid in scenarios:
        entry = run.scenario(sid)
        missing = [c for c in shared if c not in run.series(sid)]
        if missing and entry.status != "unstable":
            raise DualtwinError(f"{path}: scenario {sid!r} ({entry.status}) has no log data for channels {missing}, "
                                "which its manifest declares")


def ensemble_members_of(reference: str | Path, kind: str, scenarios: Sequence[str],
                              binding: RobotBinding) -> list[dict[str, float]]:
    """The member shifts of an ensemble reference run, checked before anything is written."""
    if kind != "run":
        raise DualtwinError("ensemble 'mean' needs a reference run with ensemble members (suite run --ensemble N "
                            "--perturb KEY=EPS), not a twin")
    offsets = ensemble_offsets(Path(reference))
    if len(offsets) < 2:
        raise DualtwinError(f"{reference}: ensemble 'mean' needs a run with ensemble members; this one has none "
                            "(make it with suite run --ensemble N --perturb KEY=EPS)")
    unknown = sorted({k for o in offsets for k in o} - set(binding.spec.initial_conditions))
    if unknown:
        raise DualtwinError(f"{reference}: ensemble shifts name {unknown}, which are not initial conditions of "
                            f"robot {binding.name!r}")
    members = load_member_traces(Path(reference), list(scenarios))
    lacking = [s for s in scenarios if len(members.get(s, [])) != len(offsets)]
    if lacking:
        raise DualtwinError(f"{reference}: scenarios {lacking} do not hold all {len(offsets)} ensemble members")
    return offsets
