"""Lockstep twins: both twins get the same commands every control period; their state difference is logged.

A *primary* twin (usually Webots, the stand-in for the real robot) and a *secondary* twin (usually MuJoCo,
the model) run the same episodes side by side, period by period: suite scenarios (the paper's inputs), or
episodes of a policy that acts on the *primary's* observations and sends the same action to both. After
every period the runner reads both mechanical states, logs the per-channel difference (secondary minus
primary) and the normalised state error (:mod:`dualtwin.divergence.channels`), and applies a re-sync policy:

* ``never``: open loop; the error grows with the chaos of the task and the model mismatch;
* ``every:N``: every N periods the secondary is put into the primary's state (``set_state``), so errors are
  measured over horizons of at most N periods (``every:1`` gives the one-period prediction error);
* ``threshold:X``: the secondary is re-synced whenever the normalised error exceeds X.

A re-sync into a state the secondary refuses (:class:`~dualtwin.twins.base.SyncError`: penetration,
non-finite values, a violent response) ends the episode, which is recorded as ``skipped`` with the reason.

The primary never depends on the secondary. So when an episode's commands are known in advance (a suite),
it runs one twin at a time, the primary's whole episode and then the secondary's against the primary's
recorded states, with the results of stepping them period by period (``interleave=True``) but without
switching simulators every period. Policy episodes interleave: the action comes from the primary each period.

Output folder::

    OUT/manifest.json                 settings, versions, input hashes, seed, per-episode summary, knob updates
    OUT/episodes/<id>/state_diff.tsv  time_s, error, resynced, horizon, one column per state channel
    OUT/primary/, OUT/secondary/      suite-run folders of each twin (``dualtwin compare`` reads them)
    OUT/trajectories.npz              the primary's states and commands (an alignment/prediction reference)
    OUT/monitor_events.jsonl          the online monitor's event log, when a monitor is attached
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from dualtwin.artifacts import package_versions, sha256_file, write_json, write_text
from dualtwin.divergence.channels import DiffLayout, channel_scales
from dualtwin.divergence.trajectories import (
    Command,
    CommandTap,
    Trajectory,
    TrajectoryRecorder,
    apply_commands,
    plan_scenarios,
    save_trajectories,
    start_scenario,
)
from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.loader import load_suite
from dualtwin.suite.runner import check_against_binding, format_rows
from dualtwin.sync.monitor import Monitor
from dualtwin.twins import make_twin
from dualtwin.twins.base import MechanicalState, StateLayout, SyncError, Twin
from dualtwin.twins.io import RobotIO

LOCKSTEP_SCHEMA = "dualtwin.lockstep/1"
DEFAULT_POLICY_EPISODES = 5
DEFAULT_POLICY_STEPS = 300


@dataclass(frozen=True)
class ResyncPolicy:
    """When the secondary is put back into the primary's state (see the module docstring)."""

    kind: Literal["never", "every", "threshold"] = "never"
    every: int = 0
    threshold: float = 0.0

    @staticmethod
    def parse(text: str | ResyncPolicy) -> ResyncPolicy:
        """``never``, ``every:N`` (N >= 1) or ``threshold:X`` (X > 0)."""
        if isinstance(text, ResyncPolicy):
            return text
        kind, _, arg = str(text).strip().partition(":")
        try:
            if kind == "never" and not arg:
                return ResyncPolicy()
            if kind == "every" and int(arg) >= 1:
                return ResyncPolicy("every", every=int(arg))
            if kind == "threshold" and float(arg) > 0 and math.isfinite(float(arg)):
                return ResyncPolicy("threshold", threshold=float(arg))
        except ValueError:
            pass
        raise DualtwinError(f"resync {text!r}: use 'never', 'every:N' (N >= 1) or 'threshold:X' (X > 0)")

    def due(self, periods: int, error: float) -> bool:
        if self.kind == "every":
            return periods % self.every == 0
        if self.kind == "threshold":
            return error > self.threshold
        return False

    def __str__(self) -> str:
        if self.kind == "every":
            return f"every:{self.every}"
        if self.kind == "threshold":
            return f"threshold:{self.threshold:g}"
        return "never"


