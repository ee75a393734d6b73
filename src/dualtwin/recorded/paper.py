"""The paper's TestOrchestrator logs: ``simulation_log_SUP_<i>.tsv``, one per scenario.

``<i>`` is the scenario's 0-based index in the suite; the header is ``time_s  pole_angle_rad  cart_pos_m``
(tab-separated), ground truth from the supervisor, in seconds, radians and metres.

Real logs from that orchestrator are messy, and the import is lenient where it can be without guessing:

* its stamps may be wall-clock (it paced itself with ``time.sleep``) or a simulation clock that runs across
  the whole suite: a file whose first stamp is later than a few control periods is re-based so that its first
  sample is at one control period, where the orchestrator takes its first sample (after the first step);
* stamps may jitter and be irregular: samples are interpolated onto the control-period grid;
* logging may start late: grid points before the first sample hold it;
* values may be rounded (to 3 decimals, say): kept as they are, and the rounding is reported;
* a file may be shorter than its scenario (the scenario ended early): the log is shorter, and noted;
* the state may carry over from the previous scenario (no reset): reported where the first sample is far
  from the suite's initial condition.

All of it is written into the manifest, per scenario.
"""

from __future__ import annotations

import re
from pathlib import Path

from dualtwin.artifacts import check_output_dir
from dualtwin.errors import DualtwinError
from dualtwin.recorded.build import KIND, write_recording
from dualtwin.recorded.mapping import TableChannel, TableMapping, TimeColumn
from dualtwin.recorded.table import AUTO_REBASE_PERIODS, TIME_DOC, recording_from_tables, resolve_inputs
from dualtwin.reporting.progress import ProgressCallback
from dualtwin.robots.binding import RobotBinding

PAPER_FILE = re.compile(r"^simulation_log_SUP_(\d+)\.tsv$")


def paper_file_name(index: int) -> str:
    return f"simulation_log_SUP_{index}.tsv"


def paper_mapping(files: list[str], period: float) -> TableMapping:
    """The paper's format as a table mapping (saved in the run like any user's mapping)."""
    return TableMapping(
        files=files,
        delimiter="\t",
        time=TimeColumn(column="time_s", unit="s", origin="auto", first_sample_s=period),
        channels=[
            TableChannel(name="pole_angle_rad", source="ground_truth", column="pole_angle_rad", unit="rad"),
            TableChannel(name="cart_pos_m", source="ground_truth", column="cart_pos_m", unit="m"),
        ],
    )


def paper_files(log_dir: Path, count: int) -> list[Path]:
    """The folder's ``simulation_log_SUP_<i>.tsv`` for ``i = 0 .. count-1``.

    Raises:
        DualtwinError: The folder is not one; a file is missing, extra (an index past the suite) or given
            twice (``_01`` and ``_1``). Other files in the folder are ignored.
    """
    log_dir = Path(log_dir)
    if not log_dir.is_dir():
        what = "does not exist" if not log_dir.exists() else "is not a folder"
        raise DualtwinError(f"{log_dir}: {what}; give the folder holding simulation_log_SUP_<i>.tsv")
    found: dict[int, list[str]] = {}
    for entry in sorted(p.name for p in log_dir.iterdir()):
        match = PAPER_FILE.match(entry)
        if match:
            found.setdefault(int(match.group(1)), []).append(entry)
    twice = {i: names for i, names in found.items() if len(names) > 1}
    if twice:
        i, names = min(twice.items())
        raise DualtwinError(f"{log_dir}: scenario {i} has more than one log: {', '.join(names)}")
    missing = [paper_file_name(i) for i in range(count) if i not in found]
    extra = [found[i][0] for i in sorted(found) if i >= count]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"missing {', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}")
        if extra:
            parts.append(f"extra {', '.join(extra[:5])}{' ...' if len(extra) > 5 else ''} (the suite has "
                         f"scenarios 0 to {count - 1})")
        raise DualtwinError(f"{log_dir}: logs do not match the suite's {count} scenario(s): {'; '.join(parts)}")
    return [log_dir / found[i][0] for i in range(count)]


def import_paper(log_dir: Path, suite: Path, robot: str | Path | RobotBinding, out: Path,
                 progress: ProgressCallback | None = None, invalid: str = "error") -> Path:
    """Import a folder of the paper's TestOrchestrator logs as a recorded run; returns the run folder.

    Args:
        log_dir: The folder holding ``simulation_log_SUP_<i>.tsv``.
        suite: The suite that was run (the logs pair with its scenarios by index).
        robot: A bundled robot name, a binding file or a loaded binding; it must have ground-truth channels
            ``pole_angle_rad`` and ``cart_pos_m``.
        out: The run folder to write (absent, empty, or an earlier import).
        progress: Receives progress events (`dualtwin.reporting.progress`) while files are read and written.
        invalid: What infinite or absurd values do (`dualtwin.recorded.build.INVALID_TREATMENTS`).
    """
    check_output_dir(Path(out), KIND, resume=True, resumable=True)
    suite_model, binding = resolve_inputs(Path(suite), robot)
    period = suite_model.global_settings.control_period_s
    files = paper_files(Path(log_dir), len(suite_model.scenarios))
    names = [str(Path(log_dir) / f.name) for f in files]
    mapping = paper_mapping([f.name for f in files], period)
    time_doc = {"column": "time_s", "unit": "s", "origin": "auto",
                "rule": f"a file whose first stamp is later than {AUTO_REBASE_PERIODS} control periods is "
                        "re-based so that its first sample is at one control period (the orchestrator samples "
                        "after each step)", **TIME_DOC}
    recording = recording_from_tables(files, names, mapping, suite_model, Path(suite), binding, "paper", None,
                                      str(log_dir), time_doc, progress)
    recording.invalid = invalid
    return write_recording(recording, Path(out), progress)
