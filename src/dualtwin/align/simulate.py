"""Simulate a suite on a twin in memory, and evaluate many knob settings as one MuJoCo batch, serially, in
processes or on Ray.

A `SimJob` is plain data (paths, names and knob values), so it pickles cheaply: each worker process builds
its own binding, suite and twin once and reuses them for every job (``set_knobs`` applies values from
nominal, so reuse cannot leak one job's knobs into the next). Results are `ScenarioTrace` objects keyed by
scenario id, with the same channel names as a run directory (ground truth by name, on-board channels as
``onboard/<column>``), so recorded runs and fresh simulations compare alike.

MuJoCo batch (`BatchedSimulator`, the `Evaluator`'s default for a MuJoCo target): a population or a
finite-difference Jacobian is a list of jobs that differ only in knob values (and, for an ensemble, initial-
condition shifts). Each job gets its own twin (kept and reused across calls) and runs as the generator
:func:`job_periods`, the very code of the one-at-a-time path, which yields wherever the twin's physics advances
a control period. Every live job is advanced to its next yield, then all their periods are stepped as one
``mujoco.batch`` call on C threads (`dualtwin.twins.mujoco_batch`), and so on: the Python of each job
(scenario inputs, resets between scenarios, failure checks) runs between periods as before. The samples are
read for every job at once: the batch computes the new state's poses and sensors on its threads, and
`~dualtwin.twins.mujoco_batch.ChannelColumns` reads the binding's channels from its arrays, which the driver
sends into each job's generator (a twin with sensor noise, bias, resolution or delay reads its own). Signal
values are computed once per scenario signal and shared (`dualtwin.suite.runner.signal_values`). Jobs may be
in different scenarios or at different times; one that ends (finished, failed or unstable) leaves the batch. Traces are bit-identical to simulating each job alone, at any thread count
(tests/align/test_batched.py).
"""

from __future__ import annotations

from collections.abc import Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from dualtwin.align import nuisance
from dualtwin.divergence.runs import Series, load_run
from dualtwin.errors import DualtwinError
from dualtwin.parallel import DEFAULT_WORKERS, EXECUTORS, ExecutorKind, ParallelMap, check_executor
from dualtwin.robots.binding import RobotBinding, load_binding
from dualtwin.suite.loader import load_suite
from dualtwin.suite.manifest import read_run_manifest
from dualtwin.suite.runner import (
    Periods,
    Samples,
    ScenarioLogs,
    ScenarioResult,
    check_against_binding,
    drive,
    scenario_periods,
)
from dualtwin.suite.schema import Suite
from dualtwin.twins import make_twin
from dualtwin.twins.base import Twin
from dualtwin.twins.io import RobotIO

if TYPE_CHECKING:
    from dualtwin.twins.mujoco_batch import ChannelColumns, TwinBatch

BatchMode = Literal["auto", "threads", "off"]
BATCH_MODES: tuple[str, ...] = ("auto", "threads", "off")

# Re-exported for callers that import them from here (fit, analyze, prediction).
__all__ = ["BATCH_MODES", "DEFAULT_WORKERS", "EXECUTORS", "BatchMode", "BatchedSimulator", "Evaluator", "ExecutorKind", "ScenarioTrace", "SimJob", "Traces",
           "check_executor", "load_traces", "needed_scenarios", "scenario_logs", "simulate", "simulate_batch", "simulate_on", "simulate_twin"]


@dataclass(frozen=True, eq=False)
class ScenarioTrace:
    """One scenario's logged channels and how it ended.

    Attributes:
        id: Scenario id.
        status: ``completed``, ``failed`` (a failure threshold stopped it) or ``unstable``.
        duration_s: Planned scenario duration.
        series: Channel name -> time stamps (s since the scenario started) and values.
        failure: What stopped a failed or unstable scenario, as a run manifest records it (None otherwise).
    """

    id: str
    status: str
    duration_s: float
    series: Mapping[str, Series] = field(default_factory=dict)
    failure: Mapping[str, Any] | None = None

    @property
    def end_time_s(self) -> float:
        """Time of the last logged sample (0 if nothing was logged)."""
        ends = [float(s.t[-1]) for s in self.series.values() if s.t.size]
        return max(ends) if ends else 0.0


