"""The scenario-suite format.

The paper's ``test_scenarios.json`` loads unchanged: ``suite_name``, ``global_settings`` (``TIME_STEP`` is the
control period in ms, other keys are robot-specific failure thresholds) and ``scenarios`` whose unknown keys
(``initial_angle``, ``wheel_velocity`` ...) are robot-specific inputs resolved through the robot binding.

Documented extensions on a scenario: ``seed``, ``reset`` (``fresh`` | ``continue``), ``tolerances`` per channel,
and time-varying action signals (see :mod:`dualtwin.suite.signals`) as the value of an action key.
"""

from __future__ import annotations

import math
import re
from typing import Any, Literal

from pydantic import ConfigDict, Field, TypeAdapter, field_validator, model_validator

from dualtwin.models import FrozenModel, Name
from dualtwin.suite.signals import MAX_DURATION_S, MAX_INPUT_MAGNITUDE, Signal

SCENARIO_KEYS = {"name", "duration_s", "type", "description", "seed", "reset", "tolerances"}

# Sane ranges, so a typo cannot start a run that grows memory for hours with no output: a scenario lasts at
# most one simulated day (MAX_DURATION_S, from dualtwin.suite.signals), a suite asks for at most
# MAX_SUITE_PERIODS control periods in all (every period is one row in each log; about 9 simulated hours at the
# paper's 32 ms), and the control period is 0.01 ms-60 s.
MAX_SUITE_PERIODS = 1_000_000
MIN_TIME_STEP_MS, MAX_TIME_STEP_MS = 0.01, 60_000.0
MAX_SEED = 2**32 - 1
# A robot-specific number (initial condition or constant action, SI units) beyond this is a typo or an attack,
# refused without knowing the robot (MAX_INPUT_MAGNITUDE, from dualtwin.suite.signals, which bounds a signal's
# values alike); with the robot, initial conditions get the tighter checks of dualtwin.suite.physical (the
# joint's stops, ±1e4).


class Tolerance(FrozenModel):
    """Per-channel budget: a scenario 'agrees' when every given metric is within its bound."""

    mse: float | None = Field(default=None, ge=0)
    rmse: float | None = Field(default=None, ge=0)
    dtw: float | None = Field(default=None, ge=0)
    dtw_rms: float | None = Field(default=None, ge=0)
    max_abs_error: float | None = Field(default=None, ge=0)
    final_diff: float | None = Field(default=None, ge=0)
    lag_s: float | None = Field(default=None, ge=0)
    crossing_diff_s: float | None = Field(default=None, ge=0)
    score: float | None = Field(default=None, ge=0)


class GlobalSettings(FrozenModel):
    model_config = ConfigDict(extra="allow")
    TIME_STEP: float = Field(default=32.0, ge=MIN_TIME_STEP_MS, le=MAX_TIME_STEP_MS, description="control period, ms")

    @model_validator(mode="after")
    def _extras_are_numbers(self) -> GlobalSettings:
        for key, value in (self.model_extra or {}).items():
            if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
                raise ValueError(f"global setting {key!r} must be a finite number")
        return self

    @property
    def control_period_s(self) -> float:
        return self.TIME_STEP / 1000.0

    @property
    def thresholds(self) -> dict[str, float]:
        """Robot-specific settings (failure thresholds), resolved through the binding."""
        return {k: float(v) for k, v in (self.model_extra or {}).items()}


_signal_adapter: TypeAdapter[Any] = TypeAdapter(Signal)


class Scenario(FrozenModel):
    model_config = ConfigDict(extra="allow")
    name: Name = Field(min_length=1)  # (reports, plots and the terminal show it: one printable line)
    duration_s: float = Field(gt=0, le=MAX_DURATION_S)
    type: str | None = None
    description: str | None = None
    seed: int | None = Field(default=None, ge=0, le=MAX_SEED)
    reset: Literal["fresh", "continue"] = "fresh"
    tolerances: dict[str, Tolerance] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _inputs_are_values_or_signals(self) -> Scenario:
        for key, value in (self.model_extra or {}).items():
            if isinstance(value, bool):
                raise ValueError(f"{key!r} must be a number or a signal object, not a boolean")
            if isinstance(value, int | float):
                if not math.isfinite(value):
                    raise ValueError(f"{key!r} must be finite")
                if abs(value) > MAX_INPUT_MAGNITUDE:
                    raise ValueError(f"{key!r} = {value:g} is beyond ±{MAX_INPUT_MAGNITUDE:g}: no robot-specific "
                                     "input (in SI units) is that large")
            elif isinstance(value, dict):
                _signal_adapter.validate_python(value)
            else:
                raise ValueError(f"{key!r} must be a number or a signal object with a 'kind'")
        return self

    @property
    def inputs(self) -> dict[str, Any]:
        """Robot-specific keys: numbers, or parsed signal objects for time-varying actions."""
        out: dict[str, Any] = {}
        for key, value in (self.model_extra or {}).items():
            out[key] = _signal_adapter.validate_python(value) if isinstance(value, dict) else float(value)
        return out


class Suite(FrozenModel):
    suite_name: Name = Field(min_length=1)
    global_settings: GlobalSettings = Field(default_factory=GlobalSettings)
    scenarios: list[Scenario] = Field(min_length=1)

    @field_validator("scenarios")
    @classmethod
    def _first_is_fresh(cls, scenarios: list[Scenario]) -> list[Scenario]:
        if scenarios and scenarios[0].reset == "continue":
            raise ValueError("the first scenario cannot continue from a previous one; use reset 'fresh'")
        return scenarios

    @model_validator(mode="after")
    def _bounded_total(self) -> Suite:
        periods = sum(math.ceil(s.duration_s / self.global_settings.control_period_s - 1e-9) for s in self.scenarios)
        if periods > MAX_SUITE_PERIODS:
            raise ValueError(f"the scenarios ask for {periods} control periods in all (duration_s / TIME_STEP); "
                             f"at most {MAX_SUITE_PERIODS} are allowed: shorten duration_s or split the suite")
        return self

    def scenario_ids(self) -> list[str]:
        """Unique ids: names may repeat in the published format, so the index prefixes them."""
        return [f"{i:02d}_{_slug(s.name)}" for i, s in enumerate(self.scenarios)]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "scenario"
