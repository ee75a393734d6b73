"""Drive a skid-steer robot to a goal point (the Pioneer 3-AT's learning task), written against the binding.

The robot starts at the origin with a random heading; the goal is a random point 0.5-2.5 m away. The policy
sees the goal in its own frame and its wheel speeds, and commands the left and right wheel speeds. Which
terms a real robot has on board is part of the I/O contract: the wheel speeds come from the encoders; the
goal's distance and bearing come from the supervisor's pose (on a real robot: a localisation system), because
skid-steer odometry is poor at exactly what differs most between the twins, the turning.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces

from dualtwin.errors import DualtwinError
from dualtwin.geometry import quat_from_matrix
from dualtwin.rl.actions import box_action
from dualtwin.rl.env import TASKS, ObservationTerm, Task
from dualtwin.twins.io import RobotIO


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class DriveToGoal(Task):
    """Reach a goal point within ``success_radius`` (m) with a differential-drive (skid-steer) robot.

    Observation (float32): goal distance (m), sine and cosine of the goal bearing in the robot frame
    (privileged: supervisor pose), left and right wheel speeds (rad/s, on-board: encoder change over the last
    control period; several encoders per side are averaged by the binding).

    Action: Box([-1, -1], [1, 1]), left and right wheel speed = action x ``max_wheel_speed`` (rad/s), sent to the
    binding's ``left_action``/``right_action`` velocity actuators.

    Reward per control period: ``progress_weight`` x (distance before - distance after) in metres, plus
    ``success_bonus`` when the goal is reached, minus ``time_cost``. The episode ends on success, or when the
    robot is more than ``max_goal_distance + leave_margin`` from the goal; time limits come from the registry.
    """

    def __init__(self, *, continuous: bool = True, max_wheel_speed: float = 6.4,
                 min_goal_distance: float = 0.5, max_goal_distance: float = 2.5, success_radius: float = 0.15,
                 leave_margin: float = 1.5, progress_weight: float = 1.0, success_bonus: float = 1.0,
                 time_cost: float = 0.005, left_action: str = "left_velocity", right_action: str = "right_velocity",
                 left_encoder: str = "left_wheel_rad", right_encoder: str = "right_wheel_rad",
                 x_channel: str = "forward_m", y_channel: str = "lateral_m",
                 heading_channel: str = "heading_rad") -> None:
        if not continuous:
            raise DualtwinError("drive_to_goal: actions are continuous wheel speeds (continuous=True)")
        if min(max_wheel_speed, success_radius, leave_margin, min_goal_distance) <= 0:
            raise DualtwinError("drive_to_goal: max_wheel_speed, success_radius, leave_margin and "
                                "min_goal_distance must be > 0")
        if not success_radius < min_goal_distance <= max_goal_distance:
            raise DualtwinError("drive_to_goal: need success_radius < min_goal_distance <= max_goal_distance")
        if min(progress_weight, success_bonus, time_cost) < 0:
            raise DualtwinError("drive_to_goal: progress_weight, success_bonus and time_cost must be >= 0")
        self.continuous = True
        self.max_wheel_speed = float(max_wheel_speed)
        self.min_goal_distance = float(min_goal_distance)
        self.max_goal_distance = float(max_goal_distance)
        self.success_radius = float(success_radius)
        self.leave_margin = float(leave_margin)
        self.progress_weight = float(progress_weight)
        self.success_bonus = float(success_bonus)
        self.time_cost = float(time_cost)
        self.actions = (left_action, right_action)
        self.encoders = (left_encoder, right_encoder)
        self.pose_channels = (x_channel, y_channel, heading_channel)
        pose, pose_heading = f"{x_channel},{y_channel}", f"{x_channel},{y_channel},{heading_channel}"
        localisation = "supervisor pose (a localisation system on a real robot)"
        self.observation_terms = (
            ObservationTerm("goal_distance", "m", "privileged", pose, f"distance to the goal from the {localisation}"),
            ObservationTerm("goal_bearing_sin", "1", "privileged", pose_heading,
                            f"sine of the goal direction in the robot frame (left positive), {localisation}"),
            ObservationTerm("goal_bearing_cos", "1", "privileged", pose_heading,
                            "cosine of the goal direction in the robot frame (1 = straight ahead)"),
            ObservationTerm("left_wheel_speed", "rad/s", "onboard", left_encoder,
                            "left encoders: change of angle over the last control period / control period"),
            ObservationTerm("right_wheel_speed", "rad/s", "onboard", right_encoder,
                            "right encoders: change of angle over the last control period / control period"),
        )
        self.goal = np.zeros(2)
        self.start_heading = 0.0
        self._encoders = np.zeros(2)
        self._previous_encoders = np.zeros(2)
        self._pose = np.zeros(3)
        self._distance = 0.0
        self._previous_distance = 0.0

    # ------------------------------------------------------------------ binding
    def bind(self, io: RobotIO) -> None:
        spec = io.robot.spec
        for where, table, names in (("onboard", spec.onboard, self.encoders),
                                    ("ground_truth", spec.ground_truth, self.pose_channels)):
            for name in names:
                if name not in table:
                    raise DualtwinError(f"{io.robot.path}: task drive_to_goal needs {where} channel {name!r} "
                                        f"(the binding has: {', '.join(sorted(table))})")
        for key in self.actions:
            action = spec.actions.get(key)
            if action is None or action.mode != "velocity":
                raise DualtwinError(f"{io.robot.path}: task drive_to_goal needs a velocity action {key!r} "
                                    f"(the binding has: {', '.join(sorted(spec.actions))})")
        x, y, heading = (spec.ground_truth[c] for c in self.pose_channels)
        if (x.axis, y.axis, heading.axis) != ("x", "y", "yaw") or x.quantity != "position" \
                or y.quantity != "position" or len({x.body, y.body, heading.body}) != 1 or x.body is None:
            raise DualtwinError(f"{io.robot.path}: task drive_to_goal needs {', '.join(self.pose_channels)} to be "
                                "the x and y position and the yaw of one body")
        self.body = x.body
        self._io = io
        self._encoder_index = [io.onboard_names.index(n) for n in self.encoders]
        self._pose_index = [io.ground_truth_index(c) for c in self.pose_channels]
        self._period = io.twin.control_period

    # ------------------------------------------------------------------ actions
    def action_space(self) -> spaces.Space[Any]:
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)

    def action_contract(self) -> dict[str, Any]:
        spec = self.io.robot.spec
        return {"type": "box", "shape": [2], "low": [-1.0, -1.0], "high": [1.0, 1.0], "dtype": "float32",
                "names": ["left_wheel_speed", "right_wheel_speed"], "unit": "rad/s",
                "scaling": f"wheel speed = clip(action, -1, 1) * {self.max_wheel_speed}",
                "scale": self.max_wheel_speed, "actuator_mode": "velocity", "actuator_unit": "rad/s",
                "actuators": {side: list(spec.actions[key].actuators)
                              for side, key in zip(("left", "right"), self.actions, strict=True)},
                "to_actuator": f"binding actions {self.actions[0]!r} (left) and {self.actions[1]!r} (right)"}

    def wheel_speeds(self, action: Any) -> tuple[float, float]:
        values = box_action(action, 2, "drive_to_goal (left, right)")
        return float(values[0]) * self.max_wheel_speed, float(values[1]) * self.max_wheel_speed

    def _command(self, left: float, right: float) -> None:
        self.io.apply_action(self.actions[0], left)
        self.io.apply_action(self.actions[1], right)

    def apply_action(self, action: Any) -> None:
        self._command(*self.wheel_speeds(action))

    # ------------------------------------------------------------------ episode
    def initialize_episode(self, rng: np.random.Generator) -> None:
        io = self.io
        self.start_heading = float(rng.uniform(-math.pi, math.pi))
        distance = float(rng.uniform(self.min_goal_distance, self.max_goal_distance))
        direction = float(rng.uniform(-math.pi, math.pi))
        state = io.twin.get_state()
        body = state.bodies[self.body]
        c, s = math.cos(self.start_heading), math.sin(self.start_heading)
        yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        body.quaternion = quat_from_matrix(yaw @ body.rotation())
        io.twin.set_state(state, partial=True)
        start = io.twin.body_position(self.body)
        self.goal = np.array([start[0] + distance * math.cos(direction), start[1] + distance * math.sin(direction)])
        # One control period with the wheels held still: a Webots supervisor's teleport only shows in the sensors
        # after the next physics step, so the first observation means the same on all twins.
        self._command(0.0, 0.0)
        self.sample()
        io.twin.step()
        self.sample()
        self._previous_encoders = self._encoders.copy()
        self._previous_distance = self._distance

    def sample(self) -> None:
        io = self.io
        onboard = io.sample_onboard()
        truth = io.sample_ground_truth()
        self._previous_encoders = self._encoders
        self._encoders = np.array([onboard[i] for i in self._encoder_index], dtype=np.float64)
        if not np.isfinite(self._previous_encoders).all():
            # Webots sensors read NaN until their first physics step (just after a reset): report zero speed.
            self._previous_encoders = self._encoders.copy()
        self._pose = np.array([truth[i] for i in self._pose_index], dtype=np.float64)
        self._previous_distance = self._distance
        self._distance = float(math.hypot(*(self.goal - self._pose[:2])))

    def bearing(self) -> float:
        """Direction of the goal in the robot frame (rad, 0 = ahead, positive = to the left)."""
        dx, dy = self.goal - self._pose[:2]
        return _wrap(math.atan2(dy, dx) - float(self._pose[2]))

    def observation(self) -> np.ndarray:
        bearing = self.bearing()
        speeds = (self._encoders - self._previous_encoders) / self._period
        return np.array([self._distance, math.sin(bearing), math.cos(bearing), *speeds], dtype=np.float32)

    def success(self) -> bool:
        return self._distance <= self.success_radius

    def reward(self) -> float:
        progress = self._previous_distance - self._distance
        return (self.progress_weight * progress + (self.success_bonus if self.success() else 0.0)
                - self.time_cost)

    def terminated(self) -> bool:
        return self.success() or self._distance > self.max_goal_distance + self.leave_margin

    def info(self) -> dict[str, Any]:
        # "is_success" is the key SB3's EvalCallback and Monitor read for success rates.
        return {"is_success": self.success(), "goal_distance": self._distance, "goal_x": float(self.goal[0]),
                "goal_y": float(self.goal[1]), "true_x": float(self._pose[0]), "true_y": float(self._pose[1]),
                "true_heading": float(self._pose[2])}

    def contract(self) -> dict[str, Any]:
        return {"name": "drive_to_goal", "start": "origin, heading uniform in [-pi, pi)",
                "goal": f"uniform direction, distance uniform in [{self.min_goal_distance}, "
                f"{self.max_goal_distance}] m from the start",
                "success_radius_m": self.success_radius, "max_wheel_speed_rad_s": self.max_wheel_speed,
                "reward": f"{self.progress_weight} x progress toward the goal (m) + {self.success_bonus} on "
                f"success - {self.time_cost} per control period (distances from the supervisor's pose)",
                "termination": f"goal distance <= {self.success_radius} m (success) or > "
                f"{self.max_goal_distance + self.leave_margin} m (left the area)"}


def proportional_action(observation: np.ndarray, distance_gain: float = 2.0, turn_gain: float = 2.0
                        ) -> np.ndarray:
    """A hand-written reference policy for :class:`DriveToGoal`: turn toward the goal, drive when facing it.

    Used by the tests and the benchmark as a baseline that needs no training.
    """
    distance, sin_b, cos_b = (float(v) for v in observation[:3])
    bearing = math.atan2(sin_b, cos_b)
    forward = min(distance_gain * distance, 1.0) * max(cos_b, 0.0)
    turn = float(np.clip(turn_gain * bearing, -1.0, 1.0))
    return np.clip([forward - turn, forward + turn], -1.0, 1.0).astype(np.float32)


TASKS["drive_to_goal"] = DriveToGoal

__all__ = ["DriveToGoal", "proportional_action"]