Traces = dict[str, ScenarioTrace]


@dataclass(frozen=True)
class SimJob:
    """Simulate ``scenarios`` of ``suite`` on ``twin`` for ``robot`` with ``knobs`` applied from nominal.

    Scenarios that continue from a previous one are simulated with their predecessors, which are not
    returned unless asked for.
    """

    robot: str
    twin: str
    suite: str
    scenarios: tuple[str, ...] | None = None
    knobs: tuple[tuple[str, float], ...] = ()
    seed: int = 0
    #: Ensemble member shifts of initial conditions at fresh starts (`dualtwin.suite.ensemble`); () for none.
    offsets: tuple[tuple[str, float], ...] = ()

    def with_knobs(self, values: Mapping[str, float]) -> SimJob:
        return SimJob(self.robot, self.twin, self.suite, self.scenarios, tuple(sorted(values.items())), self.seed,
                      self.offsets)

    def with_offsets(self, offsets: Mapping[str, float]) -> SimJob:
        return SimJob(self.robot, self.twin, self.suite, self.scenarios, self.knobs, self.seed,
                      tuple(sorted(offsets.items())))


class _Session:
    """A worker's binding, suite and twin, built once."""

    def __init__(self, robot: str, twin: str, suite: str) -> None:
        self.robot = load_binding(Path(robot))
        self.suite_path = Path(suite)
        self.suite = load_suite(self.suite_path)
        check_against_binding(self.suite, self.suite_path, self.robot)
        self.ids = self.suite.scenario_ids()
        self.twin = make_twin(twin, self.robot, self.suite.global_settings.control_period_s)
        self.io = RobotIO(self.robot, self.twin)
        self.channel_names = list(self.io.channel_info())


_SESSIONS: dict[tuple[str, str, str], _Session] = {}


def _session(job: SimJob) -> _Session:
    key = (job.robot, job.twin, job.suite)
    if key not in _SESSIONS:
        _SESSIONS[key] = _Session(*key)
    return _SESSIONS[key]


def needed_scenarios(suite: Suite, wanted: Iterable[str]) -> list[int]:
    """Indices to simulate for ``wanted`` ids: each one plus the chain of scenarios it continues from."""
    ids = suite.scenario_ids()
    wanted_set = set(wanted)
    unknown = sorted(wanted_set - set(ids))
    if unknown:
        raise DualtwinError(f"unknown scenario ids {unknown}; the suite has {ids}")
    need: set[int] = set()
    for i, sid in enumerate(ids):
        if sid in wanted_set:
            j = i
            need.add(j)
            while j > 0 and suite.scenarios[j].reset == "continue":
                j -= 1
                need.add(j)
    return sorted(need)


def simulate_on(io: RobotIO, suite: Suite, wanted: Sequence[str] | None, seed: int,
                offsets: Mapping[str, float] | None = None) -> Traces:
    """Run the wanted scenarios (all if None) on ``io.twin`` in memory, resetting like `SuiteRun`.

    ``offsets`` shift initial conditions at fresh starts, as an ensemble member does.
    """
    traces: Traces = drive(suite_periods(io, suite, wanted, seed, offsets), io.twin.step)
    return traces


def suite_periods(io: RobotIO, suite: Suite, wanted: Sequence[str] | None, seed: int,
                  offsets: Mapping[str, float] | None = None) -> Generator[None, Samples, Traces]:
    """`simulate_on` as a generator that yields where the twin's physics steps a period (see
    `dualtwin.suite.runner.scenario_periods`)."""
    ids = suite.scenario_ids()
    indices = needed_scenarios(suite, wanted if wanted is not None else ids)
    keep = set(wanted if wanted is not None else ids)
    thresholds = suite.global_settings.thresholds
    names = [*io.ground_truth_names, *(f"onboard/{n}" for n in io.onboard_names)]
    out: Traces = {}
    need_fresh = True
    previous = -2
    for index in indices:
        scenario = suite.scenarios[index]
        # A skipped predecessor means there is nothing to continue from.
        fresh = need_fresh or scenario.reset == "fresh" or previous != index - 1
        scenario_seed = scenario.seed if scenario.seed is not None else seed
        result, onboard, truth = yield from scenario_periods(io, scenario, scenario_seed, thresholds, fresh,
                                                             offsets if fresh else None)
        need_fresh = result.status == "unstable"
        previous = index
        if ids[index] not in keep:
            continue
        gt = np.asarray(truth, dtype=np.float64).reshape(len(truth), 1 + len(io.ground_truth_names))
        ob = np.asarray(onboard, dtype=np.float64).reshape(len(onboard), 1 + len(io.onboard_names))
        columns = [gt[:, i] for i in range(1, gt.shape[1])] + [ob[:, i] for i in range(1, ob.shape[1])]
        series = {name: Series(gt[:, 0].copy(), col.copy()) for name, col in zip(names, columns, strict=True)}
        out[ids[index]] = ScenarioTrace(ids[index], result.status, float(scenario.duration_s), series, result.failure)
    return out