@dataclass
class EpisodeSummary:
    """One lockstep episode: how it ended and how far the twins drifted apart."""

    id: str
    status: str  # completed | failed | unstable | skipped
    steps: int
    resyncs: int
    mean_error: float
    max_error: float
    final_error: float
    error_by_horizon: dict[int, float] = field(default_factory=dict)
    statuses: dict[str, str] = field(default_factory=dict)
    failure: dict[str, Any] | None = None
    rewards: dict[str, float] | None = None
    knobs: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "status": self.status, "steps": self.steps, "resyncs": self.resyncs,
                "mean_error": _finite(self.mean_error), "max_error": _finite(self.max_error),
                "final_error": _finite(self.final_error),
                "error_by_horizon": {str(h): _finite(v) for h, v in self.error_by_horizon.items()},
                "statuses": self.statuses, "failure": self.failure, "rewards": self.rewards,
                "secondary_knobs": self.knobs, "state_diff": f"episodes/{self.id}/state_diff.tsv"}


@dataclass
class LockstepResult:
    """What :func:`run_lockstep` did and where it wrote it."""

    out_dir: Path
    manifest: dict[str, Any]
    episodes: list[EpisodeSummary]
    knob_updates: list[dict[str, Any]] = field(default_factory=list)

    def error_by_horizon(self) -> dict[int, float]:
        """Mean normalised error at each horizon (periods since the last sync), over all episodes' rows."""
        sums: dict[int, list[float]] = {}
        for ep in self.episodes:
            for h, v in ep.error_by_horizon.items():
                sums.setdefault(h, []).append(v)
        return {h: float(np.mean(v)) for h, v in sorted(sums.items())}


#: Control periods both twins settle from reset, without commands, before their resting contacts are compared.
REST_PERIODS = 16


@dataclass
class RestCalibration:
    """How a state is carried from the primary's contact compliance to the secondary's (see `calibrate_rest`).

    ``depth_ratio``: the secondary's resting contact depth over the primary's, applied by a secondary that can
    scale contact depths itself (``reseat_depth_ratio``, the MuJoCo twin); ``height_offset``: otherwise, per
    free body, the secondary's resting height minus the primary's, added to the written height.
    """

    depth_ratio: float | None = None
    height_offset: dict[str, float] = field(default_factory=dict)

    def apply(self, state: MechanicalState) -> MechanicalState:
        if not self.height_offset:
            return state
        moved = state.copy()
        for name, dz in self.height_offset.items():
            if name in moved.bodies:
                moved.bodies[name].position[2] += dz
        return moved

    def to_dict(self) -> dict[str, Any]:
        return {"periods": REST_PERIODS, "depth_ratio": self.depth_ratio, "height_offset_m": self.height_offset}


def calibrate_rest(primary: Twin, secondary: Twin, seed: int = 0) -> RestCalibration:
    """Measure how the two twins' resting contacts differ, so that re-seating at rest is exact.

    Why: at rest nothing in the transferred state is missing, but the two engines rest at different contact
    depths under the same weight (ODE's ERP/CFM spring against MuJoCo's solref/solimp). Writing the primary's
    depth into the secondary leaves it off its own equilibrium: the contacts push it out and it bounces
    within the period, so re-seating every period at rest was worse than free-running (where each twin sits at
    its own depth and only a constant offset remains). Other candidates were checked on the bundled CartPole
    and changed nothing: MuJoCo's ``qacc_warmstart`` (Newton converges from either start), and the motors'
    integrator, saturation and slew state (zero at rest and without an acceleration limit).

    Both twins are reset, settle for `REST_PERIODS` without commands, and the secondary's resting depth is
    compared with the depth it has in the primary's resting state. Both twins are left reset afterwards.
    The calibration uses the knobs set when it runs: a monitor's knob update that changes the secondary's
    contact compliance mid-run is not re-calibrated (suite scenarios may continue from the previous one's
    state, so the twins cannot be reset between episodes to measure again).
    """
    for twin in (primary, secondary):
        twin.reset(seed)
        for _ in range(REST_PERIODS):
            twin.step()
    rest_a, rest_b = primary.get_state(), secondary.get_state()
    calibration = RestCalibration()
    depth = getattr(secondary, "contact_depth", None)
    if depth is not None and hasattr(secondary, "reseat_depth_ratio"):
        own = float(depth())
        secondary.reseat_depth_ratio = 1.0
        try:
            secondary.set_state(rest_a)
        except SyncError:
            written = 0.0  # refused here: the episodes' re-syncs will be refused and skipped the same way
        else:
            written = float(depth())
        # Within a millionth the engines rest alike (the same twin on both sides differs by the state's
        # float round trip, ~1e-9): then the state is written exactly as read.
        if own > 0 and written > 0 and abs(own / written - 1.0) > 1e-6:
            calibration.depth_ratio = own / written
    else:
        calibration.height_offset = {
            name: float(body.position[2] - rest_a.bodies[name].position[2])
            for name, body in rest_b.bodies.items() if name in rest_a.bodies}
    for twin in (primary, secondary):
        twin.reset(seed)
    return calibration


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


