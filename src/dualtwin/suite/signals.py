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


class _Signal(FrozenModel):
    """A suite input signal: a strict, frozen document."""


class Constant(_Signal):
    kind: Literal["constant"]
    value: float

    def __call__(self, t: float) -> float:
        return self.value


class Step(_Signal):
    """``before`` until ``at_s``, then ``after``."""

    kind: Literal["step"]
    at_s: float = Field(ge=0)
    before: float = 0.0
    after: float

    def __call__(self, t: float) -> float:
        return self.after if t >= self.at_s else self.before


class Impulse(_Signal):
    """``base`` except for ``duration_s`` starting at ``at_s``, where it is ``value``."""

    kind: Literal["impulse"]
    at_s: float = Field(ge=0)
    duration_s: float = Field(gt=0)
    value: float
    base: float = 0.0

    def __call__(self, t: float) -> float:
        return self.value if self.at_s <= t < self.at_s + self.duration_s else self.base


class Ramp(_Signal):
    """Linear from ``start`` at ``start_s`` to ``end`` at ``end_s``; held outside."""

    kind: Literal["ramp"]
    start_s: float = Field(ge=0)
    end_s: float
    start: float = 0.0
    end: float

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
    amplitude: float
    frequency_hz: float = Field(gt=0)
    phase_rad: float = 0.0
    offset: float = 0.0

    def __call__(self, t: float) -> float:
        return self.offset + self.amplitude * math.sin(2 * math.pi * self.frequency_hz * t + self.phase_rad)


class Table(_Signal):
    """Piecewise table of ``[time_s, value]`` points, held (zero-order) or linearly interpolated."""

    kind: Literal["table"]
    points: list[tuple[float, float]] = Field(min_length=1)
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