def simulate_with_nuisance(io: RobotIO, suite: Suite, knobs: Mapping[str, float], wanted: Sequence[str] | None,
                           seed: int, offsets: Mapping[str, float] | None = None) -> Traces:
    """`simulate_on` with physics knobs set on the twin and nuisance knobs applied to the suite and time axes.

    Nuisance initial conditions replace the scenario's; a nuisance time offset moves the scenario's time
    stamps onto the reference's clock (see :mod:`dualtwin.align.nuisance`).
    """
    traces: Traces = drive(job_periods(io, suite, knobs, wanted, seed, offsets), io.twin.step)
    return traces


def job_periods(io: RobotIO, suite: Suite, knobs: Mapping[str, float], wanted: Sequence[str] | None,
                seed: int, offsets: Mapping[str, float] | None = None) -> Generator[None, Samples, Traces]:
    """`simulate_with_nuisance` as a generator that yields where the twin's physics steps a period: the
    batched path (`BatchedSimulator`) runs many of them, one per candidate twin, in lockstep."""
    physics, extra = nuisance.split(knobs)
    io.twin.set_knobs(physics)
    if not extra:
        return (yield from suite_periods(io, suite, wanted, seed, offsets))
    traces = yield from suite_periods(io, nuisance.apply_to_suite(suite, extra), wanted, seed, offsets)
    for sid, offset in nuisance.time_offsets(extra, suite.scenario_ids()).items():
        if sid in traces:
            trace = traces[sid]
            traces[sid] = ScenarioTrace(trace.id, trace.status, trace.duration_s,
                                        nuisance.shift_series(trace.series, offset), trace.failure)
    return traces


_BATCHES: dict[tuple[str, str, str], BatchedSimulator] = {}


def simulate_batch(jobs: Sequence[SimJob]) -> list[Traces]:
    """Run jobs of one robot, twin and suite as a one-thread batch in this process (the worker entry point of
    :class:`Evaluator`'s pooled batch; the batch is built once per worker)."""
    first = jobs[0]
    key = (first.robot, first.twin, first.suite)
    simulator = _BATCHES.get(key)
    if simulator is None:
        simulator = _BATCHES[key] = BatchedSimulator(*key, nthread=1)
    return simulator.map(jobs)


def simulate(job: SimJob) -> Traces:
    """Run one job in this process (the worker entry point)."""
    session = _session(job)
    return simulate_with_nuisance(session.io, session.suite, dict(job.knobs), job.scenarios, job.seed,
                                  dict(job.offsets) or None)


def simulate_twin(robot: RobotBinding, twin: Twin, suite_path: Path, knobs: Mapping[str, float],
                  scenarios: Sequence[str] | None = None, seed: int = 0) -> Traces:
    """Run scenarios on an existing twin instance with ``knobs`` applied (used in-process, e.g. by tests).

    ``knobs`` may hold nuisance knobs (``scenario.<id>.<key>``) besides the twin's own.
    """
    suite = load_suite(Path(suite_path))
    check_against_binding(suite, Path(suite_path), robot)
    return simulate_with_nuisance(RobotIO(robot, twin), suite, knobs, scenarios, seed)


