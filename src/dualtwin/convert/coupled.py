"""Webots' coupled motors (``name::suffix``) in a converted model: their limits as Webots harmonises them at load.

Webots couples the motors of one robot whose names split on ``::`` into exactly two parts with the same first
part (``docs/reference/webots-devices.md`` §9). At load it rewrites every sibling's ``maxVelocity`` and
``minPosition``/``maxPosition`` from the group's first motor (scene-tree order) scaled by the multiplier ratio
r = multiplier / first multiplier: ``maxVelocity`` = |r| x the first's, the position limits r x the first's
(swapped when r < 0; an unlimited first motor leaves them all unlimited) — as our Webots twin does
(``dualtwin.webots.physics.build``). The converter writes the harmonised values into each motor's
``webots_motor.<name>`` numeric (:func:`dualtwin.convert.equivalences.motor_numeric`), so the MuJoCo twin, which
relays a coupled motor's commands to its siblings times each one's multiplier, runs the same limits.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from dualtwin.webots.motor_api import coupled_groups

__all__ = ["PREFIX", "harmonise_coupled_motors"]

PREFIX = "webots_motor."


def _fields(data: list[float]) -> tuple[float, float, float, float]:
    """(maxVelocity, minPosition, maxPosition, multiplier) of a ``webots_motor`` numeric."""
    lo, hi = (data[5], data[6]) if len(data) >= 7 else (0.0, 0.0)
    return data[0], lo, hi, data[7] if len(data) >= 8 else 1.0


def harmonise_coupled_motors(spec: mujoco.MjSpec, warn: Callable[[str], None]) -> None:
    """Rewrite the coupled motors' numerics of ``spec`` with Webots' load-time limits (numerics are in the
    converter's device order, which is the scene tree's)."""
    numerics = {n.name[len(PREFIX):]: n for n in spec.numerics if n.name.startswith(PREFIX)}
    for prefix, members in coupled_groups(list(numerics)).items():
        if len(members) == 1:
            warn(f"motor {members[0]!r}: no other motor is named '{prefix}::...'; nothing is coupled")
            continue
        first_velocity, first_lo, first_hi, first_multiplier = _fields(list(numerics[members[0]].data))
        for name in members[1:]:
            data = list(numerics[name].data)
            velocity, lo, hi, multiplier = _fields(data)
            r = multiplier / first_multiplier
            new_lo, new_hi = sorted((r * first_lo, r * first_hi))
            new = [abs(r) * first_velocity, *data[1:5]]
            if new_lo != new_hi or multiplier != 1.0:
                new += [new_lo, new_hi]
            if multiplier != 1.0:
                new.append(multiplier)
            if (new[0], new_lo, new_hi) != (velocity, lo, hi):
                warn(f"coupled motor {name!r}: maxVelocity and position limits set from {members[0]!r} scaled by the "
                     f"multiplier ratio {r:g} (as Webots does at load)")
            numerics[name].data = new
