"""The twin interface (the paper's ``RLRobot``): one contract, one sibling module per simulator.

A twin is physics only: it knows joints, bodies, actuators and sensors by name and advances in control
periods of simulation time. Suites, rewards and observations are written once on top of this contract
(:mod:`dualtwin.suite.runner`, :mod:`dualtwin.rl`), so they run unchanged on every twin.

Actuator commands mean what a Webots motor means, on every twin:

* ``velocity``: drive the joint to the target velocity, limited by the motor's maximum torque;
* ``position``: Webots' P(ID) on the position error gives a velocity, clamped to the maximum velocity,
  which the velocity motor then tracks;
* ``torque``: apply the torque, clamped to the maximum torque.

Until a motor is first commanded it holds its initial position (Webots' initial state).

Mechanical state (:class:`MechanicalState`, :meth:`Twin.get_state` / :meth:`Twin.set_state`) moves the robot's
full state from one twin into another (online synchronisation, :mod:`dualtwin.sync`). Its conventions:

* free (root) bodies by name: world position of the body *frame origin*, orientation as a unit quaternion
  ``(w, x, y, z)`` with ``w >= 0``, linear velocity of the frame origin and angular velocity, both in world
  coordinates;
* every hinge and slider joint by name: position (rad or m, multi-turn) and velocity. A Webots Hinge2Joint
  ``H`` is two such joints, ``H`` (axis 1) and ``H2`` (axis 2), as the Webots-to-MJCF converter names its two
  hinges. A ball joint ``B`` is three entries ``B/rx``, ``B/ry``, ``B/rz``: the rotation vector of the child
  body's orientation relative to its parent body, and as velocities the child's angular velocity relative
  to the parent in the child's frame (MuJoCo's ball ``qvel``);
* ``holds``: for each joint whose motor has not been commanded since reset (Webots' initial state: the motor
  holds a position), the position it holds. A held motor acts like a stiff spring, so this is part of the
  robot's state even though no controller set it;
* ``time``: the twin's control clock when the state was read (informational; writing a state does not
  move a twin's clock).

Writing a state takes effect *now* from the caller's point of view: the next :meth:`Twin.step` evolves from
it and :meth:`Twin.get_state` returns it until then. After a write, a motor that has not been commanded since
the last reset holds the state's ``holds`` entry for its joint, or else the *written* position, instead of
pulling the joint back to where it held before; commanded motors keep their command (the controller's
intent), and every motor's internal current velocity is zeroed (Webots' joint teleport does that,
docs/reference/webots-on-ode.md §4.1).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.geometry import matrix_from_quat, rotation_vector

ControlMode = Literal["velocity", "position", "torque"]
#: The kinds of names a binding gives a twin (see :meth:`Twin.check_name`); a "free body" is one that
#: :meth:`Twin.set_body_position` can teleport (an initial condition's body).
NameKind = Literal["joint", "body", "free body", "sensor", "motor"]

#: Per-body values of a state vector, in order (see :meth:`MechanicalState.layout`).
BODY_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
#: Names of a ball joint ``B``'s three state entries: ``B/rx``, ``B/ry``, ``B/rz`` (see the module docstring).
BALL_COMPONENTS = ("rx", "ry", "rz")
#: Per-body channels of a state difference: position, rotation vector of the relative rotation, velocities.
BODY_DIFF_FIELDS = ("x", "y", "z", "rx", "ry", "rz", "vx", "vy", "vz", "wx", "wy", "wz")


class SyncError(DualtwinError):
    """A state cannot be written into a twin: non-finite values, penetration, or a violent response to it.

    The twin is left as it was before the write where it can be (MuJoCo), else it needs a reset (Webots).
    ``reason`` is a short keyword (``nonfinite``, ``penetration``, ``unstable``, ``jump``).
    """

    def __init__(self, message: str, reason: str = "invalid") -> None:
        super().__init__(message)
        self.reason = reason


def state_names(bodies: Iterable[str], joints: Iterable[str], holds: Iterable[str]) -> list[str]:
    """Names of a state vector's entries (see :meth:`MechanicalState.layout`)."""
    joints = list(joints)
    names = [f"body/{b}/{f}" for b in bodies for f in BODY_FIELDS]
    names += [f"joint/{j}/q" for j in joints]
    names += [f"joint/{j}/qd" for j in joints]
    names += [f"hold/{j}" for j in holds]
    return names


