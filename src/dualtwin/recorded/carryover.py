"""State carried over between scenarios, detected from the data of every channel.

A twin resets before each scenario: joints to the suite's initial conditions (0 where the suite sets none),
free bodies to where the model places them, every velocity to 0. A recording made without that reset (the
paper's orchestrator did not always reset) starts a scenario where the previous one ended. That cannot be
read from the suite's keys alone (the cart's position is rarely set), so each scenario's first sample of every
channel is compared with two candidates:

* the twin's **reset state** (`reset_values`), and
* the **previous scenario's last sample** of the same channel.

A channel that starts far from its reset state and close to where the previous scenario ended carried state
over; one that starts far from both is reported as starting away from its reset state. Both are notes, not
corrections: the data is kept as recorded, and comparisons and analyses say why such a scenario differs
(instead of blaming friction or damping).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from dualtwin.robots.binding import RobotBinding


class Trace(Protocol):
    """A channel's samples in one scenario (`dualtwin.recorded.build.Trace`, which calls this module)."""

    run_name: str
    y: npt.NDArray[np.float64]

#: How far a first sample may be from a candidate state (in the channel's unit: m, rad, m/s ...), unless the
#: channel moves more than that over its first sample interval (a heuristic, recorded in the manifest).
STATE_TOLERANCE = 0.05

AXES = {"x": 0, "y": 1, "z": 2}


def _free_body_positions(robot: RobotBinding) -> dict[str, list[float]]:
    """World positions of the MuJoCo model's top-level bodies (the ones a reset puts back where written)."""
    try:
        root = ET.parse(robot.model_path("mujoco")).getroot()
    except (OSError, ET.ParseError, KeyError, ValueError):
        return {}
    out: dict[str, list[float]] = {}
    world = root.find("worldbody")
    for body in world.findall("body") if world is not None else []:
        name = body.get("name")
        if name:
            out[name] = [float(v) for v in (body.get("pos") or "0 0 0").split()]
    return out


def reset_values(robot: RobotBinding, inputs: dict[str, Any]) -> dict[str, float]:
    """Each ground-truth channel's value right after the twin's reset, where it is known.

    Joint positions and velocities take the suite's initial condition of that joint, else 0; a top-level body's
    position along x/y/z takes the suite's initial condition, else the model's placement; its velocity is 0.
    Orientations and onboard channels are left out (their reset value depends on more than the suite says).
    """
    spec = robot.spec
    set_by_suite: dict[tuple[str, str, str | None], float] = {}
    for key, ic in spec.initial_conditions.items():
        value = inputs.get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            target = ic.joint if ic.joint is not None else ic.body
            if target is not None:
                set_by_suite[(target, ic.quantity, ic.axis)] = float(value)
    bodies = _free_body_positions(robot)
    out: dict[str, float] = {}
    for name, ch in spec.ground_truth.items():
        if ch.joint is not None and ch.quantity in ("position", "velocity"):
            out[name] = set_by_suite.get((ch.joint, ch.quantity, None), 0.0)
        elif ch.body is not None and ch.axis in AXES:
            if ch.quantity == "velocity":
                out[name] = set_by_suite.get((ch.body, "velocity", ch.axis), 0.0)
            elif ch.quantity == "position" and (ch.body, "position", ch.axis) in set_by_suite:
                out[name] = set_by_suite[(ch.body, "position", ch.axis)]
            elif ch.quantity == "position" and ch.body in bodies:
                out[name] = bodies[ch.body][AXES[ch.axis]]
    return out


def _finite_end(tr: Trace, first: bool) -> float | None:
    finite = np.flatnonzero(np.isfinite(tr.y))
    if not finite.size:
        return None
    return float(tr.y[finite[0] if first else finite[-1]])


def _tolerance(tr: Trace) -> float:
    """How far a first sample may sit from a candidate: the heuristic tolerance, or the channel's own motion
    over its first sample interval when that is larger (a falling pole moves during the first period)."""
    y = tr.y[np.isfinite(tr.y)]
    step = float(abs(y[1] - y[0])) if y.size > 1 else 0.0
    return max(STATE_TOLERANCE, 2.0 * step)


def _unit(robot: RobotBinding, name: str) -> str:
    ch = robot.spec.ground_truth.get(name)
    return ch.unit if ch is not None else ""


def state_continuity(robot: RobotBinding, ids: Sequence[str], inputs: Sequence[dict[str, Any]],
                     traces: Sequence[Sequence[Trace]]) -> list[dict[str, Any]]:
    """Per scenario (its id, the suite's inputs, its traces): the channels that carried state over from the
    previous scenario, and those that start away from their reset state; each part with a ``note`` (an empty
    dict where nothing is found)."""
    results: list[dict[str, Any]] = []
    previous: dict[str, float] = {}
    for index, (sid, scenario_inputs, scenario_traces) in enumerate(zip(ids, inputs, traces, strict=True)):
        reset = reset_values(robot, scenario_inputs)
        carried: dict[str, Any] = {}
        away: dict[str, Any] = {}
        for tr in scenario_traces:
            first = _finite_end(tr, first=True)
            if first is None or tr.run_name not in reset:
                continue
            tol = _tolerance(tr)
            expected = reset[tr.run_name]
            if abs(first - expected) <= tol:
                continue
            entry = {"first": first, "reset": expected, "tolerance": tol}
            before = previous.get(tr.run_name)
            if before is not None:
                entry["previous_last"] = before
            if before is not None and abs(first - before) <= tol:
                carried[tr.run_name] = entry
            else:
                away[tr.run_name] = entry
        result: dict[str, Any] = {}
        prev_id = ids[index - 1] if index else None
        if carried:
            what = ", ".join(f"{n} {v['first']:.4g} {_unit(robot, n)} instead of {v['reset']:.4g}"
                             for n, v in carried.items())
            result["carried_over"] = {"from": prev_id, "channels": carried,
                                      "note": f"scenario {sid} starts where {prev_id} ended ({what}): state "
                                              "carried over (no reset between the scenarios)"}
        if away:
            what = ", ".join(f"{n} {v['first']:.4g} {_unit(robot, n)} instead of {v['reset']:.4g}" for n, v in away.items())
            result["away_from_reset"] = {"channels": away,
                                         "note": f"scenario {sid} starts away from the twin's reset state ({what})"
                                                 + ("" if prev_id is None else f", and not where {prev_id} ended")}
        results.append(result)
        previous = {}
        for tr in scenario_traces:
            last = _finite_end(tr, first=False)
            if last is not None and math.isfinite(last):
                previous[tr.run_name] = last
    return results
