"""Runs a suite on a twin and writes one on-board and one ground-truth log per scenario.

Run directory layout::

    RUN/manifest.json                       config, versions, input hashes, seed, scenario statuses
    RUN/config/suite.json, binding.yaml     exact copies of the inputs
    RUN/scenarios/<id>/onboard.tsv          TestRobot log (on-board sensors)
    RUN/scenarios/<id>/ground_truth.tsv     TestOrchestrator log (privileged ground truth)

Every file is written atomically and the manifest is rewritten after each scenario, so a run that dies keeps
what it finished, and ``resume=True`` runs only the rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualtwin.artifacts import (
    check_output_dir,
    copy_file,
    log_record,
    package_versions,
    resolved,
    sha256_file,
    verify_logs,
    write_json,
    write_text,
)
from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.models import json_path
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.loader import load_suite
from dualtwin.suite.manifest import read_run_manifest
from dualtwin.suite.physical import check_initial_value, impossible_reason, joint_stops
from dualtwin.suite.schema import Scenario, Suite
from dualtwin.suite.signals import Signal
from dualtwin.twins import make_twin
from dualtwin.twins.base import Twin
from dualtwin.twins.io import RobotIO

# Version 2 adds ``kind`` ("suite-run") and ``logs``: per log file (relative path) its data rows, bytes and
# SHA-256 (see dualtwin.artifacts.log_record), so every reader can verify the logs it compares.
MANIFEST_VERSION = 2
KIND = "suite-run"
MAX_SEED = 2**32 - 1


def check_against_binding(suite: Suite, suite_path: Path, robot: RobotBinding) -> None:
    """Every robot-specific key must resolve through the binding, before anything is simulated or written."""
    spec = robot.spec
    known = sorted(set(spec.initial_conditions) | set(spec.actions))
    stops = joint_stops(robot) if any(k in spec.initial_conditions for s in suite.scenarios for k in s.inputs) else {}
    for i, scenario in enumerate(suite.scenarios):
        for key, value in scenario.inputs.items():
            where = json_path(("scenarios", i, key))
            if key in spec.initial_conditions:
                if not isinstance(value, float):
                    raise DualtwinError(f"{suite_path}: {where}: initial condition {key!r} must be a number")
                check_initial_value(key, value, stops, f"{suite_path}: {where}", robot)
            elif key not in spec.actions:
                raise DualtwinError(f"{suite_path}: {where}: unknown robot-specific key {key!r}; "
                                    f"robot {robot.name!r} knows: {', '.join(known)}")
        for channel in scenario.tolerances:
            if channel not in spec.ground_truth and channel.removeprefix("onboard/") not in spec.onboard:
                raise DualtwinError(f"{suite_path}: {json_path(('scenarios', i, 'tolerances', channel))}: "
                                    f"unknown channel {channel!r}")
    for key in suite.global_settings.thresholds:
        if key not in spec.failures:
            raise DualtwinError(f"{suite_path}: {json_path(('global_settings', key))}: unknown setting {key!r}; "
                                f"robot {robot.name!r} knows failure keys: {', '.join(sorted(spec.failures)) or 'none'}")


@dataclass
class ScenarioResult:
    id: str
    status: str
    failure: dict[str, Any] | None
    steps: int


def format_rows(names: Sequence[str], rows: Sequence[Sequence[float]]) -> str:
    """A TSV log: ``time_s``, the named columns, floats as their shortest ``repr`` (exact round trip)."""
    lines = ["\t".join(["time_s", *names])]
    lines.extend("\t".join(map(repr, row)) for row in rows)
    return "\n".join(lines) + "\n"


#: What `scenario_periods` returns: the scenario's result and its two logs (rows of time followed by channels).
ScenarioLogs = tuple[ScenarioResult, list[list[float]], list[list[float]]]
#: What a driver may send a period generator after a period: the period's samples, ``(onboard, ground_truth)``
#: values in the binding's channel order, or None for the generator to read them itself.
Samples = tuple[list[float], list[float]] | None
#: A simulation that yields once per control period for its twin's physics to be stepped (see `drive`).
Periods = Generator[None, Samples, Any]


def run_scenario(io: RobotIO, scenario: Scenario, seed: int, thresholds: dict[str, float],
                 fresh: bool, offsets: Mapping[str, float] | None = None) -> ScenarioLogs:
    """Simulate one scenario; returns its result and the two logs (rows of time followed by channels).

    ``offsets`` (initial-condition key -> shift) move a fresh scenario's initial conditions, for ensembles
    (`dualtwin.suite.ensemble`): a key the scenario does not set is shifted from the twin's reset value.
    """
    result: ScenarioLogs = drive(scenario_periods(io, scenario, seed, thresholds, fresh, offsets), io.twin.step)
    return result


def drive(periods: Periods, step: Callable[[], None]) -> Any:
    """Run a period generator to its end, stepping its twin with ``step`` (e.g. ``twin.step``) at each yield;
    a `SimulationUnstable` that ``step`` raises is thrown into the generator where it yielded."""
    try:
        next(periods)
        while True:
            try:
                step()
            except SimulationUnstable as exc:
                periods.throw(exc)
            else:
                periods.send(None)
    except StopIteration as stop:
        return stop.value


_SIGNAL_TABLES: dict[tuple[type, str, float, int], list[float]] = {}


def signal_values(signal: Signal, period: float, steps: int) -> list[float]:
    """``signal(k * period)`` for ``k`` in ``range(steps)``, as the period loop evaluates it, kept for the next
    twin that runs an equal signal: signals are frozen documents and pure functions of time
    (`dualtwin.suite.signals`), and their repr gives every field exactly (floats round-trip)."""
    key = (type(signal), repr(signal), period, steps)
    values = _SIGNAL_TABLES.get(key)
    if values is None:
        values = [signal(k * period) for k in range(steps)]
        if len(_SIGNAL_TABLES) >= 256:
            _SIGNAL_TABLES.clear()
        _SIGNAL_TABLES[key] = values
    return values


def scenario_periods(io: RobotIO, scenario: Scenario, seed: int, thresholds: dict[str, float],
                     fresh: bool, offsets: Mapping[str, float] | None = None) -> Generator[None, Samples, ScenarioLogs]:
    """`run_scenario` as a generator: it yields where the twin's physics advances one control period
    (``twin.step()``), so a caller can step many twins' physics together (`dualtwin.twins.mujoco_batch`);
    the step's `SimulationUnstable` comes back through ``throw``. Returns what `run_scenario` does.

    Whoever resumes it after a period may send the period's samples, ``(onboard, ground_truth)`` values in
    the binding's channel order, read for many twins at once (`dualtwin.twins.mujoco_batch.ChannelColumns`);
    None (``next``, `drive`) has the generator read them through ``io``. Either way the values are the same."""
    twin = io.twin
    period = twin.control_period
    if fresh:
        twin.reset(seed)
    inputs = scenario.inputs
    actions = io.robot.spec.actions
    steps = math.ceil(scenario.duration_s / period - 1e-9)
    constant = {k: v for k, v in inputs.items() if k in actions and isinstance(v, float)}
    signals = {k: v for k, v in inputs.items() if k in actions and not isinstance(v, float)}
    if fresh:
        # Positions first: a joint teleport zeroes its subtree's velocity (Webots semantics).
        conditions = io.robot.spec.initial_conditions
        values = {k: v for k, v in inputs.items() if k in conditions}
        for key, shift in (offsets or {}).items():
            values[key] = (values[key] if key in values else io.read_initial(key)) + shift
        # A state no physics can start from (validation refuses it in suites; a library caller or a
        # perturbation may still bring one) is an unstable scenario now, not a simulator left to spin on it.
        for key, value in values.items():
            reason = impossible_reason(value)
            if reason is not None:
                refused: dict[str, Any] = {"time_s": 0.0, "message": f"initial condition {key!r}: {reason}"}
                return ScenarioResult("", "unstable", refused, 0), [], []
        for key in sorted(values, key=lambda k: conditions[k].quantity != "position"):
            io.apply_initial(key, values[key])
    for key, value in constant.items():
        io.apply_action(key, value)
    # The signals' values for every period, computed once per signal and shared by every twin that runs
    # this scenario (a population runs the same one on each candidate), and each action's motor commands.
    command = twin.command
    timed = [(signal_values(signal, period, steps), io.action_commands(key)) for key, signal in signals.items()]
    failures = [(key, io.robot.spec.failures[key].channel, limit) for key, limit in thresholds.items()]
    failure_index = [(key, channel, io.ground_truth_index(channel), limit) for key, channel, limit in failures]

    start = twin.time
    # Like the paper's orchestrator, sample after each control period: a Webots supervisor's teleports only
    # take effect at the next step, so a t = 0 sample would not show the initial condition on every twin.
    onboard: list[list[float]] = []
    truth: list[list[float]] = []
    status, failure = "completed", None
    for k in range(steps):
        for table, commands in timed:
            value = table[k]
            for actuator, mode, scale in commands:  # io.apply_action(key, value)
                command(actuator, mode, value * scale)
        try:
            samples = yield  # twin.step(), by whoever drives this generator
        except SimulationUnstable as exc:
            status, failure = "unstable", {"time_s": round(twin.time - start, 9), "message": str(exc)}
            break
        t = round(twin.time - start, 9)
        if samples is None:
            onboard_row = [t, *io.sample_onboard()]
            truth_row = [t, *io.sample_ground_truth()]
        else:
            onboard_row = [t, *samples[0]]
            truth_row = [t, *samples[1]]
        # A NaN or infinity anywhere makes the sum non-finite; only then is each value looked at (a sum of
        # finite values may overflow).
        if not math.isfinite(sum(onboard_row) + sum(truth_row)) and not all(
                math.isfinite(v) for v in onboard_row + truth_row):
            status, failure = "unstable", {"time_s": t, "message": "non-finite channel value"}
            break
        onboard.append(onboard_row)
        truth.append(truth_row)
        for key, channel, index, limit in failure_index:
            if abs(truth_row[index + 1]) > limit:
                status, failure = "failed", {"key": key, "channel": channel, "time_s": t, "threshold": limit}
                break
        if status == "failed":
            break
    return ScenarioResult("", status, failure, len(truth)), onboard, truth


class SuiteRun:
    """One suite on one twin, writing into ``out_dir``."""

    def __init__(self, suite_path: Path, twin_name: str, robot: RobotBinding, out_dir: Path,
                 seed: int = 0, twin: Twin | None = None) -> None:
        self.suite_path = Path(suite_path)
        self.suite = load_suite(self.suite_path)
        check_against_binding(self.suite, self.suite_path, robot)
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
            raise DualtwinError(f"--seed must be a whole number from 0 to {MAX_SEED}, not {seed!r}")
        self.robot = robot
        self.twin_name = twin_name
        self.out_dir = Path(out_dir)
        self.seed = seed
        self.control_period = self.suite.global_settings.control_period_s
        self._twin = twin

    def _inputs_record(self) -> dict[str, Any]:
        model = self.robot.model_path(self.twin_name)
        return {
            "suite": {"path": str(self.suite_path), "sha256": sha256_file(self.suite_path)},
            "binding": {"path": str(self.robot.path), "sha256": sha256_file(self.robot.path)},
            "model": {"path": str(model), "sha256": sha256_file(model)},
        }

    def run(self, resume: bool = False, on_scenario: Callable[[str, str], None] | None = None,
            replay: Mapping[str, ScenarioLogs] | None = None) -> dict[str, Any]:
        """Simulate every scenario (or, with ``resume``, those an interrupted run left) and write the run.

        ``replay`` (scenario id -> its logs, for every scenario of the suite) writes logs already simulated
        on this twin with the same knobs, suite and seed (an alignment's best candidate, simulated in memory)
        instead of simulating them again: the files are those a simulation writes, byte for byte.
        """
        out = self.out_dir
        if replay is not None and not set(self.suite.scenario_ids()) <= set(replay):
            raise ValueError(f"replay lacks scenarios {sorted(set(self.suite.scenario_ids()) - set(replay))}")
        manifest_path = out / "manifest.json"
        inputs = self._inputs_record()
        done: dict[str, dict[str, Any]] = {}
        logs: dict[str, Any] = {}
        # One output policy (dualtwin.artifacts): empty or new, or this command's own earlier run with resume.
        # A run that failed before its first manifest (only config/ written) is resumable too.
        if check_output_dir(out, KIND, resume=resume, resumable=True) and manifest_path.is_file():
            # The folder is data like any other: its manifest is checked before a record of it is trusted (and
            # copied into the resumed run's manifest).
            raw, previous = read_run_manifest(manifest_path, "cannot resume: ")
            same = all(previous.input_sha256(k) == v["sha256"] for k, v in inputs.items())
            if not same or previous.seed != self.seed or previous.twin != self.twin_name:
                raise DualtwinError(f"{manifest_path}: cannot resume: the suite, binding, model, twin or seed "
                                    "differ from the interrupted run")
            old_logs = previous.logs or {}
            for s, previous_record in zip(previous.scenarios, raw["scenarios"], strict=True):
                if s.onboard is None or s.ground_truth is None:
                    continue
                names = [s.onboard, s.ground_truth]
                outside = [n for n in names if not resolved(out / n).is_relative_to(resolved(out))]
                if outside:
                    raise DualtwinError(f"{manifest_path}: cannot resume: scenario {s.id!r} names a log outside "
                                        f"the run folder: {outside[0]!r}")
                if not all((out / n).is_file() for n in names):
                    continue
                try:  # a finished scenario whose logs changed since is run again
                    verify_logs(out, {n: old_logs[n] for n in names if n in old_logs}, manifest_path)
                except DualtwinError:
                    continue
                done[s.id] = previous_record
                logs.update({n: old_logs[n] if n in old_logs else log_record(out / n) for n in names})

        twin = self._twin or make_twin(self.twin_name, self.robot, self.control_period)
        io = RobotIO(self.robot, twin)
        (out / "config").mkdir(parents=True, exist_ok=True)
        copy_file(self.suite_path, out / "config" / "suite.json")
        copy_file(self.robot.path, out / "config" / "binding.yaml")
        manifest: dict[str, Any] = {
            "manifest_version": MANIFEST_VERSION,
            "kind": KIND,
            "suite_name": self.suite.suite_name,
            "twin": self.twin_name,
            "robot": self.robot.name,
            "seed": self.seed,
            "control_period_s": self.control_period,
            "inputs": inputs,
            "versions": package_versions(),
            "channels": io.channel_info(),
            "tolerances": {},
            "scenarios": [],
            "logs": logs,
        }
        ids = self.suite.scenario_ids()
        thresholds = self.suite.global_settings.thresholds
        need_fresh = True
        try:
            for index, (sid, scenario) in enumerate(zip(ids, self.suite.scenarios, strict=True)):
                next_continues = index + 1 < len(ids) and self.suite.scenarios[index + 1].reset == "continue"
                fresh = need_fresh or scenario.reset == "fresh"
                seed = scenario.seed if scenario.seed is not None else self.seed
                record: dict[str, Any] = {"id": sid, "index": index, "name": scenario.name, "seed": seed,
                          "reset": "fresh" if fresh else "continue",
                          "onboard": f"scenarios/{sid}/onboard.tsv",
                          "ground_truth": f"scenarios/{sid}/ground_truth.tsv"}
                if scenario.tolerances:
                    manifest["tolerances"][sid] = {k: v.model_dump(exclude_none=True)
                                                   for k, v in scenario.tolerances.items()}
                if sid in done and not next_continues:
                    manifest["scenarios"].append(done[sid])
                    need_fresh = True
                    if on_scenario:
                        on_scenario(sid, "skipped (done)")
                    continue
                result, onboard, truth = (replay[sid] if replay is not None
                                          else run_scenario(io, scenario, seed, thresholds, fresh))
                # An unstable end state cannot be continued from: the next scenario starts fresh.
                need_fresh = result.status == "unstable"
                if sid not in done:
                    write_text(out / record["onboard"], format_rows(io.onboard_names, onboard))
                    write_text(out / record["ground_truth"], format_rows(io.ground_truth_names, truth))
                    for name in (record["onboard"], record["ground_truth"]):
                        logs[name] = log_record(out / name)
                    record.update(status=result.status, failure=result.failure, steps=result.steps)
                else:
                    record = done[sid]
                manifest["scenarios"].append(record)
                manifest["logs"] = dict(sorted(logs.items()))  # scenario order: ids start with the index
                write_json(manifest_path, manifest)
                if on_scenario:
                    on_scenario(sid, result.status)
        finally:
            if self._twin is None:
                twin.close()
        manifest["logs"] = dict(sorted(logs.items()))
        write_json(manifest_path, manifest)
        return manifest