@dataclass
class BodyState:
    """A free body's pose and velocity (world frame; velocity of the frame origin)."""

    position: np.ndarray
    quaternion: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray

    def vector(self) -> np.ndarray:
        return np.concatenate([self.position, self.quaternion, self.linear_velocity, self.angular_velocity])

    @staticmethod
    def from_vector(values: np.ndarray) -> BodyState:
        v = np.asarray(values, dtype=float)
        return BodyState(v[0:3].copy(), v[3:7].copy(), v[7:10].copy(), v[10:13].copy())

    def rotation(self) -> np.ndarray:
        return matrix_from_quat(self.quaternion)


@dataclass
class MechanicalState:
    """The full mechanical state of a robot, by name, in the conventions of the module docstring."""

    time: float
    bodies: dict[str, BodyState] = field(default_factory=dict)
    joint_positions: dict[str, float] = field(default_factory=dict)
    joint_velocities: dict[str, float] = field(default_factory=dict)
    source: str = ""
    holds: dict[str, float] = field(default_factory=dict)

    def layout(self) -> list[str]:
        """Names of :meth:`vector`'s entries: ``body/<b>/<field>``, ``joint/<j>/q``, ``joint/<j>/qd``, ``hold/<j>``."""
        return state_names(self.bodies, self.joint_positions, self.holds)

    def vector(self) -> np.ndarray:
        parts = [b.vector() for b in self.bodies.values()]
        parts.append(np.array(list(self.joint_positions.values()), dtype=float))
        parts.append(np.array([self.joint_velocities[j] for j in self.joint_positions], dtype=float))
        parts.append(np.array(list(self.holds.values()), dtype=float))
        return np.concatenate(parts)

    def values(self, layout: list[str]) -> np.ndarray:
        """The entries named by ``layout`` (a hold this state lacks is NaN: its motor was commanded since)."""
        mine = dict(zip(self.layout(), self.vector(), strict=True))
        missing = [n for n in layout if n not in mine and not n.startswith("hold/")]
        if missing:
            raise DualtwinError(f"the state has no {', '.join(missing[:5])}")
        return np.array([mine.get(n, math.nan) for n in layout], dtype=float)

    @staticmethod
    def from_vector(layout: list[str], values: np.ndarray, time: float = 0.0, source: str = "") -> MechanicalState:
        """Inverse of :meth:`vector` (or :meth:`values`) for a ``layout`` written by :meth:`layout`; NaN holds
        are dropped."""
        values = np.asarray(values, dtype=float)
        bodies: dict[str, list[float]] = {}
        positions: dict[str, float] = {}
        velocities: dict[str, float] = {}
        holds: dict[str, float] = {}
        for name, value in zip(layout, values, strict=True):
            kind, rest = name.split("/", 1)
            if kind == "hold":
                if not math.isnan(value):
                    holds[rest] = float(value)
                continue
            entity, prop = rest.rsplit("/", 1)
            if kind == "body":
                bodies.setdefault(entity, []).append(float(value))
            elif prop == "q":
                positions[entity] = float(value)
            else:
                velocities[entity] = float(value)
        return MechanicalState(time, {b: BodyState.from_vector(np.array(v)) for b, v in bodies.items()},
                               positions, velocities, source, holds)

    def is_finite(self) -> bool:
        return bool(np.isfinite(self.vector()).all()) and math.isfinite(self.time)

    def nonfinite(self) -> list[str]:
        """Layout names whose values are NaN or infinite."""
        return [n for n, v in zip(self.layout(), self.vector(), strict=True) if not math.isfinite(v)]

    def diff_channels(self) -> list[str]:
        """Names of :meth:`difference`'s channels."""
        names = [f"body/{b}/{f}" for b in self.bodies for f in BODY_DIFF_FIELDS]
        names += [f"joint/{j}/{p}" for j in self.joint_positions for p in ("q", "qd")]
        return names

    def difference(self, other: MechanicalState) -> dict[str, float]:
        """Per-channel ``other - self``; orientations as the rotation vector of ``R_other R_selfᵀ`` (world).

        Raises:
            DualtwinError: The two states name different bodies or joints.
        """
        check_same_entities(self, other, "reference", "other")
        out: dict[str, float] = {}
        for name, a in self.bodies.items():
            b = other.bodies[name]
            rot = rotation_vector(b.rotation() @ a.rotation().T)
            values = [*(b.position - a.position), *rot, *(b.linear_velocity - a.linear_velocity),
                      *(b.angular_velocity - a.angular_velocity)]
            out.update({f"body/{name}/{f}": float(v) for f, v in zip(BODY_DIFF_FIELDS, values, strict=True)})
        for joint, q in self.joint_positions.items():
            out[f"joint/{joint}/q"] = other.joint_positions[joint] - q
            out[f"joint/{joint}/qd"] = other.joint_velocities[joint] - self.joint_velocities[joint]
        return out

    def copy(self) -> MechanicalState:
        return MechanicalState(self.time, {n: BodyState.from_vector(b.vector()) for n, b in self.bodies.items()},
                               dict(self.joint_positions), dict(self.joint_velocities), self.source, dict(self.holds))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (lists of floats)."""
        return {"time": self.time, "source": self.source,
                "bodies": {n: {"position": b.position.tolist(), "quaternion": b.quaternion.tolist(),
                               "linear_velocity": b.linear_velocity.tolist(),
                               "angular_velocity": b.angular_velocity.tolist()} for n, b in self.bodies.items()},
                "joint_positions": dict(self.joint_positions), "joint_velocities": dict(self.joint_velocities),
                "holds": dict(self.holds)}

    @staticmethod
    def from_dict(data: Mapping[str, Any]) -> MechanicalState:
        bodies = {n: BodyState(np.asarray(b["position"], float), np.asarray(b["quaternion"], float),
                               np.asarray(b["linear_velocity"], float), np.asarray(b["angular_velocity"], float))
                  for n, b in dict(data.get("bodies", {})).items()}
        return MechanicalState(float(data.get("time", 0.0)), bodies,
                               {k: float(v) for k, v in dict(data.get("joint_positions", {})).items()},
                               {k: float(v) for k, v in dict(data.get("joint_velocities", {})).items()},
                               str(data.get("source", "")),
                               {k: float(v) for k, v in dict(data.get("holds", {})).items()})


class StateLayout:
    """The entry names of a twin's state vector (:meth:`MechanicalState.vector`) for given bodies, joints and
    held joints. Twins keep one per set of holds, so per-period reads (:meth:`Twin.state_vector`) neither
    build nor parse names."""

    def __init__(self, bodies: Iterable[str], joints: Iterable[str], holds: Iterable[str]) -> None:
        self.bodies, self.joints, self.holds = tuple(bodies), tuple(joints), tuple(holds)
        self.names = state_names(self.bodies, self.joints, self.holds)
        self.core = 13 * len(self.bodies) + 2 * len(self.joints)

    def state(self, values: Sequence[float] | np.ndarray, time: float = 0.0, source: str = "") -> MechanicalState:
        """The state whose :meth:`~MechanicalState.vector` is ``values`` (in this layout)."""
        v = values.tolist() if isinstance(values, np.ndarray) else list(values)
        bodies = {name: BodyState(np.array(v[o:o + 3]), np.array(v[o + 3:o + 7]), np.array(v[o + 7:o + 10]),
                                  np.array(v[o + 10:o + 13]))
                  for name, o in zip(self.bodies, range(0, 13 * len(self.bodies), 13), strict=True)}
        s, n = 13 * len(self.bodies), len(self.joints)
        return MechanicalState(time, bodies, dict(zip(self.joints, v[s:s + n], strict=True)),
                               dict(zip(self.joints, v[s + n:s + 2 * n], strict=True)), source,
                               dict(zip(self.holds, v[s + 2 * n:], strict=True)))


def check_same_entities(a: MechanicalState, b: MechanicalState, label_a: str, label_b: str) -> None:
    """Raise a :class:`DualtwinError` naming every body or joint that only one of two states has."""
    problems = []
    for kind, ka, kb in (("bodies", set(a.bodies), set(b.bodies)),
                         ("joints", set(a.joint_positions), set(b.joint_positions))):
        only_a, only_b = sorted(ka - kb), sorted(kb - ka)
        if only_a:
            problems.append(f"{kind} only in {label_a}: {', '.join(only_a)}")
        if only_b:
            problems.append(f"{kind} only in {label_b}: {', '.join(only_b)}")
    if problems:
        raise DualtwinError("the states cannot be mapped onto each other: " + "; ".join(problems))


@dataclass(frozen=True)
class Knob:
    """A named, bounded physical parameter. Values are always applied from ``nominal``."""

    name: str
    nominal: float
    lower: float
    upper: float
    unit: str = ""
    description: str = ""


class Twin(ABC):
    """One simulator running one robot, headless, in simulation time."""

    name: ClassVar[str]

    @property
    @abstractmethod
    def control_period(self) -> float:
        """Seconds of simulation time advanced by :meth:`step`."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Simulation time in seconds since the last reset."""

    @abstractmethod
    def reset(self, seed: int | None = None) -> None:
        """Return to the loaded initial state; ``seed`` seeds sensor noise."""

    @abstractmethod
    def set_joint_state(self, joint: str, position: float | None = None, velocity: float | None = None) -> None:
        """Teleport a joint (Webots: set the joint's ``position`` field), zeroing its subtree's velocity."""

    @abstractmethod
    def set_body_position(self, body: str, axis: int, value: float) -> None:
        """Teleport a free body along one world axis."""

    @abstractmethod
    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        """Set an actuator target; it acts from the next :meth:`step` on."""

    def check_name(self, kind: NameKind, name: str) -> None:  # noqa: B027 - optional hook
        """Raise the :class:`DualtwinError` the first use of an unknown ``name`` would raise, now.

        A binding names joints, bodies, sensors and motors; checking them all when the twin is bound (see
        :class:`~dualtwin.twins.io.RobotIO`) refuses a wrong name before any output is written, instead of in
        the middle of a run. The default checks nothing (a twin without a cheap lookup fails on first use).
        """

    @abstractmethod
    def step(self) -> None:
        """Advance one control period (physics sub-steps inside). Raises ``SimulationUnstable`` on NaN."""

    @abstractmethod
    def joint_position(self, joint: str) -> float: ...

    @abstractmethod
    def joint_velocity(self, joint: str) -> float: ...

    @abstractmethod
    def body_position(self, body: str) -> np.ndarray:
        """World position of the body's frame origin (Webots ``Node.getPosition``)."""

    @abstractmethod
    def body_orientation(self, body: str) -> np.ndarray:
        """3x3 world rotation matrix of the body frame."""

    @abstractmethod
    def body_velocity(self, body: str) -> np.ndarray:
        """World linear velocity of the body's frame origin followed by its angular velocity (6 values)."""

    @abstractmethod
    def sensor(self, name: str) -> float:
        """An on-board sensor reading (first component for vector sensors)."""

    # Knobs: the parameter registry used by alignment and domain randomisation.
    @abstractmethod
    def knobs(self) -> dict[str, Knob]: ...

    @abstractmethod
    def set_knobs(self, values: dict[str, float]) -> None:
        """Set knob values from nominal: knobs not named return to nominal, so nothing compounds."""

    # State transfer (dualtwin.sync). Optional capability: twins without it raise.
    def get_state(self) -> MechanicalState:
        """The full mechanical state now (see the module docstring for the conventions)."""
        raise DualtwinError(f"twin {self.name!r} cannot read its mechanical state")

    def state_vector(self) -> tuple[StateLayout, np.ndarray]:
        """:meth:`get_state` as its layout and :meth:`MechanicalState.vector`, for loops that read the state
        every period (lockstep): twins override it to skip building the state object. The layout object is
        shared between calls; do not modify it."""
        state = self.get_state()
        return StateLayout(state.bodies, state.joint_positions, state.holds), state.vector()

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        """Put the robot into ``state`` now: the next :meth:`step` evolves from it.

        Args:
            state: A state by name, typically another twin's :meth:`get_state`.
            partial: Allow ``state`` to name only some of this twin's bodies and joints (the others keep their
                state). Names this twin does not have are an error either way.

        Raises:
            DualtwinError: A body or joint cannot be mapped (the message names it).
            SyncError: The state is invalid here (non-finite values, penetration, violent response).
        """
        raise DualtwinError(f"twin {self.name!r} cannot write a mechanical state")

    def render(self, camera: str, width: int, height: int) -> np.ndarray:
        """An RGB frame (H, W, 3) uint8. Optional capability."""
        raise DualtwinError(f"twin {self.name!r} cannot render cameras")

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release simulator resources."""

    def __enter__(self) -> Twin:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_state_names(state: MechanicalState, bodies: list[str], joints: list[str], where: str,
                      partial: bool) -> None:
    """Raise a :class:`DualtwinError` naming what ``state`` has that the twin lacks (and, unless ``partial``,
    what the twin has that ``state`` lacks)."""
    problems = []
    for kind, have, want in (("body", set(bodies), set(state.bodies)),
                             ("joint", set(joints), set(state.joint_positions) | set(state.joint_velocities))):
        missing = sorted(want - have)
        if missing:
            problems.append(f"the state has {kind} {', '.join(map(repr, missing))} that this twin lacks "
                            f"(it has: {', '.join(sorted(have)) or 'none'})")
        unset = sorted(have - want)
        if unset and not partial:
            problems.append(f"the state lacks {kind} {', '.join(map(repr, unset))} of this twin")
    for joint in set(state.joint_positions) ^ set(state.joint_velocities):
        problems.append(f"joint {joint!r} needs both a position and a velocity")
    unknown_holds = sorted(set(state.holds) - set(joints))
    if unknown_holds:
        problems.append(f"the state holds joints {', '.join(map(repr, unknown_holds))} that this twin lacks")
    if problems:
        raise DualtwinError(f"{where}: cannot map the state: " + "; ".join(problems))
    if not state.is_finite():
        bad = state.nonfinite() or ["time"]
        raise SyncError(f"{where}: the state has non-finite values: {', '.join(bad[:6])}", "nonfinite")


#: Physics steps per control period, at most: 1 µs steps in a 10 ms period (the bundled robots take 4 to 16).
#: Beyond it a run is a hang in all but name (and mj_step's step count is a C int).
MAX_SUBSTEPS = 10_000


def control_substeps(control_period: float, step: float, origin: str, what: str) -> int:
    """The whole number of physics steps of ``step`` seconds (``what``, from the model) in one control period.

    The model is untrusted, and its step is not checked where it is compiled: MuJoCo takes timestep="0",
    "nan" or "1e-300", and a world's basicTimeStep may be infinite or far longer than the period (a ratio
    that rounds to zero steps). Each would divide by zero, round a NaN, overflow the step count or step
    through infinite time; one error naming the model instead.
    """
    if not (math.isfinite(step) and step > 0):
        raise DualtwinError(f"{origin}: {what} must be a positive number of seconds, got {step:g} s")
    ratio = control_period / step
    steps = round(ratio) if math.isfinite(ratio) else 0
    if steps < 1 or abs(ratio - steps) > 1e-6:
        raise DualtwinError(f"{origin}: control period {control_period:g} s is not a whole number of physics "
                            f"steps of {step:g} s ({what})")
    if steps > MAX_SUBSTEPS:
        raise DualtwinError(f"{origin}: control period {control_period:g} s takes more than {MAX_SUBSTEPS} "
                            f"physics steps of {step:g} s ({what}), the most allowed")
    return steps


def unknown_name(kind: str, name: str, known: list[str], where: str) -> DualtwinError:
    listing = ", ".join(sorted(known)) or "none"
    return DualtwinError(f"{where}: no {kind} named {name!r} (known: {listing})")