class _Side:
    """One twin of the pair with its tap, I/O and logs for the current episode."""

    def __init__(self, label: str, twin: Twin, robot: RobotBinding) -> None:
        self.label = label
        self.tap = CommandTap(twin)
        # Readers bind to the twin itself (sampled every period); commands and resets go through the tap.
        self.io = RobotIO(robot, twin)
        self.io.twin = self.tap
        self.onboard: list[list[float]] = []
        self.truth: list[list[float]] = []
        self.status = "completed"
        self.failure: dict[str, Any] | None = None
        self.reward = 0.0
        self.thresholds: list[tuple[str, str, int, float]] = []  # key, channel, column in a truth row, limit

    def watch(self, suite: Any, binding: RobotBinding) -> None:
        """Check the suite's failure thresholds (if any) on this side, as the suite runner does."""
        if suite is not None:
            self.thresholds = [(key, channel, 1 + self.io.ground_truth_index(channel), limit)
                               for key, limit in suite.global_settings.thresholds.items()
                               for channel in (binding.spec.failures[key].channel,)]

    def begin(self) -> None:
        self.onboard, self.truth = [], []
        self.status, self.failure, self.reward = "completed", None, 0.0

    def step(self) -> bool:
        try:
            self.tap.step()
        except SimulationUnstable as exc:
            self.status, self.failure = "unstable", {"time_s": round(self.tap.time, 9), "message": str(exc)}
            return False
        return True

    def failed(self, t: float) -> bool:
        """Whether the last sample crosses a failure threshold (which ends the episode)."""
        if not self.truth:
            return False
        row = self.truth[-1]
        for key, channel, column, limit in self.thresholds:
            if abs(row[column]) > limit:
                self.status = "failed"
                self.failure = {"key": key, "channel": channel, "time_s": t, "threshold": limit}
                return True
        return False

    def sample(self, t: float) -> bool:
        onboard = [t, *self.io.sample_onboard()]
        truth = [t, *self.io.sample_ground_truth()]
        # One sum instead of a test per value (read every period): NaN and infinities propagate through it.
        if not math.isfinite(sum(onboard) + sum(truth)):
            self.status, self.failure = "unstable", {"time_s": t, "message": "non-finite channel value"}
            return False
        self.onboard.append(onboard)
        self.truth.append(truth)
        return True


class _Episode:
    """How one episode starts and what is sent each period: a suite scenario or a policy's actions."""

    def __init__(self, id: str, steps: int, begin: Callable[[], None],
                 send: Callable[[int], None], after: Callable[[], bool] | None = None,
                 rewards: Callable[[], dict[str, float]] | None = None,
                 send_to: Callable[[int, _Side], None] | None = None) -> None:
        self.id, self.steps, self.begin, self.send = id, steps, begin, send
        self.after = after  # returns True when the episode is over (policy termination)
        self.rewards = rewards
        self.send_to = send_to  # the same commands for one side: the episode can run one twin at a time


