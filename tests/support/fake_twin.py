"""A tiny pure-Python twin for tests that need a twin's shape but not its physics (the role of SB3's identity envs).

Each joint is a point mass on a damped spring along the world x axis::

    mass * q'' = torque - stiffness * (q - rest) - damping * q'

integrated with semi-implicit Euler in ``substeps`` sub-steps per control period. A motor drives one joint
the way the :class:`~dualtwin.twins.base.Twin` contract says motors do: ``velocity`` is a proportional torque
on the velocity error limited by ``max_torque``, ``position`` is a P law on the position error giving a
velocity (clamped to ``max_velocity``) that the velocity law then tracks, ``torque`` is clamped to
``max_torque``, and a motor that has not been commanded since the last reset holds its joint's position.

The model is a JSON file (the ``fake`` twin's entry in a robot binding), for example::

    {"substeps": 4,
     "joints": {"j1": {"mass": 1.0, "stiffness": 4.0, "damping": 0.4, "rest": 0.0, "body": "bob1"}},
     "motors": {"m1": {"joint": "j1", "max_torque": 10.0, "max_velocity": 3.0, "gain": 150.0, "p": 8.0}},
     "sensors": {"j1 sensor": {"joint": "j1", "noise": 0.0}}}

Knobs (``joint.<j>.mass|stiffness|damping``, ``motor.<m>.max_torque``) are applied from nominal, like every
twin's. A joint's body reports position ``(q, 0, 0)``, the identity orientation and velocity ``(q', 0, ...)``.
Mechanical state: joints and holds, no free bodies. Deterministic: sensor noise comes from the reset seed.

Registered through the public registry (:data:`dualtwin.twins.TWINS`) by :func:`registered`, so suites,
alignment and lockstep reach it by name exactly as they reach MuJoCo and Webots. The registration lives in
this process only: the process pool's fork server and Ray workers do not see it, so tests that use the fake
twin simulate with ``executor="serial"``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.robots.binding import RobotBinding, load_binding
from dualtwin.twins import TWINS
from dualtwin.twins.base import (
    ControlMode,
    Knob,
    MechanicalState,
    StateLayout,
    Twin,
    check_state_names,
    unknown_name,
)

NAME = "fake"
ENTRY = "tests.support.fake_twin:from_binding"
ROBOT = Path(__file__).parent / "fake_robot" / "binding.yaml"
SUITE = ROBOT.parent / "suite.json"
#: Knob families and their bounds relative to the nominal value (lower factor, upper factor, upper floor).
JOINT_KNOBS = {"mass": (0.25, 4.0, 0.0, "kg"), "stiffness": (0.0, 4.0, 1.0, "N*m/rad"),
               "damping": (0.0, 4.0, 1.0, "N*m*s/rad")}


class FakeTwin(Twin):
    """Damped springs driven by Webots-like motors, in microseconds per step."""

    name = NAME

    def __init__(self, model: dict[str, Any], control_period: float, source: str = "fake") -> None:
        if control_period <= 0:
            raise DualtwinError(f"{source}: control period must be positive")
        self._period = float(control_period)
        self._substeps = int(model.get("substeps", 4))
        joints: dict[str, dict[str, Any]] = dict(model["joints"])
        self._joints = list(joints)
        self._index = {j: i for i, j in enumerate(self._joints)}
        self._bodies = {str(spec.get("body", f"{j}_body")): j for j, spec in joints.items()}
        self._nominal = {f"joint.{j}.{field}": float(spec[field])
                         for j, spec in joints.items() for field in JOINT_KNOBS}
        self._rest = [float(s.get("rest", 0.0)) for s in joints.values()]
        self._motors: dict[str, dict[str, float | str]] = {}
        for m, spec in dict(model.get("motors", {})).items():
            if spec["joint"] not in self._index:
                raise DualtwinError(f"{source}: motor {m!r} drives unknown joint {spec['joint']!r}")
            self._motors[m] = {"joint": spec["joint"], "gain": float(spec.get("gain", 40.0)),
                               "p": float(spec.get("p", 10.0)), "max_velocity": float(spec.get("max_velocity", 10.0))}
            self._nominal[f"motor.{m}.max_torque"] = float(spec.get("max_torque", 20.0))
        self._sensors = {s: (str(spec["joint"]), float(spec.get("noise", 0.0)))
                         for s, spec in dict(model.get("sensors", {})).items()}
        # (motor, joint index, gain, p, max velocity): the per-sub-step loop reads plain tuples.
        self._drives = [(m, self._index[str(s["joint"])], float(s["gain"]), float(s["p"]), float(s["max_velocity"]))
                        for m, s in self._motors.items()]
        self._values = dict(self._nominal)
        self._apply()
        self.reset()

    # ---------------------------------------------------------------------------------------------- knobs
    def knobs(self) -> dict[str, Knob]:
        out = {}
        for name, nominal in self._nominal.items():
            field = name.rsplit(".", 1)[1]
            if field in JOINT_KNOBS:
                lo, hi, floor, unit = JOINT_KNOBS[field]
                out[name] = Knob(name, nominal, lo * nominal, max(hi * nominal, floor), unit)
            else:
                out[name] = Knob(name, nominal, 0.0, max(4.0 * nominal, 1.0), "N*m")
        return out

    def set_knobs(self, values: dict[str, float]) -> None:
        unknown = sorted(set(values) - set(self._nominal))
        if unknown:
            raise DualtwinError(f"twin 'fake': unknown knobs {', '.join(unknown)} (known: "
                                f"{', '.join(sorted(self._nominal))})")
        self._values = {**self._nominal, **{k: float(v) for k, v in values.items()}}
        self._apply()

    def _apply(self) -> None:
        v = self._values
        self._mass = [v[f"joint.{j}.mass"] for j in self._joints]
        self._stiffness = [v[f"joint.{j}.stiffness"] for j in self._joints]
        self._damping = [v[f"joint.{j}.damping"] for j in self._joints]
        self._max_torque = {m: v[f"motor.{m}.max_torque"] for m in self._motors}

    # ---------------------------------------------------------------------------------------------- clock
    @property
    def control_period(self) -> float:
        return self._period

    @property
    def time(self) -> float:
        return self._steps * self._period

    def reset(self, seed: int | None = None) -> None:
        self._q = list(self._rest)
        self._qd = [0.0] * len(self._q)
        self._steps = 0
        self._commands: dict[str, tuple[ControlMode, float]] = {}
        self._holds = {m: float(self._q[self._index[str(s["joint"])]]) for m, s in self._motors.items()}
        self._rng = np.random.default_rng(seed)

    # ---------------------------------------------------------------------------------------------- writes
    def _joint(self, joint: str) -> int:
        if joint not in self._index:
            raise unknown_name("joint", joint, self._joints, "twin 'fake'")
        return self._index[joint]

    def _rehold(self) -> None:
        for m, spec in self._motors.items():
            if m not in self._commands:
                self._holds[m] = float(self._q[self._index[str(spec["joint"])]])

    def set_joint_state(self, joint: str, position: float | None = None, velocity: float | None = None) -> None:
        i = self._joint(joint)
        if position is not None:
            self._q[i] = position
            self._qd[i] = 0.0
        if velocity is not None:
            self._qd[i] = velocity
        self._rehold()

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        if body not in self._bodies:
            raise unknown_name("body", body, list(self._bodies), "twin 'fake'")
        if axis == 0:
            self.set_joint_state(self._bodies[body], position=value)

    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        if actuator not in self._motors:
            raise unknown_name("actuator", actuator, list(self._motors), "twin 'fake'")
        if mode not in ("velocity", "position", "torque"):
            raise DualtwinError(f"twin 'fake': unknown control mode {mode!r}")
        self._commands[actuator] = (mode, float(value))

    # ---------------------------------------------------------------------------------------------- physics
    def _torques(self) -> list[float]:
        tau = [0.0] * len(self._q)
        for m, i, gain, p, vmax in self._drives:
            limit = self._max_torque[m]
            mode, value = self._commands.get(m, ("position", self._holds[m]))
            if mode == "torque":
                tau[i] += min(max(value, -limit), limit)
                continue
            target = min(max(p * (value - self._q[i]), -vmax), vmax) if mode == "position" else value
            tau[i] += min(max(gain * (target - self._qd[i]), -limit), limit)
        return tau

    def step(self) -> None:
        # Plain floats: for a handful of joints they are several times faster than numpy's small arrays.
        h = self._period / self._substeps
        q, qd, n = self._q, self._qd, len(self._q)
        for _ in range(self._substeps):
            tau = self._torques()
            for i in range(n):
                accel = (tau[i] - self._stiffness[i] * (q[i] - self._rest[i]) - self._damping[i] * qd[i]) / self._mass[i]
                qd[i] += h * accel
                q[i] += h * qd[i]
        self._steps += 1
        if not all(math.isfinite(v) for v in (*q, *qd)):
            raise SimulationUnstable(f"twin 'fake': non-finite state at t = {self.time:.3f} s")

    # ---------------------------------------------------------------------------------------------- reads
    def joint_position(self, joint: str) -> float:
        return float(self._q[self._joint(joint)])

    def joint_velocity(self, joint: str) -> float:
        return float(self._qd[self._joint(joint)])

    def _body(self, body: str) -> int:
        if body not in self._bodies:
            raise unknown_name("body", body, list(self._bodies), "twin 'fake'")
        return self._index[self._bodies[body]]

    def body_position(self, body: str) -> np.ndarray:
        return np.array([self._q[self._body(body)], 0.0, 0.0])

    def body_orientation(self, body: str) -> np.ndarray:
        self._body(body)
        return np.eye(3)

    def body_velocity(self, body: str) -> np.ndarray:
        return np.array([self._qd[self._body(body)], 0.0, 0.0, 0.0, 0.0, 0.0])

    def sensor(self, name: str) -> float:
        if name not in self._sensors:
            raise unknown_name("sensor", name, list(self._sensors), "twin 'fake'")
        joint, noise = self._sensors[name]
        value = float(self._q[self._index[joint]])
        return value + float(self._rng.normal(0.0, noise)) if noise > 0 else value

    # ---------------------------------------------------------------------------------------------- state
    def _held_joints(self) -> dict[str, float]:
        return {str(s["joint"]): self._holds[m] for m, s in self._motors.items() if m not in self._commands}

    def get_state(self) -> MechanicalState:
        layout = StateLayout((), self._joints, self._held_joints())
        values = [*self._q, *self._qd, *self._held_joints().values()]
        return layout.state(values, self.time, NAME)

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        check_state_names(state, [], self._joints, "twin 'fake'", partial)
        for joint, q in state.joint_positions.items():
            i = self._index[joint]
            self._q[i], self._qd[i] = q, state.joint_velocities[joint]
        self._rehold()
        for m, spec in self._motors.items():
            joint = str(spec["joint"])
            if m not in self._commands and joint in state.holds:
                self._holds[m] = state.holds[joint]


def load_model(path: Path) -> dict[str, Any]:
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    if not isinstance(data, dict) or not isinstance(data.get("joints"), dict) or not data["joints"]:
        raise DualtwinError(f"{path}: a fake-twin model needs a non-empty 'joints' object")
    return data


def from_binding(robot: RobotBinding, control_period: float) -> FakeTwin:
    """The registry's factory (``dualtwin.twins.TWINS['fake']``)."""
    path = robot.model_path(NAME)
    return FakeTwin(load_model(path), control_period, str(path))