def load_traces(run_dir: Path, scenarios: Sequence[str] | None = None) -> Traces:
    """A recorded run directory as traces; durations come from the run's copy of the suite if present."""
    run = load_run(Path(run_dir))
    durations: dict[str, float] = {}
    suite_copy = Path(run_dir) / "config" / "suite.json"
    if suite_copy.is_file():
        suite = load_suite(suite_copy)
        durations = {sid: float(s.duration_s) for sid, s in zip(suite.scenario_ids(), suite.scenarios, strict=True)}
    wanted = [s.id for s in run.scenarios] if scenarios is None else list(scenarios)
    out: Traces = {}
    for sid in wanted:
        series = run.series(sid)
        # Without the suite copy, the last logged sample stands in for the planned duration.
        fallback = max((float(v.t[-1]) for v in series.values() if v.t.size), default=0.0)
        entry = run.scenario(sid)
        failure = dict(entry.failure) if entry.failure is not None else None
        out[sid] = ScenarioTrace(sid, entry.status, durations.get(sid, fallback), series, failure)
    return out


def scenario_logs(trace: ScenarioTrace, ground_truth_names: Sequence[str],
                  onboard_names: Sequence[str]) -> ScenarioLogs | None:
    """The logs a suite run writes for ``trace`` (rows of time and channels in the binding's order), rebuilt
    exactly: every value is a float64 the simulation produced, and ``float`` gives it back as it was logged.
    None when the trace cannot give them (a channel missing, or channels of different lengths)."""
    try:
        truth = [trace.series[n] for n in ground_truth_names]
        onboard = [trace.series[f"onboard/{n}"] for n in onboard_names]
    except KeyError:
        return None
    if not truth and not onboard:
        return None
    t = (truth or onboard)[0].t
    if any(s.t.shape != t.shape or s.y.shape != t.shape or not np.array_equal(s.t, t) for s in truth + onboard):
        return None

    def rows(series: list[Series]) -> list[list[float]]:
        rows_out: list[list[float]] = np.column_stack([t, *(s.y for s in series)]).tolist()
        return rows_out

    failure = dict(trace.failure) if trace.failure is not None else None
    return ScenarioResult("", trace.status, failure, int(t.size)), rows(onboard), rows(truth)


def load_member_traces(run_dir: Path, scenarios: Sequence[str] | None = None) -> dict[str, list[ScenarioTrace]]:
    """Every ensemble member of each scenario (member 0, the main logs, first); {} when the run has none."""
    run = load_run(Path(run_dir))
    main = load_traces(run_dir, scenarios)
    out: dict[str, list[ScenarioTrace]] = {}
    for sid, trace in main.items():
        entry = run.scenario(sid)
        if not entry.members:
            continue
        members = [trace]
        for m, series in zip(entry.members, run.members(sid)[1:], strict=True):
            members.append(ScenarioTrace(sid, m.status, trace.duration_s, series))
        out[sid] = members
    return out


def ensemble_offsets(run_dir: Path) -> list[dict[str, float]]:
    """Each member's initial-condition shifts from an ensemble run's manifest (member 0 first); [] if none."""
    manifest_path = Path(run_dir) / "manifest.json"
    _, manifest = read_run_manifest(manifest_path)  # typed: the offsets are a list of finite shifts
    if manifest.ensemble is None:
        return []
    offsets: list[dict[str, float]] = []
    for k, record in enumerate(manifest.ensemble.offsets or []):
        if record.member != k:
            raise DualtwinError(f"{manifest_path}: ensemble.offsets[{k}]: needs 'member': {k}, not {record.member}")
        offsets.append(dict(record.shift))
    return offsets


