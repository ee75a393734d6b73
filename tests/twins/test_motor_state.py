"""MotorState's command clamps (twins/motors.py) are written as comparisons, not min/max calls (they run per
command and motor): they must pick exactly what ``max(-limit, min(limit, value))`` picks, bit for bit, with
NaN, infinities and signed zeros among the commands, gains and limits."""

from __future__ import annotations

import itertools
import math
import struct

from dualtwin.twins.motors import MotorParams, MotorState

SPECIAL = [math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0, 1.0, -1.0, 2.5, -2.5, 7.0, -7.0, 1e-300]
LIMITS = [3.0, 0.0, -0.0, math.inf, 1.0, -1.0, math.nan]


def _bits(value: float) -> bytes:
    return struct.pack("<d", value)


def test_velocity_clamp_picks_what_min_and_max_pick() -> None:
    for limit, command, gain in itertools.product(LIMITS, SPECIAL, (1.0, -1.0, 0.5, -0.0)):
        state = MotorState(MotorParams(max_velocity=limit), gain=gain)
        state.set_velocity(command)
        v = command * gain
        expected = max(-limit, min(limit, v))
        assert _bits(state.target_velocity) == _bits(expected), (limit, command, gain)
        assert state.target_position == math.inf and not state.torque_mode


def test_torque_clamp_picks_what_min_and_max_pick() -> None:
    for available, most, command, gain in itertools.product(LIMITS, LIMITS, SPECIAL, (1.0, -1.0, -0.0)):
        state = MotorState(MotorParams(max_torque=most), available_torque=available, gain=gain)
        state.set_torque(command)
        limit = min(available, most)
        expected = max(-limit, min(limit, command * gain))
        assert _bits(state.torque) == _bits(expected), (available, most, command, gain)
        assert state.torque_mode
