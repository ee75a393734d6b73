"""Simulator twins behind one interface. Adding a simulator means adding one module and one entry here."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from dualtwin.errors import DualtwinError
from dualtwin.twins.base import BodyState, ControlMode, Knob, MechanicalState, SyncError, Twin

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding

# name -> "module:factory"; a factory takes (robot binding, control period in s) and returns a Twin.
TWINS: dict[str, str] = {
    "mujoco": "dualtwin.twins.mujoco:from_binding",
    "webots": "dualtwin.twins.webots:from_binding",
}


def make_twin(name: str, robot: RobotBinding, control_period: float | None = None) -> Twin:
    """Build the named twin for a robot; the control period defaults to the binding's."""
    if name not in TWINS:
        raise DualtwinError(f"unknown twin {name!r} (available: {', '.join(sorted(TWINS))})")
    module_name, factory = TWINS[name].split(":")
    module = importlib.import_module(module_name)
    period = control_period if control_period is not None else robot.spec.control_period_ms / 1000.0
    twin: Twin = getattr(module, factory)(robot, period)
    return twin


__all__ = ["TWINS", "BodyState", "ControlMode", "Knob", "MechanicalState", "SyncError", "Twin", "make_twin"]