class _Comparison:
    """The per-period work of a lockstep episode once both twins stepped a period: log the two state vectors,
    re-sync the secondary when the policy says so, feed the monitor. Calling it returns True to stop."""

    def __init__(self, a: _Side, b: _Side, layout: DiffLayout, scale_map: Mapping[str, float],
                 resync: ResyncPolicy, recorder: TrajectoryRecorder, monitor: Monitor | None, clock: float,
                 period: float, rest: RestCalibration | None = None) -> None:
        self.a, self.b, self.layout, self.scale_map, self.resync = a, b, layout, scale_map, resync
        self.rest = rest
        self.recorder, self.monitor, self.clock, self.period = recorder, monitor, clock, period
        self.channels = layout.channels
        self.scale = np.array([scale_map[c] for c in self.channels])
        # Differences are needed as they happen only to decide on a threshold re-sync or to feed a monitor;
        # otherwise they are computed for the whole episode at once (vectorised), which keeps lockstep cheap.
        self.online = resync.kind == "threshold" or monitor is not None
        self.marks: list[tuple[float, float, float]] = []  # time, resynced, horizon
        self.rows_a: list[np.ndarray] = []
        self.rows_b: list[np.ndarray] = []
        self.resyncs, self.horizon = 0, 0
        self.skipped: dict[str, Any] | None = None

    def __call__(self, k: int, t: float, names_a: StateLayout, full_a: np.ndarray, truth_a: Sequence[float],
                 active_a: dict[str, Command]) -> bool:
        # State vectors only: a state object is built when a re-sync or the monitor needs one.
        va, vb = self.layout.vectors(full_a, self.b.tap.state_vector()[1])
        self.rows_a.append(va)
        self.rows_b.append(vb)
        error = math.nan
        if self.online:
            diff = self.layout.differences(va, vb)
            error = float(self.layout.errors(diff, self.scale_map)[0])
        self.horizon += 1
        self.recorder.after_period(names_a, full_a, truth_a, active_a)
        resynced = self.resync.due(k + 1, error)
        monitor = self.monitor
        state_a = names_a.state(full_a, t, self.a.tap.name) if resynced or monitor is not None else None
        if resynced and state_a is not None:
            try:
                self.b.tap.set_state(self.rest.apply(state_a) if self.rest is not None else state_a)
            except SyncError as exc:
                self.skipped = {"time_s": t, "reason": exc.reason, "message": str(exc)}
                resynced = False
        self.marks.append((t, 1.0 if resynced else 0.0, float(self.horizon)))
        if monitor is not None:
            finite = np.isfinite(self.scale)
            scaled = dict(zip((c for c, keep in zip(self.channels, finite, strict=True) if keep),
                              (diff[0][finite] / self.scale[finite]).tolist(), strict=True))
            monitor.observe(self.clock + t, error, scaled, state=state_a, commands=active_a, period=self.period)
        if self.skipped is not None:
            return True
        if resynced:
            self.resyncs += 1
            self.horizon = 0
        return False


def _blocked(episode: _Episode, a: _Side, b: _Side, period: float,
             compare: Callable[[int, float, StateLayout, np.ndarray, Sequence[float], dict[str, Command]], bool]
             ) -> None:
    """Run an episode whose commands are known in advance one twin at a time: the primary's whole episode,
    then the secondary's against it. The primary never depends on the secondary, so this gives the
    interleaved loop's results exactly, without alternating between two simulators every period (which
    costs each of them its caches). Where the secondary ends the episode first, the primary's logs are cut
    back to that period and its status is what it was then."""
    assert episode.send_to is not None
    primary: list[tuple[StateLayout, np.ndarray, dict[str, Command]]] = []
    a_failed_at_end = False
    for k in range(episode.steps):
        episode.send_to(k, a)
        t = round((k + 1) * period, 9)
        if not (a.step() and a.sample(t)):
            break
        primary.append((*a.tap.state_vector(), dict(a.tap.active)))
        if a.failed(t):
            a_failed_at_end = True
            break
    status, failure = a.status, a.failure
    kept = len(primary)  # the primary's samples the episode keeps
    own_end = status == "completed"  # the episode ends where the primary's own run ended
    for k in range(len(primary) + (status == "unstable")):
        episode.send_to(k, b)
        t = round((k + 1) * period, 9)
        ok_b = b.step() and b.sample(t)
        if k == len(primary):  # the primary went unstable here: both stepped and sampled, nothing compared
            own_end = True
            break
        if not ok_b:
            kept = k + 1
            break
        names_a, full_a, active_a = primary[k]
        if compare(k, t, names_a, full_a, a.truth[k][1:], active_a):
            kept = k + 1  # skipped: no threshold was checked in this period
            break
        if k == len(primary) - 1 and a_failed_at_end:
            own_end = True
            break
        if b.failed(t):
            kept = k + 1
            break
    if not own_end or kept < len(primary):
        status, failure = "completed", None
    del a.onboard[kept:], a.truth[kept:]
    a.status, a.failure = status, failure


