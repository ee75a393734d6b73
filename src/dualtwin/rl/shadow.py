"""A Webots shadow of MuJoCo RL training: divergence along the states the policy actually visits.

:class:`ShadowCallback` is a Stable-Baselines3 callback. For a sampled fraction of training episodes it
puts a shadow twin (Webots by default) into the training env's state at the episode start (``set_state``),
then mirrors every action the policy sends to that env into the shadow, steps it, and compares the two
mechanical states after every control period. Statistics go to the SB3 logger (TensorBoard when training
logs there) under ``shadow/``:

=============================  ====================================================================
``shadow/error_mean``          mean normalised state error over the shadowed periods of the rollout
``shadow/error_max``           largest normalised error in the rollout
``shadow/error_h1``            mean error one period after a synchronised episode start
``shadow/episode_error_mean``  mean error of each finished shadow episode (averaged over the rollout)
``shadow/channel/<c>``         RMS scaled difference of the three largest channels of finished episodes
``shadow/periods``             shadowed control periods so far
``shadow/episodes``            shadow episodes started so far
``shadow/sync_failures``       episode starts the shadow refused (penetration, non-finite, violent)
``shadow/knob_updates``        monitor knob updates applied to the training envs so far
=============================  ====================================================================

One shadow twin serves all training envs: an episode is shadowed only if no other one is, and then with
probability ``fraction`` (a private generator seeded with ``seed``). The training envs must live in this
process (``vec_env: dummy``); a drift monitor (:class:`dualtwin.sync.Monitor`) may watch the shadow, and its
knob updates are applied to the training envs' knobs, which take effect at their next reset (an episode
boundary). The callback only observes: training itself is unchanged.

The callback lives in :mod:`dualtwin.rl` because it is a piece of training; :mod:`dualtwin.sync` sits above
:mod:`dualtwin.rl` (lockstep runs drive twins with trained policies), so the monitor is typed here by the
:class:`DriftMonitor` protocol it satisfies rather than imported.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from dualtwin.divergence.channels import channel_scales, normalized, normalized_error
from dualtwin.divergence.trajectories import Command, CommandTap
from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins.base import MechanicalState, SyncError
from dualtwin.twins.io import RobotIO


class DriftMonitor(Protocol):
    """What the shadow feeds a drift monitor (:class:`dualtwin.sync.Monitor` is one)."""

    def attach(self, log_path: Path, scales: Mapping[str, float] | None = None) -> None: ...

    def episode_start(self, episode: str, t: float) -> None: ...

    def observe(self, t: float, error: float, channels: Mapping[str, float] | None = None, *,
                state: MechanicalState | None = None, commands: Mapping[str, Command] | None = None,
                period: float | None = None) -> list[dict[str, Any]]: ...

    def episode_end(self, episode: str, t: float) -> dict[str, Any] | None: ...

    def close(self) -> None: ...


class ShadowCallback(BaseCallback):
    """Mirror a sampled fraction of training episodes into a shadow twin and log their divergence.

    Args:
        fraction: Probability that an episode starting while the shadow is free is shadowed (0 to 1).
        twin: The shadow twin's name.
        seed: Seed of the sampling generator and of the shadow twin's resets.
        scales: Channel scale overrides for the normalised error (:mod:`dualtwin.divergence.channels`).
        knobs: Knob values of the shadow twin.
        monitor: Optional drift monitor fed with the shadow's errors.
    """

    def __init__(self, fraction: float = 0.1, *, twin: str = "webots", seed: int = 0,
                 scales: Mapping[str, float] | None = None, knobs: Mapping[str, float] | None = None,
                 monitor: DriftMonitor | None = None, verbose: int = 0) -> None:
        super().__init__(verbose)
        if not 0.0 <= fraction <= 1.0:
            raise DualtwinError(f"shadow fraction must be within [0, 1], got {fraction}")
        self.fraction = float(fraction)
        self.twin_name = twin
        self.seed = seed
        self.scale_overrides = dict(scales or {})
        self.shadow_knobs = dict(knobs or {})
        self.monitor = monitor
        self._rng = np.random.default_rng(seed)
        self._envs: list[Any] = []
        self._shadow: Any = None
        self._tap: CommandTap | None = None
        self._scales: dict[str, float] = {}
        self._active: int | None = None  # index of the shadowed training env
        self._episode_errors: list[float] = []
        self._episode_channels: dict[str, float] = {}
        self._rollout: list[float] = []
        self.periods = 0
        self.episodes = 0
        self.sync_failures = 0
        self.knob_updates = 0
        self._clock = 0.0

    # ------------------------------------------------------------------ set-up
    def _on_training_start(self) -> None:
        from dualtwin.rl.env import TwinEnv

        base: Any = self.training_env
        while hasattr(base, "venv"):
            base = base.venv
        if not hasattr(base, "envs"):
            raise DualtwinError("the shadow needs the training envs in this process: use vec_env 'dummy'")
        self._envs = [env.unwrapped for env in base.envs]
        first = self._envs[0]
        if not isinstance(first, TwinEnv):
            raise DualtwinError(f"the shadow needs dualtwin TwinEnv training envs, got {type(first).__name__}")
        spec = getattr(base.envs[0], "spec", None)
        kwargs = dict(spec.kwargs) if spec is not None else {}
        kwargs.update(twin=self.twin_name, robot=first.robot_name, task=first.task_name,
                      control_period=first.control_period, render_mode=None)
        kwargs.setdefault("continuous", bool(getattr(first.task, "continuous", False)))
        kwargs.pop("knobs", None)
        self._shadow = TwinEnv(**kwargs)
        self._tap = CommandTap(self._shadow.twin)
        # Commands go through the tap, so a monitor's re-alignment sees what the shadow was sent.
        self._shadow.task.bind(RobotIO(self._shadow.robot, self._tap))
        channels = first.twin.get_state().diff_channels()
        self._scales = channel_scales(channels, self.scale_overrides)
        if self.monitor is not None:
            log_dir = Path(getattr(self.logger, "dir", None) or ".")
            self.monitor.attach(log_dir / "shadow_monitor_events.jsonl", self._scales)
        for i in range(len(self._envs)):
            if self._active is None:
                self._maybe_start(i)

    def _maybe_start(self, index: int) -> None:
        if self._active is not None or self._shadow is None or self._rng.random() >= self.fraction:
            return
        assert self._tap is not None
        source = self._envs[index].twin
        self._tap.reset(int(self._rng.integers(2**31 - 1)))
        self._tap.set_knobs(dict(self.shadow_knobs))
        try:
            self._tap.set_state(source.get_state())
        except (SyncError, SimulationUnstable):
            self.sync_failures += 1
            return
        self._active = index
        self.episodes += 1
        self._episode_errors = []
        self._episode_channels = {}
        if self.monitor is not None:
            self.monitor.episode_start(f"shadow{self.episodes:05d}", self._clock)

    # ------------------------------------------------------------------ every step
    def _on_step(self) -> bool:
        actions = self.locals.get("clipped_actions", self.locals.get("actions"))
        dones = np.asarray(self.locals.get("dones", []), dtype=bool)
        index = self._active
        if index is not None and actions is not None:
            self._mirror(index, actions[index], bool(dones[index]) if dones.size > index else False)
        for i in np.flatnonzero(dones):
            if self._active is None:
                self._maybe_start(int(i))
        return True

    def _mirror(self, index: int, action: Any, done: bool) -> None:
        assert self._shadow is not None and self._tap is not None
        self._shadow.task.apply_action(action)
        try:
            self._tap.step()
        except SimulationUnstable:
            self._finish()
            return
        self.periods += 1
        period = self._shadow.control_period
        self._clock += period
        if done:
            # The training env has already been reset for its next episode: nothing left to compare.
            self._finish()
            return
        primary = self._envs[index].twin.get_state()
        shadow = self._tap.get_state()
        diff = primary.difference(shadow)
        error = normalized_error(diff, self._scales)
        scaled = normalized(diff, self._scales)
        if not self._episode_errors:
            self.logger.record_mean("shadow/error_h1", error)
        self._episode_errors.append(error)
        self._rollout.append(error)
        for name, value in scaled.items():
            self._episode_channels[name] = self._episode_channels.get(name, 0.0) + value * value
        if self.monitor is not None:
            # The shadow (Webots) plays the primary: its states are the reference a re-alignment fits to.
            self.monitor.observe(self._clock, error, scaled, state=shadow, commands=dict(self._tap.active),
                                 period=period)

    def _finish(self) -> None:
        errors = self._episode_errors
        if errors:
            self.logger.record_mean("shadow/episode_error_mean", float(np.mean(errors)))
            top = sorted(self._episode_channels, key=lambda c: -self._episode_channels[c])[:3]
            for name in top:
                self.logger.record_mean(f"shadow/channel/{name}", math.sqrt(self._episode_channels[name] / len(errors)))
        self._active = None
        if self.monitor is not None:
            update = self.monitor.episode_end(f"shadow{self.episodes:05d}", self._clock)
            if update is not None:
                for env in self._envs:
                    # TwinEnv applies base_knobs at every reset: the update lands at each env's next episode.
                    env.base_knobs.update(update["knobs"])
                self.knob_updates += 1

    def _on_rollout_end(self) -> None:
        if self._rollout:
            self.logger.record("shadow/error_mean", float(np.mean(self._rollout)))
            self.logger.record("shadow/error_max", float(np.max(self._rollout)))
        self._rollout = []
        self.logger.record("shadow/periods", self.periods)
        self.logger.record("shadow/episodes", self.episodes)
        self.logger.record("shadow/sync_failures", self.sync_failures)
        self.logger.record("shadow/knob_updates", self.knob_updates)

    def _on_training_end(self) -> None:
        if self._shadow is not None:
            self._shadow.close()
            self._shadow = None
        if self.monitor is not None:
            self.monitor.close()

