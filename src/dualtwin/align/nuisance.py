"""Nuisance knobs: per-scenario initial conditions and time offsets that alignment may fit with the physics.

A recording starts from a state that the suite only approximates: a supervisor's kick, a small initial
velocity, a delay between the start of logging and the start of motion. Fitting the physics alone would
make the physics absorb them (a damping that explains a kick). Nuisance knobs give each such effect its own
parameter, so it can be estimated next to the physics and then discarded.

Names:

* ``scenario.<id>.<key>``: an initial condition the robot binding knows (``initial_angle``,
  ``initial_angular_velocity``, ...) for the fresh scenario ``<id>``. Its nominal value is the suite's; a
  velocity the suite leaves unset has nominal 0 (a reset twin is at rest). A position the suite leaves
  unset is not offered: its nominal value is whatever the model's reset state is, which the suite does not
  say. Scenarios that continue from the previous one apply no initial conditions, so have none of these.
* ``scenario.<id>.time_offset`` (s): the reference's time zero falls this long after the scenario's start
  (positive: logging started late). The candidate's time axis is shifted by it and the objective
  interpolates, so it is continuous; it is not an integer number of control periods.
* ``scenario.*.time_offset`` (this exact name; an exact name wins over glob matching): one offset shared
  by every fitted scenario, for a logger that starts late by the same amount each time. It adds to a
  scenario's own offset if both are fitted (they then trade off; fit one or the other).

An initial kick and a time offset of the *same* scenario nearly trade off when the scenario is a free fall
from rest (both mostly set the amplitude of the growing mode): the trajectory is fitted well, but the two
values are weakly identified (wide intervals). A shared offset is pinned down by the driven scenarios,
where the commands start at a known time.

Decisions: nuisance knobs are never written into the aligned model (``knobs.json``, patched MJCF/world,
DR ranges): they describe one recording, not the robot. Their default bounds are narrow and symmetric
(:data:`DEFAULT_HALF_WIDTH`), because a wide nuisance range lets initial conditions explain what the physics
should; override them with the alignment's ``bounds`` like any knob.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dualtwin.divergence.runs import Series
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.schema import Scenario, Suite
from dualtwin.twins.base import Knob

PREFIX = "scenario."
TIME_OFFSET = "time_offset"
#: The scenario part of the shared time offset's name.
EVERY = "*"
SHARED_TIME_OFFSET = f"{PREFIX}{EVERY}.{TIME_OFFSET}"
#: Default half-width of a nuisance knob's bounds around its nominal value, by quantity.
DEFAULT_HALF_WIDTH = {"position": 0.05, "velocity": 0.5, TIME_OFFSET: 0.1}


def is_nuisance(name: str) -> bool:
    """True for a per-scenario nuisance knob name (``scenario.<id>.<key>``)."""
    return name.startswith(PREFIX)


def split(values: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """``(physics, nuisance)`` knob values."""
    physics = {k: float(v) for k, v in values.items() if not is_nuisance(k)}
    nuisance = {k: float(v) for k, v in values.items() if is_nuisance(k)}
    return physics, nuisance


def parse(name: str, ids: Sequence[str]) -> tuple[str, str]:
    """``(scenario id, key)`` of a nuisance name; scenario ids may contain dots, keys do not."""
    sid, dot, key = name[len(PREFIX):].rpartition(".")
    if name == SHARED_TIME_OFFSET:
        return EVERY, TIME_OFFSET
    if not dot or sid not in ids:
        raise DualtwinError(f"nuisance knob {name!r}: no scenario {sid!r} in the suite (ids: {list(ids)})")
    return sid, key


def registry(suite: Suite, binding: RobotBinding, scenarios: Sequence[str]) -> dict[str, Knob]:
    """The nuisance knobs of ``scenarios`` (ids of ``suite``), ready to merge with a twin's ``knobs()``."""
    ids = suite.scenario_ids()
    half = DEFAULT_HALF_WIDTH[TIME_OFFSET]
    out: dict[str, Knob] = {SHARED_TIME_OFFSET: Knob(
        SHARED_TIME_OFFSET, 0.0, -half, half, "s",
        "every fitted scenario: the reference's time zero falls this long after the scenario's start")}
    conditions = binding.spec.initial_conditions
    for sid, scenario in zip(ids, suite.scenarios, strict=True):
        if sid not in scenarios:
            continue
        half = DEFAULT_HALF_WIDTH[TIME_OFFSET]
        out[f"{PREFIX}{sid}.{TIME_OFFSET}"] = Knob(
            f"{PREFIX}{sid}.{TIME_OFFSET}", 0.0, -half, half, "s",
            f"scenario {sid}: the reference's time zero falls this long after the scenario's start")
        if scenario.reset != "fresh":
            continue
        inputs = scenario.inputs
        for key, ic in conditions.items():
            given = inputs.get(key)
            if isinstance(given, float):
                nominal = given
            elif ic.quantity == "velocity" and ic.joint is not None:
                nominal = 0.0
            else:
                continue
            half = DEFAULT_HALF_WIDTH["velocity" if ic.quantity == "velocity" else "position"]
            name = f"{PREFIX}{sid}.{key}"
            out[name] = Knob(name, nominal, nominal - half, nominal + half, ic.unit,
                             f"scenario {sid}: initial condition {key} ({ic.quantity})")
    return out


def apply_to_suite(suite: Suite, nuisance: Mapping[str, float]) -> Suite:
    """``suite`` with the nuisance initial conditions written into its scenarios (time offsets ignored)."""
    ids = suite.scenario_ids()
    updates: dict[str, dict[str, float]] = {}
    for name, value in nuisance.items():
        sid, key = parse(name, ids)
        if key != TIME_OFFSET:
            updates.setdefault(sid, {})[key] = float(value)
    if not updates:
        return suite
    scenarios = [
        Scenario.model_validate({**s.model_dump(exclude_defaults=True), **updates[sid]}) if sid in updates else s
        for sid, s in zip(ids, suite.scenarios, strict=True)
    ]
    return suite.model_copy(update={"scenarios": scenarios})


def apply_to_document(document: Mapping[str, Any], ids: Sequence[str], nuisance: Mapping[str, float]) -> dict[str, Any]:
    """A suite file's JSON with the nuisance initial conditions written into its scenarios (to run it again)."""
    out = dict(document)
    scenarios = [dict(s) for s in document["scenarios"]]
    for name, value in nuisance.items():
        sid, key = parse(name, ids)
        if key != TIME_OFFSET:
            scenarios[ids.index(sid)][key] = float(value)
    out["scenarios"] = scenarios
    return out


def time_offsets(nuisance: Mapping[str, float], ids: Sequence[str]) -> dict[str, float]:
    """Scenario id -> time offset (s) for every nonzero ``time_offset`` knob (the shared one added to each)."""
    shared = float(nuisance.get(SHARED_TIME_OFFSET, 0.0))
    out: dict[str, float] = {sid: shared for sid in ids} if shared else {}
    for name, value in nuisance.items():
        sid, key = parse(name, ids)
        if key == TIME_OFFSET and sid != EVERY and value != 0.0:
            out[sid] = out.get(sid, 0.0) + float(value)
    return out


def shift_series(series: Mapping[str, Series], offset_s: float) -> dict[str, Series]:
    """Every series on the reference's clock: ``t - offset_s`` (values unchanged, so nothing is extrapolated)."""
    return {name: Series(np.asarray(s.t, dtype=np.float64) - offset_s, s.y) for name, s in series.items()}
