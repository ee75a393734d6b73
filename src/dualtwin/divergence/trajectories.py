"""Recorded trajectories with full mechanical states, and the per-period commands of a suite scenario.

A :class:`Trajectory` is what multiple-shooting needs: the state after every control period, the motor
commands that were active during every period, and the ground-truth channels. Index ``k`` holds the state at
the end of period ``k + 1`` (time ``(k + 1)·T``) and the commands active *during* period ``k + 1``. A
prediction from ``states[i]`` over ``h`` periods therefore replays ``commands[i + 1 .. i + h]`` and is compared
with ``states[i + h]``.

Commands are recorded per actuator (mode and value) by a :class:`CommandTap`, a twin that forwards everything
to the real one and notes every ``command``; so suite scenarios and policy-driven episodes record alike.
Suite scenarios send their commands like the suite runner (:func:`dualtwin.suite.runner.run_scenario`):
constant actions once before the first period, time-varying signals every period. Replaying a recording
sends every active command at the start and then only the ones that change, which is what the recording did.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import atomic_open
from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.schema import Suite
from dualtwin.twins.base import ControlMode, Knob, MechanicalState, NameKind, StateLayout, Twin
from dualtwin.twins.io import RobotIO

TRAJECTORIES_SCHEMA = "dualtwin.trajectories/1"
MODES: tuple[ControlMode, ...] = ("velocity", "position", "torque")
Command = tuple[ControlMode, float]


class CommandTap(Twin):
    """A twin that forwards everything to ``inner`` and keeps the last command sent to each actuator."""

    def __init__(self, inner: Twin) -> None:
        self.inner = inner
        self.name = inner.name  # type: ignore[misc]  # per instance: the tapped twin's name
        self.active: dict[str, Command] = {}

    @property
    def control_period(self) -> float:
        return self.inner.control_period

    @property
    def time(self) -> float:
        return self.inner.time

    def reset(self, seed: int | None = None) -> None:
        self.active.clear()
        self.inner.reset(seed)

    def set_joint_state(self, joint: str, position: float | None = None, velocity: float | None = None) -> None:
        self.inner.set_joint_state(joint, position, velocity)

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        self.inner.set_body_position(body, axis, value)

    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        self.inner.command(actuator, mode, value)
        self.active[actuator] = (mode, float(value))

    def check_name(self, kind: NameKind, name: str) -> None:
        self.inner.check_name(kind, name)

    def step(self) -> None:
        self.inner.step()

    def joint_position(self, joint: str) -> float:
        return self.inner.joint_position(joint)

    def joint_velocity(self, joint: str) -> float:
        return self.inner.joint_velocity(joint)

    def body_position(self, body: str) -> np.ndarray:
        return self.inner.body_position(body)

    def body_orientation(self, body: str) -> np.ndarray:
        return self.inner.body_orientation(body)

    def body_velocity(self, body: str) -> np.ndarray:
        return self.inner.body_velocity(body)

    def sensor(self, name: str) -> float:
        return self.inner.sensor(name)

    def knobs(self) -> dict[str, Knob]:
        return self.inner.knobs()

    def set_knobs(self, values: dict[str, float]) -> None:
        self.inner.set_knobs(values)

    def get_state(self) -> MechanicalState:
        return self.inner.get_state()

    def state_vector(self) -> tuple[StateLayout, np.ndarray]:
        return self.inner.state_vector()

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        self.inner.set_state(state, partial=partial)

    def render(self, camera: str, width: int, height: int) -> np.ndarray:
        return self.inner.render(camera, width, height)

    def close(self) -> None:
        self.inner.close()


@dataclass
class ScenarioPlan:
    """A suite scenario as initial conditions plus the commands of every period."""

    id: str
    initial: dict[str, float]
    constant: dict[str, float]
    signals: dict[str, Callable[[float], float]]
    steps: int
    seed: int
    fresh: bool = True

    def commands(self, k: int, period: float) -> dict[str, float]:
        """Action values sent at the start of period ``k + 1`` (k from 0): constants only at k = 0."""
        out = dict(self.constant) if k == 0 else {}
        out.update({key: float(signal(k * period)) for key, signal in self.signals.items()})
        return out


def plan_scenarios(suite: Suite, robot: RobotBinding, seed: int = 0) -> list[ScenarioPlan]:
    """One plan per scenario, in suite order (``fresh`` follows the suite's reset rules)."""
    actions = robot.spec.actions
    conditions = robot.spec.initial_conditions
    period = suite.global_settings.control_period_s
    plans = []
    for index, (sid, scenario) in enumerate(zip(suite.scenario_ids(), suite.scenarios, strict=True)):
        inputs = scenario.inputs
        plans.append(ScenarioPlan(
            id=sid,
            initial={k: float(v) for k, v in inputs.items() if k in conditions},
            constant={k: float(v) for k, v in inputs.items() if k in actions and isinstance(v, float)},
            signals={k: v for k, v in inputs.items() if k in actions and not isinstance(v, float)},
            steps=math.ceil(scenario.duration_s / period - 1e-9),
            seed=scenario.seed if scenario.seed is not None else seed,
            fresh=index == 0 or scenario.reset == "fresh",
        ))
    return plans


def start_scenario(io: RobotIO, plan: ScenarioPlan, seed: int, fresh: bool = True) -> None:
    """Reset (if ``fresh``) and apply the initial conditions, positions first, like the suite runner."""
    if fresh:
        io.twin.reset(seed)
        conditions = io.robot.spec.initial_conditions
        for key in sorted(plan.initial, key=lambda k: conditions[k].quantity != "position"):
            io.apply_initial(key, plan.initial[key])


def apply_commands(io: RobotIO, commands: Mapping[str, float]) -> None:
    for key, value in commands.items():
        io.apply_action(key, value)


@dataclass
class Trajectory:
    """One episode on one twin: states, active motor commands and ground truth after every control period.

    ``commands[k, a]`` is the value and ``modes[k, a]`` the index into :data:`MODES` (-1: never commanded) of
    actuator ``actuators[a]`` during the period ending at ``k``.
    """

    id: str
    period: float
    layout: list[str]
    states: np.ndarray
    actuators: list[str]
    commands: np.ndarray
    modes: np.ndarray
    channels: list[str] = field(default_factory=list)
    truth: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    status: str = "completed"

    def __len__(self) -> int:
        return int(self.states.shape[0])

    @property
    def times(self) -> np.ndarray:
        return (np.arange(len(self)) + 1) * self.period

    def state(self, k: int) -> MechanicalState:
        return MechanicalState.from_vector(self.layout, self.states[k], time=float(self.times[k]))

    def active(self, k: int) -> dict[str, Command]:
        """Commands active during the period ending at index ``k`` (actuators never commanded are absent)."""
        return {name: (MODES[int(m)], float(v)) for name, m, v in zip(self.actuators, self.modes[k], self.commands[k],
                                                                      strict=True) if m >= 0}

    def window(self, start: int, stop: int, suffix: str = "") -> Trajectory:
        return Trajectory(self.id + suffix, self.period, list(self.layout), self.states[start:stop].copy(),
                          list(self.actuators), self.commands[start:stop].copy(), self.modes[start:stop].copy(),
                          list(self.channels), self.truth[start:stop].copy() if self.truth.size else self.truth,
                          self.status)


def replay(twin: Twin, commands: Mapping[str, Command], previous: Mapping[str, Command] | None = None) -> None:
    """Send the commands that differ from ``previous`` (all of them without it)."""
    for actuator, (mode, value) in commands.items():
        if previous is None or previous.get(actuator) != (mode, value):
            twin.command(actuator, mode, value)


class TrajectoryRecorder:
    """Collects one episode period by period from a :class:`CommandTap` (lockstep and recording use it)."""

    def __init__(self, episode: str, tap: CommandTap, channels: Sequence[str] = ()) -> None:
        self.episode = episode
        self.tap = tap
        self.period = tap.control_period
        self.channels = list(channels)
        self.layout: list[str] | None = None
        self._first: StateLayout | None = None
        self._states: list[np.ndarray] = []
        self._active: list[dict[str, Command]] = []
        self._truth: list[list[float]] = []

    def after_period(self, layout: StateLayout, vector: np.ndarray, truth: Sequence[float] = (),
                     active: Mapping[str, Command] | None = None) -> None:
        """Record the state reached by the period just stepped (a twin's :meth:`~Twin.state_vector`) and the
        commands that drove it (``active``: the tap's active commands then; default: now)."""
        if self._first is None:
            self._first, self.layout = layout, list(layout.names)
        # Twins reuse one layout object per set of holds: the usual case costs an identity test.
        if layout is self._first or layout.names == self.layout:
            self._states.append(vector)
        else:  # a motor was commanded since (its hold is gone: NaN), or a hold appeared after a reset
            self._states.append(layout.state(vector).values(self._first.names if self.layout is None else self.layout))
        self._active.append(dict(self.tap.active if active is None else active))
        self._truth.append(list(map(float, truth)))

    def finish(self, status: str = "completed") -> Trajectory:
        return build_trajectory(self.episode, self.period, list(self.layout or []), self._states, self._active,
                                self.channels, self._truth, status)


def build_trajectory(episode: str, period: float, layout: list[str], states: Sequence[np.ndarray],
                     actives: Sequence[Mapping[str, Command]], channels: Sequence[str] = (),
                     truth: Sequence[Sequence[float]] = (), status: str = "completed") -> Trajectory:
    """A :class:`Trajectory` from per-period state vectors (in ``layout``) and active-command dicts."""
    n = len(states)
    actuators: list[str] = []
    for active in actives:
        actuators += [a for a in active if a not in actuators]
    # Nested lists converted once: element-wise writes into numpy arrays cost ~1 us each, every period.
    mode_index = {mode: i for i, mode in enumerate(MODES)}
    commands = np.array([[active[a][1] if a in active else math.nan for a in actuators] for active in actives],
                        dtype=float).reshape(n, len(actuators))
    modes = np.array([[mode_index[active[a][0]] if a in active else -1 for a in actuators] for active in actives],
                     dtype=np.int8).reshape(n, len(actuators))
    width = len(truth[0]) if len(truth) == n and n else 0
    truth_array = np.array(truth, dtype=float).reshape(n, width) if width else np.zeros((n, 0))
    return Trajectory(episode, period, layout, np.array(states, dtype=float).reshape(n, len(layout)), actuators,
                      commands, modes, list(channels) if width else [], truth_array, status)


def record_trajectories(twin: Twin, robot: RobotBinding, suite: Suite, scenarios: Sequence[str] | None = None,
                        seed: int = 0) -> list[Trajectory]:
    """Run suite scenarios on ``twin`` and record each as a :class:`Trajectory` (fresh start per scenario)."""
    tap = CommandTap(twin)
    io = RobotIO(robot, tap)
    plans = plan_scenarios(suite, robot, seed)
    wanted = set(scenarios) if scenarios is not None else {p.id for p in plans}
    unknown = sorted(wanted - {p.id for p in plans})
    if unknown:
        raise DualtwinError(f"unknown scenario ids {unknown}; the suite has {[p.id for p in plans]}")
    period = twin.control_period
    out = []
    for plan in plans:
        if plan.id not in wanted:
            continue
        start_scenario(io, plan, plan.seed)
        recorder = TrajectoryRecorder(plan.id, tap, io.ground_truth_names)
        status = "completed"
        for k in range(plan.steps):
            apply_commands(io, plan.commands(k, period))
            try:
                tap.step()
            except SimulationUnstable:
                status = "unstable"
                break
            recorder.after_period(*tap.state_vector(), io.sample_ground_truth())
        out.append(recorder.finish(status))
    return out


def save_trajectories(path: Path, trajectories: Sequence[Trajectory], meta: Mapping[str, Any] | None = None) -> Path:
    """One ``.npz``: arrays per trajectory plus a JSON header (layout, keys, channels, status, ``meta``)."""
    arrays: dict[str, np.ndarray] = {}
    header: dict[str, Any] = {"schema": TRAJECTORIES_SCHEMA, "meta": dict(meta or {}), "trajectories": []}
    for i, t in enumerate(trajectories):
        arrays[f"t{i}_states"] = t.states
        arrays[f"t{i}_commands"] = t.commands
        arrays[f"t{i}_modes"] = t.modes
        arrays[f"t{i}_truth"] = t.truth
        header["trajectories"].append({"id": t.id, "period": t.period, "layout": t.layout,
                                       "actuators": t.actuators, "channels": t.channels, "status": t.status})
    arrays["header"] = np.array(json.dumps(header))
    path = Path(path)
    with atomic_open(path, "wb") as handle:
        # Not compressed: simulation doubles shrink by only a third, for four times the CPU (lockstep saves one)
        np.savez(handle, **arrays)  # type: ignore[arg-type]
    return path


def load_trajectories(path: Path) -> tuple[list[Trajectory], dict[str, Any]]:
    """Trajectories and the ``meta`` saved with them."""
    path = Path(path)
    if not path.is_file():
        raise DualtwinError(f"{path}: trajectory file not found")
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(str(data["header"]))
            if header.get("schema") != TRAJECTORIES_SCHEMA:
                raise DualtwinError(f"{path}: not a dualtwin trajectory file (schema {header.get('schema')!r})")
            out = []
            for i, t in enumerate(header["trajectories"]):
                out.append(Trajectory(t["id"], float(t["period"]), list(t["layout"]), data[f"t{i}_states"],
                                      list(t["actuators"]), data[f"t{i}_commands"], data[f"t{i}_modes"],
                                      list(t["channels"]), data[f"t{i}_truth"], t["status"]))
    except (OSError, ValueError, KeyError) as exc:
        raise DualtwinError(f"{path}: unreadable trajectory file ({exc})") from None
    return out, dict(header.get("meta", {}))