def run_lockstep(
    primary: str | Twin,
    secondary: str | Twin,
    robot: str | RobotBinding,
    *,
    out_dir: Path,
    suite: Path | None = None,
    policy: Path | str | None = None,
    resync: str | ResyncPolicy = "never",
    seed: int = 0,
    episodes: int | None = None,
    episode_steps: int | None = None,
    scales: Mapping[str, float] | None = None,
    primary_knobs: Mapping[str, float] | None = None,
    secondary_knobs: Mapping[str, float] | None = None,
    monitor: Monitor | None = None,
    on_episode: Callable[[EpisodeSummary], None] | None = None,
    interleave: bool = False,
) -> LockstepResult:
    """Run two twins in lockstep over a suite's scenarios or a policy's episodes (see the module docstring).

    Args:
        primary: Twin name (``webots``) or instance whose state is the reference.
        secondary: Twin name (``mujoco``) or instance that follows (and is re-synced).
        robot: Robot name or binding.
        out_dir: Output folder (must be empty).
        suite: Suite file; its scenarios are the episodes.
        policy: Exported ONNX policy folder or training run; it acts on the primary's observations.
        resync: ``never``, ``every:N`` or ``threshold:X``.
        seed: Scenario seed (suite) or episode seed base (policy).
        episodes: Policy episodes (default 5); with a suite, only the first ``episodes`` scenarios.
        episode_steps: Policy episode length in control periods (default: the policy's time limit, else 300).
        scales: Channel scale overrides (fnmatch patterns) for the normalised error.
        primary_knobs: Knob values of the primary twin.
        secondary_knobs: Knob values of the secondary twin (a monitor's updates are applied on top of them).
        monitor: Optional online :class:`~dualtwin.sync.monitor.Monitor`; its knob updates are applied to the
            secondary at episode boundaries only.
        on_episode: Called with each episode's summary.
        interleave: Step the two twins period by period even when the commands are known in advance (a
            suite). By default such episodes run the primary first and then the secondary against it, which
            gives the same results faster.

    Raises:
        DualtwinError: Bad input (neither or both of suite/policy, unknown names, non-empty output folder).
    """
    if (suite is None) == (policy is None):
        raise DualtwinError("give exactly one of a suite (scenarios) or a policy (episodes)")
    policy_obj_resync = ResyncPolicy.parse(resync)
    binding = resolve_robot(robot) if isinstance(robot, str) else robot
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()):
        raise DualtwinError(f"{out}: output folder is not empty; choose another folder")

    inputs: dict[str, Any] = {"binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)}}
    suite_obj = None
    lockstep_policy = None
    if suite is not None:
        suite_path = Path(suite)
        suite_obj = load_suite(suite_path)
        check_against_binding(suite_obj, suite_path, binding)
        period = suite_obj.global_settings.control_period_s
        inputs["suite"] = {"path": str(suite_path), "sha256": sha256_file(suite_path)}
    else:
        from dualtwin.sync.policy import load_policy

        lockstep_policy = load_policy(policy or "")
        period = float(lockstep_policy.task_arguments().get("control_period", 0.032))
        inputs["policy"] = {"path": str(lockstep_policy.path), "kind": lockstep_policy.kind,
                            "env_id": lockstep_policy.env_id, "sha256": lockstep_policy.digest()}

    owned: list[Twin] = []
    twin_a = make_twin(primary, binding, period) if isinstance(primary, str) else primary
    if isinstance(primary, str):
        owned.append(twin_a)
    twin_b = make_twin(secondary, binding, period) if isinstance(secondary, str) else secondary
    if isinstance(secondary, str):
        owned.append(twin_b)
    depth_ratio = getattr(twin_b, "reseat_depth_ratio", None)
    try:
        for twin in (twin_a, twin_b):
            model = binding.model_path(twin.name) if twin.name in binding.spec.twins else None
            if model is not None:
                inputs[f"model_{twin.name}"] = {"path": str(model), "sha256": sha256_file(model)}
        return _run(twin_a, twin_b, binding, out, suite_obj, lockstep_policy, policy_obj_resync, seed, episodes,
                    episode_steps, scales, dict(primary_knobs or {}), dict(secondary_knobs or {}), monitor,
                    on_episode, inputs, period, interleave)
    finally:
        if depth_ratio is not None:
            twin_b.reseat_depth_ratio = depth_ratio  # type: ignore[attr-defined]
        for twin in owned:
            twin.close()


def _run(twin_a: Twin, twin_b: Twin, binding: RobotBinding, out: Path, suite: Any, lockstep_policy: Any,
         resync: ResyncPolicy, seed: int, n_episodes: int | None, episode_steps: int | None,
         scales: Mapping[str, float] | None, knobs_a: dict[str, float], knobs_b: dict[str, float],
         monitor: Monitor | None, on_episode: Callable[[EpisodeSummary], None] | None,
         inputs: dict[str, Any], period: float, interleave: bool = False) -> LockstepResult:
    a, b = _Side("primary", twin_a, binding), _Side("secondary", twin_b, binding)
    a.watch(suite, binding)
    b.watch(suite, binding)
    a.tap.set_knobs(knobs_a)
    b.tap.set_knobs(knobs_b)
    rest = calibrate_rest(twin_a, twin_b, seed) if resync.kind != "never" else None
    if rest is not None and rest.depth_ratio is not None:
        twin_b.reseat_depth_ratio = rest.depth_ratio  # type: ignore[attr-defined]  # run_lockstep restores it
    plan = _episodes(a, b, binding, suite, lockstep_policy, seed, n_episodes, episode_steps, period)
    layout = DiffLayout(a.tap.get_state(), b.tap.get_state())
    channels = layout.channels
    scale_map = channel_scales(channels, scales)
    if monitor is not None:
        monitor.attach(out / "monitor_events.jsonl", scale_map)

    summaries: list[EpisodeSummary] = []
    updates: list[dict[str, Any]] = []
    trajectories: list[Trajectory] = []
    records: dict[str, list[dict[str, Any]]] = {"primary": [], "secondary": []}
    clock = 0.0  # simulated seconds over all episodes, for the monitor's event log
    writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="lockstep-writer")
    writes: list[Future[None]] = []
    for episode in plan:
        a.begin()
        b.begin()
        episode.begin()
        recorder = TrajectoryRecorder(episode.id, a.tap, a.io.ground_truth_names)
        if monitor is not None:
            monitor.episode_start(episode.id, clock)
        compare = _Comparison(a, b, layout, scale_map, resync, recorder, monitor, clock, period, rest)
        if episode.send_to is None or interleave:
            # Interleaved: the primary's next commands may depend on both twins (a policy's episode end).
            for k in range(episode.steps):
                episode.send(k)
                ok_a, ok_b = a.step(), b.step()
                t = round((k + 1) * period, 9)
                ok_a = ok_a and a.sample(t)
                ok_b = ok_b and b.sample(t)
                if not (ok_a and ok_b):
                    break
                if compare(k, t, *a.tap.state_vector(), a.truth[-1][1:], dict(a.tap.active)):
                    break
                if episode.after is not None and episode.after():
                    break
                if a.failed(t) or b.failed(t):
                    break
        else:
            _blocked(episode, a, b, period, compare)
        marks, resyncs, skipped = compare.marks, compare.resyncs, compare.skipped
        if compare.rows_a:
            diffs = layout.differences(np.array(compare.rows_a), np.array(compare.rows_b))
            errors = layout.errors(diffs, scale_map)
        else:
            diffs, errors = np.zeros((0, len(channels))), np.zeros(0)
        times, resynced, horizons = np.array(marks, dtype=float).reshape(-1, 3).T
        rows = np.column_stack([times, errors, resynced, horizons, diffs]).tolist()
        clock += len(rows) * period
        trajectories.append(recorder.finish(a.status))
        summary = _summarize(episode, errors, horizons, resyncs, a, b, skipped, knobs_b)
        # Logs are formatted and written (with fsync) by a background thread while the next episode runs.
        writes.append(writer.submit(_write_rows, out / "episodes" / episode.id / "state_diff.tsv",
                                    ["error", "resynced", "horizon", *channels], rows))
        if skipped is None:
            for side in (a, b):
                records[side.label].append(_side_logs(out, side, episode.id, len(summaries), writer, writes))
        summaries.append(summary)
        if monitor is not None:
            update = monitor.episode_end(episode.id, clock)
            if update is not None:
                # Knob updates land between episodes only: never change physics under a running episode.
                knobs_b = {**knobs_b, **update["knobs"]}
                b.tap.set_knobs(knobs_b)
                updates.append({**update, "applied_before_episode": len(summaries)})
        if on_episode is not None:
            on_episode(summary)

    writer.shutdown(wait=True)
    for write in writes:
        write.result()  # a failed write fails the run, before any manifest names the file
    versions = package_versions()
    save_trajectories(out / "trajectories.npz", trajectories,
                      {"twin": a.tap.name, "robot": binding.name, "knobs": knobs_a, "seed": seed})
    name = getattr(suite, "suite_name", None) or f"policy:{getattr(lockstep_policy, 'path', '')}"
    for side, twin, knobs in ((a, twin_a, knobs_a), (b, twin_b, knobs_b)):
        write_json(out / side.label / "manifest.json", {
            "manifest_version": 1, "suite_name": name, "twin": twin.name, "robot": binding.name, "seed": seed,
            "control_period_s": period, "inputs": inputs, "versions": versions,
            "channels": side.io.channel_info(), "tolerances": {}, "scenarios": records[side.label],
            "knobs": knobs, "lockstep": {"role": side.label, "resync": str(resync)}})
    manifest = {
        "schema": LOCKSTEP_SCHEMA, "primary": twin_a.name, "secondary": twin_b.name, "robot": binding.name,
        "mode": "suite" if suite is not None else "policy", "suite_name": name, "resync": str(resync),
        "seed": seed, "control_period_s": period, "inputs": inputs, "versions": versions,
        "rest_calibration": rest.to_dict() if rest is not None else None,
        "knobs": {"primary": knobs_a, "secondary_initial": dict(summaries[0].knobs) if summaries else knobs_b},
        "channels": {c: {"scale": _finite(scale_map[c])} for c in channels},
        "episodes": [s.to_dict() for s in summaries],
        "error_by_horizon": {}, "knob_updates": updates,
        "files": {"primary": "primary", "secondary": "secondary", "trajectories": "trajectories.npz",
                  "monitor_events": "monitor_events.jsonl" if monitor is not None else None},
    }
    result = LockstepResult(out, manifest, summaries, updates)
    manifest["error_by_horizon"] = {str(h): v for h, v in result.error_by_horizon().items()}
    write_json(out / "manifest.json", manifest)
    return result