class BatchedSimulator:
    """Simulates jobs of one robot, twin and suite as a batch on ``nthread`` threads (0: all CPUs).

    Raises nothing for a twin that cannot be batched: :attr:`reason` says why (None when it can), and the
    caller runs its jobs another way.
    """

    def __init__(self, robot: str, twin: str, suite: str, nthread: int) -> None:
        self.robot = load_binding(Path(robot))
        self.suite = load_suite(Path(suite))
        check_against_binding(self.suite, Path(suite), self.robot)
        self.twin_name = twin
        self.nthread = nthread
        self._period = self.suite.global_settings.control_period_s
        self._ios: list[RobotIO] = []
        self._batch: TwinBatch | None = None
        self._columns: ChannelColumns | None = None
        #: Periods of the last map whose samples were read for many jobs at once / by each job's twin.
        self.read_together = 0
        self.read_alone = 0
        from dualtwin.twins.mujoco_batch import batch_reason  # imports mujoco.batch: only when batching

        #: Why this twin cannot be batched, or None.
        self.reason = batch_reason(self._io(0).twin)

    def _io(self, index: int) -> RobotIO:
        while len(self._ios) <= index:
            self._ios.append(RobotIO(self.robot, make_twin(self.twin_name, self.robot, self._period)))
            self._batch = None  # sized for fewer twins
        return self._ios[index]

    def _twin_batch(self, n: int) -> TwinBatch:
        from dualtwin.twins.mujoco_batch import ChannelColumns, TwinBatch

        self._io(n - 1)
        if self._batch is None:
            self._batch = TwinBatch([io.twin for io in self._ios], self.nthread)  # type: ignore[misc]
            section = self.robot.spec.twins.get("mujoco")
            spec = self.robot.spec
            # Ground truth, then on-board channels (the order of a period's samples, see `_send`).
            self._columns = ChannelColumns.build(self._batch, dict(section.aliases) if section else {},
                                                 [*spec.ground_truth.values(), *spec.onboard.values()])
        return self._batch

    def map(self, jobs: Sequence[SimJob]) -> list[Traces]:
        """Every job's traces, in job order."""
        periods: list[Periods] = [
            job_periods(self._io(i), self.suite, dict(job.knobs), job.scenarios, job.seed, dict(job.offsets) or None)
            for i, job in enumerate(jobs)]
        results: list[Traces | None] = [None] * len(jobs)
        if len(jobs) == 1:  # nothing to batch with: the twin steps itself (the same result)
            return [drive(periods[0], self._ios[0].twin.step)]
        batch = self._twin_batch(len(jobs))
        live: list[int] = []
        for i, job in enumerate(periods):
            try:
                next(job)  # knobs set, first period's commands given
                live.append(i)
            except StopIteration as stop:
                results[i] = stop.value
        columns = self._columns
        # Jobs whose samples are read for all of them at once from the batch's arrays (the same values as each
        # twin's getters); a twin with sensor noise, bias, resolution or delay reads its own.
        together = {i for i in live if columns is not None and getattr(self._ios[i].twin, "plain_sensor_reads", False)}
        truth_width = len(self.robot.spec.ground_truth)
        self.read_together = self.read_alone = 0
        while live:
            unstable = batch.step(live)
            samples: dict[int, list[float]] = {}
            read = [i for i, exc in zip(live, unstable, strict=True) if exc is None and i in together]
            if read and columns is not None:
                samples = dict(zip(read, columns.read(np.asarray(read)).tolist(), strict=True))
            still: list[int] = []
            for i, exc in zip(live, unstable, strict=True):
                try:
                    if exc is not None:
                        periods[i].throw(exc)
                    elif i in samples:
                        row = samples[i]
                        self.read_together += 1
                        periods[i].send((row[truth_width:], row[:truth_width]))
                    else:
                        self.read_alone += 1
                        periods[i].send(None)
                    still.append(i)
                except StopIteration as stop:
                    results[i] = stop.value
            live = still
        return [r for r in results if r is not None]

    def close(self) -> None:
        for io in self._ios:
            io.twin.close()
        self._ios.clear()
        self._batch = None
        self._columns = None


