"""MuJoCoTwin.command's fast path (a position command to a native-law motor, inlined in twins/mujoco.py) against
the general path it inlines (_apply_command with MotorState.set_position, which delayed commands take), bit for
bit: motor states, plugin_state and the motion, over periods that clamp targets, flip gains and saturate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dualtwin.robots.binding import resolve_robot
from dualtwin.twins import motor_plugin
from dualtwin.twins.mujoco import MuJoCoTwin

pytestmark = pytest.mark.skipif(motor_plugin.available() is not None,
                                reason=f"motor plugin unavailable: {motor_plugin.available()}")

PERIOD = 0.016
PERIODS = 150


def _run(fast: bool) -> tuple[list[tuple[object, ...]], dict[str, int]]:
    """Per period: every motor's state and saturation, plugin_state, qpos and qvel; and counts of what the
    commands exercised (clamped targets, infinite targets, saturated periods, torque-to-position switches)."""
    twin = MuJoCoTwin(resolve_robot("arm").model_path("mujoco"), PERIOD, native_law=True)
    motors = twin._motors
    # A negative gain, a scaled one, a lower speed cap; one motor without position limits (min == max).
    twin.set_knobs({f"motor.{motors[1].name}.gain": -1.5, f"motor.{motors[2].name}.gain": 0.7,
                    f"motor.{motors[3].name}.max_velocity": 0.8})
    motors[4].state.params.min_position = motors[4].state.params.max_position = 0.0
    twin.reset(0)
    rng = np.random.default_rng(3)
    rows: list[tuple[object, ...]] = []
    seen = {"clamped": 0, "infinite": 0, "saturated": 0, "from_torque": 0}
    for k in range(PERIODS):
        for mo in motors:
            # Mostly position targets, some beyond the limits once the gain applies and some infinite; now
            # and then a velocity or a large torque command, which a later position command leaves.
            mode = ("position", "position", "position", "velocity", "torque")[int(rng.integers(5))] if k % 7 else "position"
            value = float(rng.normal(0.0, 3.0)) if mode != "torque" else float(rng.normal(0.0, 400.0))
            if mode == "position" and rng.random() < 0.1:
                value = math.copysign(math.inf, value)
            if mode == "position":
                p = mo.state.params
                target = value * mo.state.gain
                seen["clamped"] += p.min_position != p.max_position and not p.min_position <= target <= p.max_position \
                    and math.isfinite(target)
                seen["infinite"] += math.isinf(value)
                seen["from_torque"] += mo.state.torque_mode
            if fast:
                twin.command(mo.name, mode, value)  # type: ignore[arg-type]
            else:
                twin._commanded.add(mo.name)
                twin._apply_command(mo, mode, value)  # type: ignore[arg-type]
        twin.step()
        d = twin.data
        seen["saturated"] += any(d.plugin_state[mo.plugin + motor_plugin.SLOT["saturated"]] for mo in motors)
        states = tuple((dataclasses.astuple(mo.state), mo.saturated) for mo in motors)
        rows.append((states, d.plugin_state.tobytes(), d.qpos.tobytes(), d.qvel.tobytes()))
    assert np.isfinite(twin.data.qpos).all()
    twin.close()
    return rows, seen


def test_fast_position_command_equals_the_general_path() -> None:
    fast, seen = _run(fast=True)
    general, general_seen = _run(fast=False)
    # The commands exercise every branch of the fast path: clamping, infinite targets, leaving torque mode and
    # saturation (which a position command resets).
    assert seen == general_seen
    assert min(seen.values()) > 5, seen
    for k, (a, b) in enumerate(zip(fast, general, strict=True)):
        assert a[0] == b[0], f"motor states differ after period {k}"
        assert a[1:] == b[1:], f"plugin_state, qpos or qvel differ after period {k}"