def _summarize(episode: _Episode, errors: np.ndarray, horizons: np.ndarray, resyncs: int, a: _Side, b: _Side,
               skipped: dict[str, Any] | None, knobs: dict[str, float]) -> EpisodeSummary:
    """``errors``: the normalised error of every period logged; ``horizons``: periods since the last sync then."""
    # Mean error per horizon: a stable sort keeps each group's order, so np.mean sums as it would the group
    # alone; a group of one (every period without re-syncs) is its value.
    order = np.argsort(horizons, kind="stable")
    grouped = errors[order]
    levels, starts, counts = np.unique(horizons[order], return_index=True, return_counts=True)
    by_h = {int(h): float(grouped[i]) if n == 1 else float(np.mean(grouped[i:i + n]))
            for h, i, n in zip(levels.tolist(), starts.tolist(), counts.tolist(), strict=True)}
    if skipped is not None:
        status = "skipped"
    elif "unstable" in (a.status, b.status):
        status = "unstable"
    elif "failed" in (a.status, b.status):
        status = "failed"
    else:
        status = "completed"
    return EpisodeSummary(
        episode.id, status, len(errors), resyncs,
        float(errors.mean()) if errors.size else math.nan, float(errors.max()) if errors.size else math.nan,
        float(errors[-1]) if errors.size else math.nan,
        by_h,
        {"primary": a.status, "secondary": b.status}, skipped or a.failure or b.failure,
        episode.rewards() if episode.rewards is not None else None, dict(knobs))


