"""The online synchronisation monitor: sliding-window divergence statistics, a drift alarm with hysteresis,
an event log, and re-alignment in the background that takes effect at episode boundaries only.

Feed it the normalised state error of every control period (the lockstep runner and the RL shadow do)::

    monitor = Monitor(MonitorConfig(window=25, high=0.5, low=0.25, persist=3,
                                    realign=RealignSettings("mujoco", "cartpole", ("joint.pole_hinge.damping",))))
    run_lockstep("webots", "mujoco", "cartpole", suite=suite, out_dir=out, monitor=monitor)

* Every ``hop`` periods (default: one window) it summarises the last ``window`` errors of the running episode
  (mean, RMS, max, 95th percentile, and the channels that contribute most) and logs a ``window`` event.
* Alarm with hysteresis: raised when the chosen statistic stays above ``high`` for ``persist`` consecutive
  windows, cleared when it falls below ``low``; in between nothing changes, so a signal hovering around one
  threshold cannot make the alarm flicker.
* When the alarm is raised and ``realign`` is set, the primary's recent states and commands (the last
  ``periods`` control periods) are written as a trajectory file and a separate process runs
  :func:`dualtwin.align.run_align` with the ``prediction`` objective on them. Its knob values are handed out by
  :meth:`Monitor.episode_end`, never in the middle of an episode, and only if they lower the objective.
* Every event is a JSON line carrying simulation time (``t``, seconds summed over episodes) and the episode;
  no wall-clock time, so two identical runs write identical logs (with ``wait=True`` for re-alignments).
  A knob update records the alarm that triggered it and the fit's evidence (objective before and after).
"""

from __future__ import annotations

import json
import math
import multiprocessing
from collections import deque
from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np

from dualtwin.artifacts import json_safe
from dualtwin.divergence.trajectories import Command, build_trajectory, save_trajectories
from dualtwin.errors import DualtwinError
from dualtwin.twins.base import MechanicalState

Statistic = Literal["mean", "rms", "max", "p95"]


@dataclass(frozen=True)
class RealignSettings:
    """A background re-alignment of the secondary twin on the recent window's data."""

    target: str
    robot: str
    knobs: tuple[str, ...]
    optimizer: Literal["lsq", "cma"] = "lsq"
    budget: int = 40
    horizons: tuple[int, ...] = (1, 5)
    stride: int = 2
    periods: int | None = None
    out_root: str | None = None
    wait: bool = False
    min_improvement: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class MonitorConfig:
    """Window, statistic and hysteresis thresholds of the drift alarm (see the module docstring)."""

    window: int = 25
    hop: int | None = None
    statistic: Statistic = "rms"
    high: float = 0.5
    low: float = 0.25
    persist: int = 3
    realign: RealignSettings | None = None

    def __post_init__(self) -> None:
        if self.window < 1 or (self.hop is not None and self.hop < 1) or self.persist < 1:
            raise DualtwinError("monitor: window, hop and persist must be at least 1")
        if not 0 <= self.low <= self.high:
            raise DualtwinError(f"monitor: need 0 <= low <= high, got low {self.low}, high {self.high}")
        if self.statistic not in ("mean", "rms", "max", "p95"):
            raise DualtwinError(f"monitor: unknown statistic {self.statistic!r}")


def window_stats(errors: Sequence[float]) -> dict[str, float]:
    values = np.asarray(errors, dtype=float)
    return {"mean": float(values.mean()), "rms": float(np.sqrt(np.mean(values ** 2))),
            "max": float(values.max()), "p95": float(np.percentile(values, 95))}


def _run_realign(settings: dict[str, Any], reference: str, out_dir: str) -> dict[str, Any]:
    """Worker process entry: the prediction-objective fit on the window's trajectories."""
    from dualtwin.align import AlignConfig, run_align

    config = AlignConfig(reference=str(Path(reference)), target=settings["target"], robot=str(settings["robot"]),
                         knobs=list(settings["knobs"]), optimizer=settings["optimizer"], budget=settings["budget"],
                         executor="serial", objective="prediction", horizons=list(settings["horizons"]),
                         stride=settings["stride"])
    result = run_align(config, Path(out_dir))
    return {"fitted": result.fitted, "objective_before": result.objective_before,
            "objective_after": result.objective_after, "evaluations": result.evaluations,
            "out_dir": str(result.out_dir)}


