"""Which initial conditions a robot can physically start from, checked before anything is simulated.

Two rules, the same in ``suite validate --robot`` and every command that runs a suite:

* a joint position set by an initial condition lies within the joint's stops, where the robot's model gives
  it stops (read from its MuJoCo model, whose limits both twins share; a small tolerance lets a suite start a
  joint exactly at a stop);
* every initial condition's magnitude is at most :data:`MAX_INITIAL_MAGNITUDE` in its SI unit (rad, rad/s,
  m, m/s): no robot we model starts ten kilometres away or spinning at 1,600 turns a second, and beyond such
  values a simulator loses every digit of the state (an angle of 1e300 rad has no meaningful remainder) or
  never finishes normalising it.

A state that slips past these checks anyway (a library caller, a perturbation) is reported as an unstable
scenario at its start by :func:`dualtwin.suite.runner.run_scenario`, never simulated.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding

#: The largest magnitude of any initial condition, in SI units (documented in docs/ and above).
MAX_INITIAL_MAGNITUDE = 1e4
#: Slack at a joint stop (rad or m): a suite may start a joint exactly at its stop as the model writes it.
STOP_TOLERANCE = 1e-6


def impossible_reason(value: float) -> str | None:
    """Why ``value`` cannot be any initial state (not finite or beyond the bound), or None."""
    if not math.isfinite(value):
        return f"{value!r} is not a finite number"
    if abs(value) > MAX_INITIAL_MAGNITUDE:
        return f"{value!r} is beyond the bound of ±{MAX_INITIAL_MAGNITUDE:g} (SI units) on initial conditions"
    return None


def joint_stops(robot: RobotBinding) -> dict[str, tuple[float, float]]:
    """Initial-condition key -> (low, high) stops of the joint it positions, for joints that have stops."""
    spec = robot.spec
    if "mujoco" not in spec.twins:
        return {}
    stops = _model_stops(str(robot.model_path("mujoco")))
    out = {}
    for key, ic in spec.initial_conditions.items():
        if ic.joint is None or ic.quantity != "position":
            continue
        found = stops.get(robot.twin_name("mujoco", ic.joint))
        if found is not None:
            out[key] = found
    return out


@lru_cache(maxsize=16)
def _model_stops(model: str) -> dict[str, tuple[float, float]]:
    import mujoco

    from dualtwin.twins.mjcf_files import compile_spec, load_spec

    try:
        compiled = compile_spec(load_spec(Path(model)), model)
    except DualtwinError:
        return {}  # the run itself reports an unreadable model, naming it
    out = {}
    for j in range(compiled.njnt):
        if compiled.jnt_limited[j] and int(compiled.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                                                       int(mujoco.mjtJoint.mjJNT_SLIDE)):
            name = mujoco.mj_id2name(compiled, mujoco.mjtObj.mjOBJ_JOINT, j)
            if name:
                low, high = (float(v) for v in compiled.jnt_range[j])
                out[name] = (low, high)
    return out


def check_initial_value(key: str, value: float, stops: dict[str, tuple[float, float]], where: str,
                        robot: RobotBinding) -> None:
    """Refuse ``value`` for initial condition ``key`` with one line naming ``where`` (file and JSON path)."""
    reason = impossible_reason(value)
    if reason is None and key in stops:
        low, high = stops[key]
        if not low - STOP_TOLERANCE <= value <= high + STOP_TOLERANCE:
            joint = robot.spec.initial_conditions[key].joint
            reason = (f"{value:g} is outside joint {joint!r}'s stops [{low:g}, {high:g}] "
                      f"(robot {robot.name!r}); no robot can start there")
    if reason is not None:
        raise DualtwinError(f"{where}: initial condition {key!r}: {reason}")