def _side_logs(out: Path, side: _Side, episode: str, index: int, writer: ThreadPoolExecutor,
               writes: list[Future[None]]) -> dict[str, Any]:
    """Queue one twin's episode logs for writing; returns its manifest entry (a suite-run scenario record)."""
    onboard = f"scenarios/{episode}/onboard.tsv"
    truth = f"scenarios/{episode}/ground_truth.tsv"
    # The row lists are replaced, not cleared, when the next episode begins: the writer may still read them.
    writes.append(writer.submit(_write_rows, out / side.label / onboard, side.io.onboard_names, side.onboard))
    writes.append(writer.submit(_write_rows, out / side.label / truth, side.io.ground_truth_names, side.truth))
    return {"id": episode, "index": index, "name": episode, "status": side.status, "failure": side.failure,
            "steps": len(side.truth), "onboard": onboard, "ground_truth": truth}


def _write_rows(path: Path, names: Sequence[str], rows: Sequence[Sequence[float]]) -> None:
    write_text(path, format_rows(names, rows))


def _episodes(a: _Side, b: _Side, binding: RobotBinding, suite: Any, lockstep_policy: Any, seed: int,
              n_episodes: int | None, episode_steps: int | None, period: float) -> list[_Episode]:
    if suite is not None:
        plans = plan_scenarios(suite, binding, seed)[: n_episodes or None]
        episodes = []
        for index, plan in enumerate(plans):
            sent: list[dict[str, float]] = []  # the commands of each period, once evaluated

            def begin(plan: Any = plan, index: int = index) -> None:
                fresh = plan.fresh or index == 0
                for side in (a, b):
                    start_scenario(side.io, plan, plan.seed, fresh)

            def send(k: int, plan: Any = plan) -> None:
                commands = plan.commands(k, period)
                for side in (a, b):
                    apply_commands(side.io, commands)

            def send_to(k: int, side: _Side, plan: Any = plan, sent: list[dict[str, float]] = sent) -> None:
                # The primary's pass evaluates the signals; the secondary's replays what it was sent.
                if k == len(sent):
                    sent.append(plan.commands(k, period))
                apply_commands(side.io, sent[k])

            episodes.append(_Episode(plan.id, plan.steps, begin, send, send_to=send_to))
        return episodes
    return _policy_episodes(a, b, lockstep_policy, seed, n_episodes, episode_steps)


