"""Binding generation for a converted robot: names 1:1 with the Webots world, both twins in one file.

* ``twins``: ``mujoco.model`` = the written MJCF, ``webots.model`` = the world, ``webots.robot`` = its DEF/name;
* ``onboard``: one channel per PositionSensor (``<sensor>_rad`` / ``_m``), and GPS x/y when present;
* ``ground_truth``: every hinge/slide joint position (passive hinges as ``<joint>_angle_rad`` so the divergence
  report measures their crossing times), plus the root body's x, y and yaw when it is free;
* ``actions``: ``<motor>_velocity`` and ``<motor>_torque`` (``_force`` for linear motors) per motor, and grouped
  ``<group>_velocity`` / ``<group>_torque`` for motors sharing a name stem (``wheel1..4`` -> ``wheel``) or a
  last word (``rear_left_wheel`` -> ``wheel``);
* ``initial_conditions``: ``<joint>_position`` / ``<joint>_velocity`` per joint, ``initial_x``/``initial_y``
  for a free root body.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

from pydantic import ValidationError

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import Binding


class _Joint(Protocol):
    name: str
    kind: str
    motors: list[str]
    sensors: list[str]


class _Motor(Protocol):
    name: str
    joint: str
    linear: bool


class ConvertedRobot(Protocol):
    """What the binding needs from a conversion (:class:`dualtwin.convert.conversion.Conversion` has it).

    A protocol rather than an import, so the conversion result can use this module without a cycle.
    """

    @property
    def joints(self) -> Sequence[_Joint]: ...
    @property
    def motors(self) -> Sequence[_Motor]: ...
    @property
    def sensors(self) -> dict[str, str]: ...
    @property
    def free_base(self) -> bool: ...
    @property
    def root_body(self) -> str: ...
    @property
    def model_name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def control_period_ms(self) -> float: ...
    @property
    def robot(self) -> str: ...


def key(text: str) -> str:
    """A binding key from a Webots name: lower case, words joined by ``_``."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower() or "x"


def motor_groups(names: list[str]) -> dict[str, list[str]]:
    """Motors that share a stem (trailing digits removed) or a last word, at least two per group."""
    groups: dict[str, list[str]] = defaultdict(list)
    for name in names:
        stem = key(re.sub(r"[\s_\-]*\d+$", "", name))
        words = key(name).split("_")
        candidates = {stem, words[-1]} if len(words) > 1 else {stem}
        for group in candidates:
            if group and group != key(name):
                groups[group].append(name)
    return {g: members for g, members in sorted(groups.items()) if len(members) >= 2}


def make_binding(conv: ConvertedRobot, xml_name: str, webots_model: str) -> dict[str, Any]:
    """The binding dict for a conversion (see the module docstring)."""
    onboard: dict[str, Any] = {}
    ground_truth: dict[str, Any] = {}
    actions: dict[str, Any] = {}
    initial: dict[str, Any] = {}
    joint_kind = {j.name: j.kind for j in conv.joints}
    for joint in conv.joints:
        if joint.kind == "ball":
            continue
        angular = joint.kind == "hinge"
        unit = "rad" if angular else "m"
        for sensor in joint.sensors:
            onboard[f"{key(sensor)}_{unit}"] = {"sensors": [sensor], "unit": unit}
        passive = not joint.motors
        suffix = ("_angle_rad" if passive else "_position_rad") if angular else "_pos_m"
        ground_truth[key(joint.name) + suffix] = {"joint": joint.name, "quantity": "position", "unit": unit}
        initial[f"{key(joint.name)}_position"] = {"joint": joint.name, "quantity": "position", "unit": unit}
        initial[f"{key(joint.name)}_velocity"] = {"joint": joint.name, "quantity": "velocity",
                                                   "unit": f"{unit}/s"}
    for name, kind in conv.sensors.items():
        if kind == "GPS":
            # framepos is 3 values; the twin reads the first component (x).
            onboard[f"{key(name)}_x_m"] = {"sensors": [name], "unit": "m"}
    if conv.free_base:
        body = conv.root_body
        ground_truth[f"{key(body)}_x_m"] = {"body": body, "axis": "x", "quantity": "position", "unit": "m"}
        ground_truth[f"{key(body)}_y_m"] = {"body": body, "axis": "y", "quantity": "position", "unit": "m"}
        ground_truth[f"{key(body)}_yaw_rad"] = {"body": body, "axis": "yaw", "quantity": "position", "unit": "rad"}
        ground_truth[f"{key(body)}_vx_m_s"] = {"body": body, "axis": "x", "quantity": "velocity", "unit": "m/s"}
        initial["initial_x"] = {"body": body, "axis": "x", "unit": "m"}
        initial["initial_y"] = {"body": body, "axis": "y", "unit": "m"}
    for motor in conv.motors:
        linear = motor.linear or joint_kind.get(motor.joint) == "slide"
        vel_unit = "m/s" if linear else "rad/s"
        effort, effort_unit = ("force", "N") if linear else ("torque", "N*m")
        actions[f"{key(motor.name)}_velocity"] = {"actuators": [motor.name], "mode": "velocity", "unit": vel_unit}
        actions[f"{key(motor.name)}_{effort}"] = {"actuators": [motor.name], "mode": "torque", "unit": effort_unit}
    motors = {m.name: m for m in conv.motors}
    for group, members in motor_groups([m.name for m in conv.motors]).items():
        linear = all(motors[m].linear for m in members)
        effort = "force" if linear else "torque"
        velocity_key, effort_key = f"{group}_velocity", f"{group}_{effort}"
        if velocity_key not in actions:
            actions[velocity_key] = {"actuators": members, "mode": "velocity", "unit": "m/s" if linear else "rad/s"}
        if effort_key not in actions:
            actions[effort_key] = {"actuators": members, "mode": "torque", "unit": "N" if linear else "N*m"}
    clash = set(initial) & set(actions)
    for k in clash:
        del initial[k]
    return {
        "name": key(conv.model_name),
        "description": conv.description,
        "control_period_ms": conv.control_period_ms,
        "twins": {"mujoco": {"model": xml_name}, "webots": {"model": webots_model, "robot": conv.robot}},
        "initial_conditions": initial,
        "actions": actions,
        "onboard": onboard,
        "ground_truth": ground_truth,
    }


def validate_binding(data: dict[str, Any], where: Path | str) -> Binding:
    """Validate a generated binding; a robot without on-board sensors cannot have one."""
    if not data.get("onboard"):
        raise DualtwinError(f"{where}: the robot has no on-board sensors (PositionSensor, GPS), so no binding can be "
                            "written (the TestRobot log needs at least one); add a PositionSensor to a joint")
    try:
        return Binding.model_validate(data)
    except ValidationError as exc:
        raise DualtwinError(f"{where}: generated binding is invalid: {exc}") from None
