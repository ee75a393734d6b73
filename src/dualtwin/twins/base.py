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
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from dualtwin.errors import DualtwinError

ControlMode = Literal["velocity", "position", "torque"]


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

    def render(self, camera: str, width: int, height: int) -> np.ndarray:
        """An RGB frame (H, W, 3) uint8. Optional capability."""
        raise DualtwinError(f"twin {self.name!r} cannot render cameras")

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release simulator resources."""

    def __enter__(self) -> Twin:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def unknown_name(kind: str, name: str, known: list[str], where: str) -> DualtwinError:
    listing = ", ".join(sorted(known)) or "none"
    return DualtwinError(f"{where}: no {kind} named {name!r} (known: {listing})")