def _policy_episodes(a: _Side, b: _Side, lockstep_policy: Any, seed: int, n_episodes: int | None,
                     episode_steps: int | None) -> list[_Episode]:
    from dualtwin.rl.env import TASKS, check_task_kwargs

    args = lockstep_policy.task_arguments()
    task_name = args.get("task", "cartpole_balance")
    if task_name not in TASKS:
        raise DualtwinError(f"policy {lockstep_policy.path}: unknown task {task_name!r}")
    task_kwargs = check_task_kwargs(task_name, args.get("task_kwargs"), f"policy {lockstep_policy.path}: task_kwargs")
    tasks = {}
    for side in (a, b):
        task = TASKS[task_name](continuous=bool(args.get("continuous", False)), **task_kwargs)
        task.bind(side.io)
        tasks[side.label] = task
    limit = getattr(getattr(lockstep_policy, "_loaded", None), "max_episode_steps", None)
    steps = int(episode_steps or limit or DEFAULT_POLICY_STEPS)
    rewards: dict[str, float] = {}

    def make(index: int) -> _Episode:
        def begin() -> None:
            rewards.clear()
            for side in (a, b):
                side.tap.reset(seed + index)
                # The same episode start on both twins: the same generator seed for the task's draw.
                tasks[side.label].initialize_episode(np.random.default_rng(seed + index))
                rewards[side.label] = 0.0

        def send(k: int) -> None:
            action = lockstep_policy.act(tasks["primary"].observation())
            for side in (a, b):
                tasks[side.label].apply_action(action)

        def after() -> bool:
            for side in (a, b):
                tasks[side.label].sample()
                rewards[side.label] += tasks[side.label].reward()
            return bool(tasks["primary"].terminated())

        return _Episode(f"{index:02d}_episode", steps, begin, send, after, lambda: dict(rewards))

    return [make(i) for i in range(n_episodes or DEFAULT_POLICY_EPISODES)]

