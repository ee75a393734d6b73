"""Time-varying action signals, the documented suite extension.

A scenario key bound to an action may hold a number (constant for the whole scenario) or one of these
objects, selected by ``kind``. Every signal is a pure function of simulation time since the scenario
started.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from dualtwin.models import FrozenModel

# The bounds a suite's numbers must keep (`dualtwin.suite.schema` applies them to scenarios; they live here so
# that signals, which the schema imports, use the same ones). A scenario lasts at most one simulated day; a
# robot-specific number (initial condition or action, SI units) beyond MAX_INPUT_MAGNITUDE is a typo or an
# attack. A signal's values and times keep the same bounds as a constant's, and its frequency stays far below
# anything a control period can sample, so 2*pi*f*t stays finite (math.sin(inf) raises) for every t of a run.
MAX_DURATION_S = 86_400.0
MAX_INPUT_MAGNITUDE = 1e6
MAX_FREQUENCY_HZ = 1e6

#: An action value, and a time since the scenario started (a table's may be negative: held before its start).
Value = Annotated[float, Field(ge=-MAX_INPUT_MAGNITUDE, le=MAX_INPUT_MAGNITUDE)]
Time = Annotated[float, Field(ge=0, le=MAX_DURATION_S)]
TableTime = Annotated[float, Field(ge=-MAX_DURATION_S, le=MAX_DURATION_S)]


class _Signal(FrozenModel):
    """A suite input signal: a strict, frozen document."""


class Constant(_Signal):
    kind: Literal["constant"]
    value: Value

    def __call__(self, t: float) -> float:
        return self.value


class Step(_Signal):
    """``before`` until ``at_s``, then ``after``."""

    kind: Literal["step"]
    at_s: Time
    before: Value = 0.0
    after: Value

    def __call__(self, t: float) -> float:
        return self.after if t >= self.at_s else self.before


class Impulse(_Signal):
    """``base`` except for ``duration_s`` starting at ``at_s``, where it is ``value``."""

    kind: Literal["impulse"]
    at_s: Time
    duration_s: Time = Field(gt=0)
    value: Value
    base: Value = 0.0

    def __call__(self, t: float) -> float:
        return self.value if self.at_s <= t < self.at_s + self.duration_s else self.base


class Ramp(_Signal):
    """Linear from ``start`` at ``start_s`` to ``end`` at ``end_s``; held outside."""

    kind: Literal["ramp"]
    start_s: Time
    end_s: Time
    start: Value = 0.0
    end: Value

    @model_validator(mode="after")
    def _ordered(self) -> Ramp:
        if self.end_s <= self.start_s:
            raise ValueError("end_s must be greater than start_s")
        return self

    def __call__(self, t: float) -> float:
        if t <= self.start_s:
            return self.start
        if t >= self.end_s:
            return self.end
        return self.start + (self.end - self.start) * (t - self.start_s) / (self.end_s - self.start_s)


class Sine(_Signal):
    """``offset + amplitude * sin(2π f t + phase)``."""

    kind: Literal["sine"]
    amplitude: Value
    frequency_hz: float = Field(gt=0, le=MAX_FREQUENCY_HZ)
    phase_rad: Value = 0.0
    offset: Value = 0.0

    def __call__(self, t: float) -> float:
        return self.offset + self.amplitude * math.sin(2 * math.pi * self.frequency_hz * t + self.phase_rad)


class Table(_Signal):
    """Piecewise table of ``[time_s, value]`` points, held (zero-order) or linearly interpolated."""

    kind: Literal["table"]
    points: list[tuple[TableTime, Value]] = Field(min_length=1)
    interpolation: Literal["hold", "linear"] = "hold"

    @field_validator("points")
    @classmethod
    def _increasing(cls, points: list[tuple[float, float]]) -> list[tuple[float, float]]:
        times = [p[0] for p in points]
        if any(b <= a for a, b in zip(times, times[1:], strict=False)):
            raise ValueError("table times must be strictly increasing")
        return points

    def __call__(self, t: float) -> float:
        points = self.points
        if t <= points[0][0]:
            return points[0][1]
        for (t0, v0), (t1, v1) in zip(points, points[1:], strict=False):
            if t < t1:
                if self.interpolation == "hold":
                    return v0
                return v0 + (v1 - v0) * (t - t0) / (t1 - t0)
        return points[-1][1]


Signal = Annotated[Constant | Step | Impulse | Ramp | Sine | Table, Field(discriminator="kind")]
