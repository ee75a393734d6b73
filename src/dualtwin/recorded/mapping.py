"""The mapping files that say how a user's recording becomes run channels (typed, saved in the run).

Two mappings share one channel model (:class:`ChannelBase`: which run channel, which source, the unit as
recorded and a scale):

* :class:`TableMapping` for CSV/TSV logs: one file per scenario, a time column and a column per channel.
* :class:`BagMapping` for ROS 2 bags in MCAP: a topic and message field per channel, and scenario boundaries
  either as time ranges in one bag or as one bag per scenario.

The paper's TestOrchestrator format is a fixed :class:`TableMapping` (see :mod:`dualtwin.recorded.paper`).

A CSV per scenario, in milliseconds, degrees counted the other way and millimetres::

    files: logs/run_*.csv              # a glob (natural order: run_2 before run_10) or a list
    time: {column: stamp_ms, unit: ms} # origin auto: wall-clock stamps are re-based
    channels:
      - {name: pole_angle_rad, column: theta_deg, unit: deg, scale: -1}
      - {name: cart_pos_m, column: x_mm, unit: mm}
      - {name: pole_angle_rad, source: onboard, column: encoder_rad, unit: rad}

One ROS 2 bag cut into the suite's scenarios by time ranges (seconds from the bag's first mapped message)::

    files: drive.mcap
    stamp: header                      # or log_time (default)
    scenarios: [{start_s: 0, end_s: 3}, {start_s: 4, end_s: 7}]
    channels:
      - {name: forward_m, topic: /odom, field: pose.pose.position.x, unit: m}
      - {name: heading_rad, topic: /odom, field: pose.pose.orientation, angle: yaw, unit: rad}
      - {name: left_wheel_rad, source: onboard, topic: /joint_states, field: position,
         element: front_left_wheel, unit: rad}
Paths in a mapping are relative to a data folder (by default the mapping file's own folder) and may not
leave it: a mapping is a file, and every path read from a file is confined to its folder.
"""

from __future__ import annotations

import glob as globlib
import re
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from dualtwin.artifacts import resolved
from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel

Source = Literal["ground_truth", "onboard"]
TimeUnit = Literal["s", "ms", "us", "ns"]  # the time units of dualtwin.recorded.units

#: The largest time in a bag, in seconds: ROS stamps are int64 nanoseconds (about 292 years), and a range is
#: turned into nanoseconds as an integer; a larger bound could only be a mistake, and 1e300 s overflows that.
MAX_BAG_TIME_S = 9.2e9


def _file_names(files: str | list[str]) -> str | list[str]:
    # The OS cannot open a path holding NUL (Python raises ValueError deep in the path functions), so it is
    # refused here, where the mapping's field can be named.
    if any("\x00" in name for name in ([files] if isinstance(files, str) else files)):
        raise ValueError("a file name or pattern cannot hold a NUL character")
    return files


class ChannelBase(FrozenModel):
    """One run channel read from a recording.

    The value written is ``recorded * scale``, converted from ``unit`` to the unit the binding declares for
    the channel. A sign convention that differs from the twin's (a cart that counts positive the other way)
    is ``scale: -1``: explicit, and recorded in the run's manifest.
    """

    name: str = Field(min_length=1, description="the binding's channel name (its ground_truth or onboard key)")
    source: Source = Field(default="ground_truth", description="ground_truth (the supervisor's view) or onboard")
    unit: str = Field(description="the unit the recording uses (m, mm, cm, rad, deg, m/s, deg/s ...)")
    scale: float = Field(default=1.0, description="multiplies the recorded value (-1 flips a sign convention)")

    @property
    def run_name(self) -> str:
        """The channel's name in the run: ground truth under its own name, on-board as ``onboard/<name>``."""
        return self.name if self.source == "ground_truth" else f"onboard/{self.name}"


def _unique_channels(channels: list[ChannelBase]) -> None:
    names = [c.run_name for c in channels]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"channels mapped twice: {dupes}")


class TimeColumn(FrozenModel):
    """Where a table's time stamps are and what they count."""

    column: str = Field(min_length=1)
    unit: TimeUnit = "s"
    origin: Literal["auto", "simulation", "rebase"] = Field(
        default="auto",
        description="simulation: stamps already count simulation time from the scenario's start; rebase: "
                    "they are wall-clock (or any clock), so the first sample is moved to first_sample_s; "
                    "auto: rebase when a file's first stamp is later than 10 control periods",
    )
    first_sample_s: float = Field(default=0.0, ge=0,
                                  description="simulation time of a re-based file's first sample")