class Evaluator:
    """Runs `SimJob` batches as MuJoCo batches, serially, in a process pool, or on a Ray cluster; counts
    evaluations.

    Jobs for a MuJoCo twin whose physics can be batched (`dualtwin.twins.mujoco_batch.batch_reason`) run as
    ``mujoco.batch`` calls, bit-identical to the other executors:

    * ``batch="auto"`` (the default): split into ``workers`` contiguous chunks, each a one-thread batch in a
      worker of the process pool (in this process with ``kind="serial"``; maps of fewer than ``pool_start``
      jobs a worker while the pool has not started, or of fewer than two once it has, run here as with
      ``threads``). The Python of every period (inputs, bookkeeping, failure checks) runs in parallel too, which a
      thread pool cannot do under the GIL: on the arm's fit (2 idle cores) the in-process batch on 2 threads
      was slower than the pool without batching;
    * ``batch="threads"``: one batch in this process on ``workers`` threads (the physics in parallel, the
      Python serial; less memory and no traces to send back);
    * ``batch="off"``, other twins, and every twin with ``kind="ray"``: one job at a time on the executor.

    :attr:`batched` says whether the last map ran as a batch.

    The process pool uses the ``forkserver`` start method (no fork of a threaded parent) and keeps its
    workers for the evaluator's lifetime, so each worker builds its twin once. As with any non-fork start
    method, a script that aligns in a process pool must guard its entry point with
    ``if __name__ == "__main__":`` because workers import the main module.
    """

    def __init__(self, kind: ExecutorKind = "process", workers: int = DEFAULT_WORKERS,
                 ray_address: str | None = None, batch: BatchMode = "auto", pool_start: int = 12) -> None:
        """``pool_start``: with the pooled batch, the candidates per worker a map needs to start the pool (a
        small fit never pays its start-up; the arm's 25-knob Jacobian starts it); once it runs, two per worker
        use it. Smaller maps run as one batch here on ``workers`` threads."""
        if batch not in BATCH_MODES:
            raise DualtwinError(f"unknown batch mode {batch!r}; use one of {', '.join(BATCH_MODES)}")
        # The generic parallel map lives in `dualtwin.parallel`, shared with suite ensembles.
        self._map = ParallelMap(kind, workers, ray_address, preload=["dualtwin.align.simulate"])
        self.kind = kind
        self.workers = workers
        self.batch: BatchMode = batch if kind != "ray" else "off"
        self.evaluations = 0
        #: Whether the last map ran as a MuJoCo batch, and in how many pieces (one per pool worker that got one).
        self.batched = False
        self.batch_chunks = 0
        self.pool_start = pool_start
        self._simulators: dict[tuple[str, str, str], BatchedSimulator | None] = {}

    def _simulator(self, jobs: Sequence[SimJob]) -> BatchedSimulator | None:
        """This process's batch for ``jobs`` (None when they cannot be batched); with the pooled batch it only
        answers whether they can, and the workers build their own."""
        keys = {(job.robot, job.twin, job.suite) for job in jobs}
        if self.batch == "off" or len(keys) != 1:
            return None
        key = keys.pop()
        if key not in self._simulators:
            simulator: BatchedSimulator | None = None
            if key[1] == "mujoco":
                simulator = BatchedSimulator(*key, nthread=self.workers if self._threaded else 1)
                if simulator.reason is not None:
                    simulator.close()
                    simulator = None
            self._simulators[key] = simulator
        return self._simulators[key]

    @property
    def _threaded(self) -> bool:
        return self.batch in ("threads", "auto") and self.kind == "process"

    @property
    def _pooled(self) -> bool:
        return self.batch == "auto" and self.kind == "process" and self.workers > 1

    def map(self, jobs: Sequence[SimJob]) -> list[Traces]:
        """Simulate every job; results come back in job order."""
        jobs = list(jobs)
        self.evaluations += len(jobs)
        simulator = self._simulator(jobs) if jobs else None
        self.batched = simulator is not None
        self.batch_chunks = int(self.batched)
        if simulator is None:
            return self._map.map(simulate, jobs)
        share = 2 if self._map.started else self.pool_start
        if not self._pooled or len(jobs) < share * self.workers:
            # A handful of candidates (a small fit's populations, a line search) stay here, on the threads:
            # starting the pool costs seconds (a CartPole fit of budget 12 took 14 s when a map of 16 started
            # it, against 10 s here), and a worker's share must pay for sending its traces back.
            return simulator.map(jobs)
        # Contiguous chunks, as even as they come, one per worker: each is a one-thread batch there.
        self.batch_chunks = k = self.workers
        chunks = [jobs[i * len(jobs) // k:(i + 1) * len(jobs) // k] for i in range(k)]
        return [traces for chunk in self._map.map(simulate_batch, chunks) for traces in chunk]

    def close(self) -> None:
        self._map.close()
        for simulator in self._simulators.values():
            if simulator is not None:
                simulator.close()
        self._simulators.clear()

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
