"""The shape of a run folder's ``manifest.json``, as the readers of a run use it: the suite runner resuming an
interrupted run (`dualtwin.suite.runner`) and `dualtwin.divergence.runs.load_run` (compare, analyze, align).

A run folder is untrusted data (someone else's run, a recording's import, a folder edited by hand), so the
fields those readers use are typed here and checked once, where the manifest is read: a wrong type anywhere (a list for the seed, a number for the tolerances, a string for a failure record)
is one error naming the file and the JSON path, not a traceback deep in the comparison.

Decisions:

* ``extra="allow"`` at every level: the writers (suite runner, recorded import, lockstep) add their own
  records (inputs, versions, ensemble, state continuity, sources ...) that this reader does not use; only the
  fields it reads are typed.
* Names (scenario ids, channels, units, twin, robot, suite) are `dualtwin.models.Name`: reports, plots and
  the terminal show them, so a control character or a megabyte name is refused here.
* Log paths are strings here; that they stay inside the run folder is checked by ``load_run``, which knows
  the folder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import ConfigDict, Field, ValidationError

from dualtwin.artifacts import read_json
from dualtwin.errors import DualtwinError
from dualtwin.models import Name, Note, StrictModel, validation_message
from dualtwin.suite.schema import MAX_SEED

Status = Literal["completed", "failed", "unstable"]
Source = Literal["onboard", "ground_truth"]


class _Record(StrictModel):
    """Typed fields are checked (finite numbers, no coercion surprises); fields a writer adds are kept."""

    model_config = ConfigDict(extra="allow")


class ChannelRecord(_Record):
    source: Source
    unit: Name = ""
    column: Name = ""
    resolution: float | None = Field(default=None, gt=0)


class MemberRecord(_Record):
    member: int = Field(strict=True)
    status: Status
    onboard: str | None = None
    ground_truth: str | None = None


class ContinuityRecord(_Record):
    """One part of a scenario's state continuity (the importer's finding); its note reaches the terminal."""

    note: Note = ""


class ScenarioRecord(_Record):
    id: Name = Field(min_length=1)
    index: int | None = None
    name: Name | None = None
    status: Status
    failure: dict[str, Any] | None = None
    onboard: str | None = None
    ground_truth: str | None = None
    members: list[MemberRecord] | None = None
    state_continuity: dict[Name, ContinuityRecord] | None = None


class OffsetRecord(_Record):
    member: int = Field(strict=True)
    #: initial-condition key -> shift (finite: the model refuses NaN and infinities)
    shift: dict[str, float]


class EnsembleRecord(_Record):
    """Written by `dualtwin.suite.ensemble` once every member is done; alignment reads the shifts back."""

    offsets: list[OffsetRecord] | None = None


class RunManifest(_Record):
    robot: Name
    twin: Name | None = None
    kind: Name = "simulated"
    suite_name: Name = ""
    control_period_s: float | None = Field(default=None, gt=0)
    seed: int | None = Field(default=None, ge=0, le=MAX_SEED)
    channels: dict[Name, ChannelRecord]
    scenarios: list[ScenarioRecord]
    #: scenario id -> channel -> metric -> bound (the suite's tolerances, as the runner copied them).
    tolerances: dict[Name, dict[Name, dict[Name, float]]] | None = None
    #: relative log path -> record; checked by `dualtwin.artifacts.verify_logs`.
    logs: dict[str, Any] | None = None
    ensemble: EnsembleRecord | None = None
    #: input name (suite, binding, model) -> its path and SHA-256; resuming compares the hashes.
    inputs: dict[str, Any] | None = None

    def input_sha256(self, name: str) -> Any:
        """The recorded SHA-256 of input ``name`` (None where the manifest has no such record)."""
        record = (self.inputs or {}).get(name)
        return record.get("sha256") if isinstance(record, dict) else None


def read_run_manifest(manifest_path: Path, context: str = "") -> tuple[dict[str, Any], RunManifest]:
    """The manifest as read (a JSON object, for records to copy as they are) and validated.

    Raises:
        DualtwinError: ``<context><file>: <JSON path>: <what is wrong>`` for invalid JSON or the wrong shape.
    """
    raw = read_json(manifest_path, "run manifest")
    try:
        return raw, RunManifest.model_validate(raw)
    except ValidationError as exc:
        raise DualtwinError(f"{context}{validation_message(manifest_path, exc)}") from None


__all__ = ["ChannelRecord", "EnsembleRecord", "MemberRecord", "OffsetRecord", "RunManifest", "ScenarioRecord",
           "read_run_manifest"]
