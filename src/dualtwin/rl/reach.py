"""Reach a point with the arm's flange (issue 19's RL task), written against the binding.

Decisions, and why:

* **Actions are joint-position deltas** on the binding's position actions (Webots' PID position control in
  both twins): the commanded target moves by ``action x max_delta`` per control period and holds where it is
  when the action is zero, so the arm stands still under gravity without the policy having to learn to. The
  command accumulates (it is not the measured angle plus the delta), so encoder noise or a lagging joint never
  makes the command drift; it is clipped to the sampling box widened by ``command_margin``.
* **Three joints move by default** (shoulder pan, shoulder lift, elbow), the wrist joints hold their start
  angles: flange *position* is what success is measured on, and those three joints place it. ``joints`` names
  any subset of the binding's position actions.
* **Targets are reachable by construction and twin-agnostic**: each episode draws a joint configuration,
  holds the arm there for one control period and reads the flange position from the supervisor (a Webots
  teleport only shows in the body poses after a physics step, so there is no kinematics shortcut that both twins
  share), then draws the start configuration. Target and start come from the same box (:data:`DEFAULT_BOX`),
  and a target closer than ``min_target_distance`` to the start is redrawn.
* **Success** is the flange within ``success_radius`` (2 cm) of the target; the episode ends there (Gymnasium's
  ``info["is_success"]``, which SB3's evaluation and :func:`dualtwin.rl.transfer.run_episodes` read).

Observation (float32): the moved joints' encoder angles (rad, on-board), the flange position (m), the target
(m) and target minus flange (m), the last three from the supervisor (on a real arm: forward kinematics of the
encoders, and the target as given).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces

from dualtwin.errors import DualtwinError
from dualtwin.rl.actions import box_action
from dualtwin.rl.env import TASKS, ObservationTerm, Task
from dualtwin.twins.io import RobotIO

# Joint-space box (rad) that targets and starts are drawn from: the arm above its base plane, elbow bent one
# way (the UR convention: lift negative raises the upper arm, elbow positive folds the forearm up).
DEFAULT_BOX: dict[str, tuple[float, float]] = {
    "shoulder_pan": (-1.2, 1.2), "shoulder_lift": (-1.9, -0.5), "elbow": (0.5, 2.2),
    "wrist_1": (-0.5, 0.5), "wrist_2": (-0.5, 0.5), "wrist_3": (-0.5, 0.5)}
DEFAULT_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow")
HELD_JOINTS = {"wrist_1": 0.0, "wrist_2": 0.0, "wrist_3": 0.0}


class ArmReach(Task):
    """Bring the flange within ``success_radius`` (m) of a target point with joint-position-delta actions.

    Action: Box(-1, 1, (len(joints),)); joint ``j``'s position command += clip(action_j, -1, 1) x ``max_delta``
    (rad per control period).

    Reward per control period: ``progress_weight`` x (distance before - distance after) in metres, plus
    ``success_bonus`` on success, minus ``time_cost``.
    """

    def __init__(self, *, continuous: bool = True, joints: list[str] | tuple[str, ...] = DEFAULT_JOINTS,
                 max_delta: float = 0.1, success_radius: float = 0.02, min_target_distance: float = 0.1,
                 command_margin: float = 0.3, progress_weight: float = 10.0, success_bonus: float = 1.0,
                 time_cost: float = 0.01, box: dict[str, list[float]] | None = None,
                 x_channel: str = "ee_x_m", y_channel: str = "ee_y_m", z_channel: str = "ee_z_m") -> None:
        if not continuous:
            raise DualtwinError("reach: actions are continuous joint-position deltas (continuous=True)")
        if min(max_delta, success_radius, min_target_distance) <= 0 or command_margin < 0:
            raise DualtwinError("reach: max_delta, success_radius and min_target_distance must be > 0, "
                                "command_margin >= 0")
        if min(progress_weight, success_bonus, time_cost) < 0:
            raise DualtwinError("reach: progress_weight, success_bonus and time_cost must be >= 0")
        self.joints = tuple(joints)
        if not self.joints or len(set(self.joints)) != len(self.joints):
            raise DualtwinError(f"reach: joints must be distinct action names, got {list(joints)!r}")
        merged = {**DEFAULT_BOX, **{k: (float(v[0]), float(v[1])) for k, v in (box or {}).items()}}
        for name, (low, high) in merged.items():
            if not (math.isfinite(low) and math.isfinite(high) and low <= high):
                raise DualtwinError(f"reach: box[{name!r}] must be two finite numbers, low <= high")
        self.box = merged
        self.continuous = True
        self.max_delta = float(max_delta)
        self.success_radius = float(success_radius)
        self.min_target_distance = float(min_target_distance)
        self.command_margin = float(command_margin)
        self.progress_weight = float(progress_weight)
        self.success_bonus = float(success_bonus)
        self.time_cost = float(time_cost)
        self.position_channels = (x_channel, y_channel, z_channel)
        supervisor = "supervisor (on a real arm: forward kinematics of the encoders)"
        self.observation_terms = (
            *(ObservationTerm(f"{j}_angle", "rad", "onboard", "", f"{j} encoder") for j in self.joints),
            *(ObservationTerm(f"flange_{a}", "m", "privileged", c, f"flange position, {supervisor}")
              for a, c in zip("xyz", self.position_channels, strict=True)),
            *(ObservationTerm(f"target_{a}", "m", "privileged", "", "target point, drawn at reset") for a in "xyz"),
            *(ObservationTerm(f"error_{a}", "m", "privileged", c, "target minus flange position")
              for a, c in zip("xyz", self.position_channels, strict=True)),
        )
        self.target = np.zeros(3)
        self._commands = np.zeros(len(self.joints))
        self._angles = np.zeros(len(self.joints))
        self._flange = np.zeros(3)
        self._distance = 0.0
        self._previous_distance = 0.0

    # ------------------------------------------------------------------ binding
    def bind(self, io: RobotIO) -> None:
        spec = io.robot.spec
        for name in self.position_channels:
            if name not in spec.ground_truth:
                raise DualtwinError(f"{io.robot.path}: task reach needs ground_truth channel {name!r} "
                                    f"(the binding has: {', '.join(sorted(spec.ground_truth))})")
        channels = [spec.ground_truth[c] for c in self.position_channels]
        if [c.axis for c in channels] != ["x", "y", "z"] or any(c.quantity != "position" for c in channels) \
                or len({c.body for c in channels}) != 1 or channels[0].body is None:
            raise DualtwinError(f"{io.robot.path}: task reach needs {', '.join(self.position_channels)} to be the "
                                "x, y and z position of one body (the flange)")
        self.flange_body = channels[0].body
        positional = {k: a for k, a in spec.actions.items() if a.mode == "position"}
        moved_or_held = list(self.joints) + [j for j in HELD_JOINTS if j in positional and j not in self.joints]
        for key in moved_or_held:
            action = positional.get(key)
            if action is None:
                raise DualtwinError(f"{io.robot.path}: task reach needs a position action {key!r} "
                                    f"(position actions in the binding: {', '.join(sorted(positional))})")
            if len(action.actuators) != 1:
                raise DualtwinError(f"{io.robot.path}: reach action {key!r} must drive one joint")
            if key not in self.box:
                raise DualtwinError(f"reach: no sampling box for joint {key!r} (give box={{{key!r}: [low, high]}})")
        self.held = [j for j in moved_or_held if j not in self.joints]
        # The encoder of each moved joint: the on-board channel whose ground-truth twin reads that joint.
        joint_of = {key: self._joint_name(io, key) for key in moved_or_held}
        self._joint_of = joint_of
        self._encoder_index: list[int] = []
        for key in self.joints:
            index = next((i for i, name in enumerate(io.onboard_names)
                          if spec.ground_truth.get(name) is not None and spec.ground_truth[name].joint == joint_of[key]
                          and spec.ground_truth[name].quantity == "position"), None)
            if index is None:
                raise DualtwinError(f"{io.robot.path}: task reach needs an on-board encoder channel for joint "
                                    f"{joint_of[key]!r} (an onboard channel named like the ground_truth channel "
                                    "that reads the joint)")
            self._encoder_index.append(index)
        self._position_index = [io.ground_truth_index(c) for c in self.position_channels]
        self._io = io

    @staticmethod
    def _joint_name(io: RobotIO, key: str) -> str:
        # A Webots motor and its MJCF joint share the name on the bundled arm; the binding's actuators are motors.
        return str(io.robot.spec.actions[key].actuators[0])

    # ------------------------------------------------------------------ actions
    def action_space(self) -> spaces.Space[Any]:
        return spaces.Box(-1.0, 1.0, shape=(len(self.joints),), dtype=np.float32)

    def action_contract(self) -> dict[str, Any]:
        n = len(self.joints)
        return {"type": "box", "shape": [n], "low": [-1.0] * n, "high": [1.0] * n, "dtype": "float32",
                "names": [f"{j}_delta" for j in self.joints], "unit": "rad per control period",
                "scaling": f"position command += clip(action, -1, 1) * {self.max_delta}",
                "scale": self.max_delta, "actuator_mode": "position", "actuator_unit": "rad",
                "actuators": list(self.joints),
                "to_actuator": "binding position actions; the command accumulates from the start angles and is "
                f"clipped to the sampling box widened by {self.command_margin} rad; "
                f"held at their start angles: {', '.join(self.held) or 'none'}"}

    def _limits(self, key: str) -> tuple[float, float]:
        low, high = self.box[key]
        return low - self.command_margin, high + self.command_margin

    def apply_action(self, action: Any) -> None:
        self._commands = self._commands + box_action(action, len(self.joints), "reach") * self.max_delta
        for i, key in enumerate(self.joints):
            low, high = self._limits(key)
            self._commands[i] = min(max(self._commands[i], low), high)
            self.io.apply_action(key, float(self._commands[i]))

    # ------------------------------------------------------------------ episode
    def _pose(self, angles: dict[str, float]) -> None:
        """Teleport the arm to ``angles`` at rest, and command it to hold there."""
        twin = self.io.twin
        for key, angle in angles.items():
            twin.set_joint_state(self._joint_of[key], position=angle, velocity=0.0)
            self.io.apply_action(key, angle)

    def _draw(self, rng: np.random.Generator) -> dict[str, float]:
        angles = {k: float(rng.uniform(*self.box[k])) for k in self.joints}
        angles.update({k: HELD_JOINTS.get(k, 0.0) for k in self.held})
        return angles

    def initialize_episode(self, rng: np.random.Generator) -> None:
        io = self.io
        goal = self._draw(rng)
        # Hold the target pose for one control period, so every twin reports the flange from its physics.
        self._pose(goal)
        io.twin.step()
        self.target = np.array([float(io.twin.body_position(self.flange_body)[a]) for a in range(3)])
        for _ in range(20):
            start = self._draw(rng)
            self._pose(start)
            io.twin.step()
            self.sample()
            if self._distance > self.min_target_distance:
                break
        self._commands = np.array([start[k] for k in self.joints], dtype=np.float64)
        self._previous_distance = self._distance

    def sample(self) -> None:
        io = self.io
        onboard = io.sample_onboard()
        truth = io.sample_ground_truth()
        self._angles = np.array([onboard[i] for i in self._encoder_index], dtype=np.float64)
        self._flange = np.array([truth[i] for i in self._position_index], dtype=np.float64)
        self._previous_distance = self._distance
        self._distance = float(np.linalg.norm(self.target - self._flange))

    def observation(self) -> np.ndarray:
        angles = np.nan_to_num(self._angles)  # Webots encoders read NaN before their first physics step
        return np.concatenate([angles, self._flange, self.target, self.target - self._flange]).astype(np.float32)

    def success(self) -> bool:
        return self._distance <= self.success_radius

    def reward(self) -> float:
        progress = self._previous_distance - self._distance
        return self.progress_weight * progress + (self.success_bonus if self.success() else 0.0) - self.time_cost

    def terminated(self) -> bool:
        return self.success()

    def info(self) -> dict[str, Any]:
        return {"is_success": self.success(), "distance": self._distance,
                "target": self.target.tolist(), "flange": self._flange.tolist()}

    def contract(self) -> dict[str, Any]:
        return {"name": "reach", "joints": list(self.joints), "held_joints": self.held,
                "box_rad": {k: list(self.box[k]) for k in (*self.joints, *self.held)},
                "target": "flange position at a joint configuration drawn uniformly from the box (held one "
                "control period); the start is drawn from the same box, at least "
                f"{self.min_target_distance} m from the target",
                "success_radius_m": self.success_radius, "max_delta_rad": self.max_delta,
                "reward": f"{self.progress_weight} x progress toward the target (m) + {self.success_bonus} on "
                f"success - {self.time_cost} per control period (flange position from the supervisor)",
                "termination": f"flange within {self.success_radius} m of the target (success)"}


TASKS["reach"] = ArmReach

__all__ = ["DEFAULT_BOX", "ArmReach"]