def fake_robot() -> RobotBinding:
    """The bundled fake robot: two spring joints, each with a motor and an encoder."""
    return load_binding(ROBOT)


@contextmanager
def registered() -> Iterator[str]:
    """Register the fake twin in the public registry for the duration (its name is yielded), then remove it."""
    had = TWINS.get(NAME)
    TWINS[NAME] = ENTRY
    try:
        yield NAME
    finally:
        if had is None:
            TWINS.pop(NAME, None)
        else:
            TWINS[NAME] = had


def step_rate(twin: Twin, steps: int = 2000) -> float:
    """Control periods per wall-clock second (a quick speed probe)."""
    import time

    start = time.perf_counter()
    for _ in range(steps):
        twin.step()
    return steps / max(time.perf_counter() - start, 1e-9)


__all__ = ["ENTRY", "NAME", "ROBOT", "SUITE", "FakeTwin", "fake_robot", "from_binding", "load_model", "registered",
           "step_rate"]


def fit_fake(out: Path, knobs: list[str], truth: dict[str, float], **settings: Any) -> Any:
    """Fit ``knobs`` of the fake twin to the fake twin run with ``truth`` (least squares, serial, unless
    ``settings`` say otherwise); the AlignResult."""
    from dualtwin.align import AlignConfig, run_align

    config = AlignConfig.model_validate({"reference": NAME, "target": NAME, "robot": str(ROBOT), "suite": str(SUITE),
                                         "knobs": knobs, "reference_knobs": truth, "executor": "serial",
                                         "optimizer": "lsq", **settings})
    return run_align(config, out)