class Monitor:
    """Online drift monitor (see the module docstring). Not thread-safe: one caller feeds it."""

    def __init__(self, config: MonitorConfig | None = None, log_path: Path | None = None) -> None:
        self.config = config or MonitorConfig()
        self.events: list[dict[str, Any]] = []
        self.alarm = False
        self._log_path = Path(log_path) if log_path is not None else None
        self._log: IO[str] | None = None
        self._scales: Mapping[str, float] = {}
        self._episode = ""
        self._errors: deque[float] = deque(maxlen=self.config.window)
        self._channels: deque[Mapping[str, float]] = deque(maxlen=self.config.window)
        self._since_eval = 0
        self._above = 0
        self._recent_stats: deque[dict[str, float]] = deque(maxlen=self.config.persist)
        realign = self.config.realign
        keep = (realign.periods if realign and realign.periods else self.config.window * self.config.persist)
        self._buffer: deque[tuple[str, MechanicalState, dict[str, Command], float]] = deque(maxlen=keep)
        self._pool: ProcessPoolExecutor | None = None
        self._job: Future[dict[str, Any]] | None = None
        self._job_event: dict[str, Any] | None = None
        self._realigns = 0
        self._time = 0.0

    # ------------------------------------------------------------------ wiring
    def attach(self, log_path: Path, scales: Mapping[str, float] | None = None) -> None:
        """Where events go (unless given at construction) and the channel scales in force (for the record)."""
        if self._log_path is None:
            self._log_path = Path(log_path)
        self._scales = dict(scales or {})
        self._emit("monitor_started", config={k: v for k, v in asdict(self.config).items()})

    def _emit(self, kind: str, **data: Any) -> dict[str, Any]:
        event = {"seq": len(self.events), "t": round(self._time, 9), "episode": self._episode, "event": kind, **data}
        self.events.append(event)
        if self._log_path is not None:
            if self._log is None:
                self._log_path.parent.mkdir(parents=True, exist_ok=True)
                self._log = open(self._log_path, "a", encoding="utf-8")  # noqa: SIM115 - held for the run
            self._log.write(json.dumps(json_safe(event), allow_nan=False) + "\n")
            self._log.flush()
        return event

    # ------------------------------------------------------------------ feeding
    def episode_start(self, episode: str, t: float) -> None:
        """A new episode: the window restarts (errors of different episodes are not one signal)."""
        self._episode = episode
        self._time = t
        self._errors.clear()
        self._channels.clear()
        self._since_eval = 0

    def observe(self, t: float, error: float, channels: Mapping[str, float] | None = None, *,
                state: MechanicalState | None = None, commands: Mapping[str, Command] | None = None,
                period: float | None = None) -> list[dict[str, Any]]:
        """One control period's normalised error (and, for re-alignment, the primary's state and commands).

        Returns the events this observation produced.
        """
        self._time = t
        before = len(self.events)
        self._errors.append(float(error) if math.isfinite(error) else math.inf)
        self._channels.append(dict(channels or {}))
        if state is not None:
            self._buffer.append((self._episode, state, dict(commands or {}), float(period or 0.0)))
        self._since_eval += 1
        hop = self.config.hop or self.config.window
        if len(self._errors) == self.config.window and self._since_eval >= hop:
            self._since_eval = 0
            self._evaluate()
        return self.events[before:]

    def _evaluate(self) -> None:
        cfg = self.config
        stats = window_stats(list(self._errors))
        value = stats[cfg.statistic]
        contributions: dict[str, float] = {}
        for row in self._channels:
            for name, v in row.items():
                contributions[name] = contributions.get(name, 0.0) + v * v
        top = sorted(contributions, key=lambda n: -contributions[n])[:3]
        evidence = {"stats": stats, "statistic": cfg.statistic, "value": value,
                    "top_channels": {n: math.sqrt(contributions[n] / len(self._channels)) for n in top}}
        self._emit("window", alarm=self.alarm, **evidence)
        self._recent_stats.append(stats)
        if not self.alarm:
            self._above = self._above + 1 if value > cfg.high else 0
            if self._above >= cfg.persist:
                self.alarm = True
                raised = self._emit("alarm_raised", threshold=cfg.high, windows=cfg.persist,
                                    window_values=[s[cfg.statistic] for s in self._recent_stats], **evidence)
                self._start_realign(raised)
        elif value < cfg.low:
            self.alarm = False
            self._above = 0
            self._emit("alarm_cleared", threshold=cfg.low, **evidence)

    # ------------------------------------------------------------------ re-alignment
    def _start_realign(self, alarm: dict[str, Any]) -> None:
        settings = self.config.realign
        if settings is None or self._job is not None or not self._buffer:
            return
        root = Path(settings.out_root) if settings.out_root else (
            self._log_path.parent / "realign" if self._log_path is not None else Path("realign"))
        folder = root / f"{self._realigns:02d}"
        self._realigns += 1
        trajectories = []
        entries = list(self._buffer)
        start = 0
        for i in range(1, len(entries) + 1):
            if i == len(entries) or entries[i][0] != entries[start][0]:
                chunk = entries[start:i]
                layout = chunk[0][1].layout()
                trajectories.append(build_trajectory(
                    f"{chunk[0][0]}@{start}", chunk[0][3], layout, [e[1].values(layout) for e in chunk],
                    [e[2] for e in chunk]))
                start = i
        usable = [t for t in trajectories if len(t) > min(settings.horizons)]
        if not usable:
            self._emit("realign_skipped", reason="the window holds too little data", alarm_seq=alarm["seq"])
            return
        reference = save_trajectories(folder / "window.npz", usable, {"source": "monitor window"})
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("forkserver"))
        self._job = self._pool.submit(_run_realign, settings.to_dict(), str(reference), str(folder / "fit"))
        self._job_event = self._emit("realign_started", alarm_seq=alarm["seq"], reference=str(reference),
                                     periods=sum(len(t) for t in usable), knobs=list(settings.knobs),
                                     optimizer=settings.optimizer, budget=settings.budget)

    def episode_end(self, episode: str, t: float) -> dict[str, Any] | None:
        """Between episodes: a finished re-alignment's knob update, or None. With ``wait`` this blocks until
        a running one finishes, so runs are reproducible."""
        self._time = t
        job = self._job
        settings = self.config.realign
        if job is None or settings is None:
            return None
        if not job.done() and not settings.wait:
            return None
        started = self._job_event or {}
        self._job, self._job_event = None, None
        try:
            outcome = job.result()
        except Exception as exc:  # noqa: BLE001 - a failed fit is logged, the run goes on
            self._emit("realign_failed", started_seq=started.get("seq"), message=f"{type(exc).__name__}: {exc}")
            return None
        before, after = float(outcome["objective_before"]), float(outcome["objective_after"])
        evidence = {"alarm_seq": started.get("alarm_seq"), "realign_seq": started.get("seq"),
                    "objective_before": before, "objective_after": after, "evaluations": outcome["evaluations"],
                    "fit_dir": outcome["out_dir"], "reference": started.get("reference")}
        if not after < before * (1.0 - settings.min_improvement):
            self._emit("realign_rejected", reason="the fit did not lower the objective", **evidence)
            return None
        event = self._emit("knobs_updated", knobs=dict(outcome["fitted"]), applies_from_episode_after=episode,
                           **evidence)
        return {"knobs": dict(outcome["fitted"]), "evidence": event}

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> Monitor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_events(path: Path) -> list[dict[str, Any]]:
    """A monitor's JSONL event log."""
    path = Path(path)
    if not path.is_file():
        raise DualtwinError(f"{path}: no monitor event log")
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]



__all__ = ["Monitor", "MonitorConfig", "RealignSettings", "read_events", "window_stats"]