class TableChannel(ChannelBase):
    column: str = Field(min_length=1, description="header name of the column holding the channel")


class TableMapping(FrozenModel):
    """CSV/TSV logs, one file per scenario (in the suite's scenario order)."""

    format: Literal["table"] = "table"
    files: str | list[str] = Field(description="a glob pattern (files sorted naturally: log_2 before log_10) "
                                               "or the list of files, one per scenario")
    delimiter: Literal["auto", ",", "\t", ";"] = Field(
        default="auto", description="auto: tab for .tsv, comma for .csv, else whichever the header holds")
    time: TimeColumn
    channels: list[TableChannel] = Field(min_length=1)

    _files = field_validator("files")(_file_names)

    @model_validator(mode="after")
    def _check(self) -> TableMapping:
        _unique_channels(list(self.channels))
        return self


class TimeRange(FrozenModel):
    """A scenario's span in a bag, seconds from the bag's first mapped message."""

    start_s: float = Field(ge=0, le=MAX_BAG_TIME_S)
    end_s: float = Field(le=MAX_BAG_TIME_S)

    @model_validator(mode="after")
    def _ordered(self) -> TimeRange:
        if self.end_s <= self.start_s:
            raise ValueError("end_s must be after start_s")
        return self


class BagChannel(ChannelBase):
    """A message field of a topic; arrays select one element by ``element`` (a name) or ``index``."""

    topic: str = Field(min_length=1)
    field: str = Field(min_length=1, pattern=r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$",
                       description="dotted message field path, e.g. position or pose.pose.position.x")
    element: str | None = Field(default=None, description="for an array field: the entry whose position in "
                                                          "the message's `name` list has this name (JointState)")
    index: int | None = Field(default=None, ge=0, description="for an array field: this entry")
    angle: Literal["roll", "pitch", "yaw"] | None = Field(
        default=None, description="the field is a quaternion (x, y, z, w): take this Euler angle, radians")

    @model_validator(mode="after")
    def _one_selector(self) -> BagChannel:
        if self.element is not None and self.index is not None:
            raise ValueError("give at most one of 'element' or 'index'")
        return self


class BagMapping(FrozenModel):
    """ROS 2 bags in MCAP: one bag per scenario, or one bag cut into scenarios by time ranges."""

    format: Literal["mcap"] = "mcap"
    files: str | list[str] = Field(description="a glob pattern or a list of bags; one bag when `scenarios` "
                                               "gives time ranges, else one bag per scenario")
    stamp: Literal["log_time", "header"] = Field(
        default="log_time", description="log_time: the bag's record time; header: the message's header.stamp")
    scenarios: list[TimeRange] | None = Field(default=None, description="one time range per scenario")
    channels: list[BagChannel] = Field(min_length=1)

    _files = field_validator("files")(_file_names)

    @model_validator(mode="after")
    def _check(self) -> BagMapping:
        _unique_channels(list(self.channels))
        return self


def load_mapping(path: Path, model: type[TableMapping] | type[BagMapping]) -> TableMapping | BagMapping:
    """Read and validate a YAML mapping; errors name the file and the field (``$.channels[1].unit``)."""
    from dualtwin.artifacts import read_yaml
    from dualtwin.models import validation_message

    path = Path(path)
    data = read_yaml(path, "mapping file")
    if not isinstance(data, dict):
        raise DualtwinError(f"{path}: a mapping file must hold a YAML mapping (keys such as files, channels)")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise DualtwinError(validation_message(path, exc)) from None


def _natural_key(path: Path) -> list[object]:
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", path.name)]


def resolve_files(files: str | list[str], data_dir: Path, where: str) -> list[Path]:
    """The mapping's files under ``data_dir``, each confined to it; a glob is sorted naturally.

    Raises:
        DualtwinError: A path that leaves ``data_dir``, a listed file that is missing, or a glob matching none.
    """
    root = resolved(Path(data_dir))
    if isinstance(files, str) and globlib.has_magic(files):
        found = sorted((Path(p) for p in globlib.glob(str(root / files))), key=_natural_key)
        if not found:
            raise DualtwinError(f"{where}: files: pattern {files!r} matches nothing in {data_dir}")
        names = [str(p) for p in found]
    else:
        names = [files] if isinstance(files, str) else list(files)
    out: list[Path] = []
    for name in names:
        candidate = resolved(root / name)
        if not candidate.is_relative_to(root):
            raise DualtwinError(f"{where}: files: {name!r} is outside the data folder {data_dir}")
        out.append(candidate)
    return out
