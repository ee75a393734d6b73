"""Binding-driven robot I/O: the suite's words applied to, and read from, any twin.

It lives with the twins because it wraps a :class:`~dualtwin.twins.base.Twin`: everything above the twins
(suites, alignment, RL, lockstep) talks to a robot through it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dualtwin.errors import DualtwinError
from dualtwin.geometry import rpy_from_matrix
from dualtwin.robots.binding import Channel, RobotBinding
from dualtwin.twins.base import ControlMode, NameKind, Twin

AXES = {"x": 0, "y": 1, "z": 2}


def channel_reader(twin: Twin, channel: Channel) -> Callable[[], float]:
    """A function reading ``channel`` from ``twin`` through its getters (what RobotIO samples)."""
    scale = channel.scale
    if channel.sensors:
        names = list(channel.sensors)
        if len(names) == 1:
            name = names[0]
            return lambda: twin.sensor(name) * scale
        return lambda: sum(twin.sensor(n) for n in names) / len(names) * scale
    if channel.joint is not None:
        joint = channel.joint
        if channel.quantity == "position":
            return lambda: twin.joint_position(joint) * scale
        return lambda: twin.joint_velocity(joint) * scale
    body = channel.body or ""
    if channel.axis == "yaw":
        def yaw() -> float:
            return rpy_from_matrix(twin.body_orientation(body), "yaw") * scale
        return yaw
    if channel.axis == "pitch":
        # Z-Y-X Euler angles (R = Rz(yaw) Ry(pitch) Rx(roll)), the convention yaw above already follows.
        def pitch() -> float:
            return rpy_from_matrix(twin.body_orientation(body), "pitch") * scale
        return pitch
    if channel.axis == "roll":
        def roll() -> float:
            return rpy_from_matrix(twin.body_orientation(body), "roll") * scale
        return roll
    axis = AXES[channel.axis or "x"]
    if channel.quantity == "position":
        return lambda: float(twin.body_position(body)[axis]) * scale
    return lambda: float(twin.body_velocity(body)[axis]) * scale


def binding_names(robot: RobotBinding) -> list[tuple[str, NameKind, str]]:
    """Every twin entity the binding names: (the binding field naming it, its kind, the name)."""
    spec = robot.spec
    out: list[tuple[str, NameKind, str]] = []
    for key, ic in spec.initial_conditions.items():
        if ic.joint is not None:
            out.append((f"initial_conditions.{key}.joint", "joint", ic.joint))
        if ic.body is not None:
            out.append((f"initial_conditions.{key}.body", "free body", ic.body))
    for key, action in spec.actions.items():
        out.extend((f"actions.{key}.actuators[{i}]", "motor", name) for i, name in enumerate(action.actuators))
    for log, channels in (("onboard", spec.onboard), ("ground_truth", spec.ground_truth)):
        for key, channel in channels.items():
            out.extend((f"{log}.{key}.sensors[{i}]", "sensor", name) for i, name in enumerate(channel.sensors))
            if channel.joint is not None:
                out.append((f"{log}.{key}.joint", "joint", channel.joint))
            if channel.body is not None:
                out.append((f"{log}.{key}.body", "body", channel.body))
    return out


def check_binding_names(robot: RobotBinding, twin: Twin) -> None:
    """Refuse a binding naming an entity ``twin`` lacks, naming the binding file and field.

    A binding may come from someone else: a wrong name must stop a command before it writes anything, not
    when the first sample or command reaches it (after the run folder exists).
    """
    for where, kind, name in binding_names(robot):
        try:
            twin.check_name(kind, name)
        except DualtwinError as exc:
            raise DualtwinError(f"{robot.path}: $.{where}: {exc}") from None


class RobotIO:
    """Applies initial conditions and actions, and samples the two logs, through a binding."""

    def __init__(self, robot: RobotBinding, twin: Twin) -> None:
        self.robot = robot
        self.twin = twin
        spec = robot.spec
        check_binding_names(robot, twin)
        self.onboard_names = list(spec.onboard)
        self.ground_truth_names = list(spec.ground_truth)
        self._onboard = [channel_reader(twin, c) for c in spec.onboard.values()]
        self._ground_truth = [channel_reader(twin, c) for c in spec.ground_truth.values()]
        self._gt_index = {name: i for i, name in enumerate(self.ground_truth_names)}

    def apply_initial(self, key: str, value: float) -> None:
        ic = self.robot.spec.initial_conditions[key]
        if ic.joint is not None:
            if ic.quantity == "position":
                self.twin.set_joint_state(ic.joint, position=value)
            else:
                self.twin.set_joint_state(ic.joint, velocity=value)
        else:
            self.twin.set_body_position(ic.body or "", AXES[ic.axis or "x"], value)

    def read_initial(self, key: str) -> float:
        """The twin's current value of an initial-condition key (its nominal right after a reset)."""
        ic = self.robot.spec.initial_conditions[key]
        if ic.joint is not None:
            if ic.quantity == "position":
                return float(self.twin.joint_position(ic.joint))
            return float(self.twin.joint_velocity(ic.joint))
        return float(self.twin.body_position(ic.body or "")[AXES[ic.axis or "x"]])

    def apply_action(self, key: str, value: float) -> None:
        action = self.robot.spec.actions[key]
        for actuator in action.actuators:
            self.twin.command(actuator, action.mode, value * action.scale)

    def action_commands(self, key: str) -> list[tuple[str, ControlMode, float]]:
        """What `apply_action` does for ``key``, as ``twin.command(actuator, mode, value * scale)`` per entry:
        for a caller that commands every control period."""
        action = self.robot.spec.actions[key]
        return [(actuator, action.mode, action.scale) for actuator in action.actuators]

    def sample_onboard(self) -> list[float]:
        return [read() for read in self._onboard]

    def sample_ground_truth(self) -> list[float]:
        return [read() for read in self._ground_truth]

    def ground_truth_index(self, channel: str) -> int:
        return self._gt_index[channel]

    def channel_info(self) -> dict[str, Any]:
        """Manifest channels: ground truth under its own names, on-board ones as ``onboard/<column>``."""
        spec = self.robot.spec
        info: dict[str, Any] = {k: {"source": "ground_truth", "unit": c.unit} for k, c in spec.ground_truth.items()}
        for key, channel in spec.onboard.items():
            info[f"onboard/{key}"] = {"source": "onboard", "column": key, "unit": channel.unit}
        # A declared resolution travels with the run (comparisons rank by it); the default by unit is not
        # written, so runs of bindings that declare none keep their manifests unchanged.
        for key, channel in [*spec.ground_truth.items(), *((f"onboard/{k}", c) for k, c in spec.onboard.items())]:
            if channel.resolution is not None:
                info[key]["resolution"] = channel.resolution
        return info
