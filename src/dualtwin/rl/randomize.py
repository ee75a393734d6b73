"""Domain randomisation and aligned-knob application, both through the twin's knob registry.

Ranges file (written by alignment; JSON or YAML)::

    {"knobs": {"joint.pole_hinge.damping":
        {"nominal": 0.0, "fitted": 0.05, "low": 0.04, "high": 0.06, "distribution": "uniform"}}}

``low``/``high`` are knob values (``operation: "abs"``, the default) or factors of the twin's nominal value
(``operation: "scale"``). Every reset draws fresh values and hands them to the env, which applies them with
``twin.set_knobs`` from nominal: a draw never builds on the previous episode's (mjlab #38).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel
from dualtwin.twins.base import Knob


class KnobRange(FrozenModel):
    """How one knob is drawn at each reset."""

    # dr_ranges.json records more per knob (its unit) than sampling needs: kept, not refused.
    model_config = ConfigDict(extra="allow")

    low: float
    high: float
    distribution: Literal["uniform", "log_uniform"] = "uniform"
    operation: Literal["abs", "scale"] = "abs"
    nominal: float | None = None
    fitted: float | None = None
    integer: bool = False

    @model_validator(mode="after")
    def _valid(self) -> KnobRange:
        if self.low > self.high:
            raise ValueError(f"low ({self.low}) must not exceed high ({self.high})")
        if self.distribution == "log_uniform" and self.low <= 0:
            raise ValueError("log_uniform needs low > 0")
        if self.integer and math.ceil(self.low) > math.floor(self.high):
            raise ValueError(f"integer knob: no integer in [{self.low}, {self.high}]")
        return self


class _RangesFile(BaseModel):
    model_config = ConfigDict(extra="allow")

    # At least one: training "with DR" from a file that names no knob would randomise nothing while its run
    # records that it did.
    knobs: dict[str, KnobRange] = Field(min_length=1)


def _read_mapping(source: Path | str | Mapping[str, Any], what: str) -> tuple[dict[str, Any], str]:
    if isinstance(source, Mapping):
        return dict(source), f"<{what} dict>"
    from dualtwin.artifacts import read_json, read_yaml

    path = Path(source)
    # The shared careful readers: a directory, a pipe, binary data, duplicate keys, deep nesting or a huge
    # file is one line naming the file (and the line and column where there is one).
    data = read_json(path, f"{what} file") if path.suffix == ".json" else read_yaml(path, f"{what} file")
    if not isinstance(data, dict):
        raise DualtwinError(f"{path}: a {what} file must hold a mapping")
    return data, str(path)


def load_ranges(source: Path | str | Mapping[str, Any]) -> dict[str, KnobRange]:
    """Read and validate a ranges file (or dict) of the format above."""
    data, origin = _read_mapping(source, "ranges")
    try:
        return dict(_RangesFile.model_validate(data).knobs)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())
        raise DualtwinError(f"{origin}: invalid ranges: {problems}") from None


def load_knob_values(source: Path | str | Mapping[str, Any]) -> dict[str, float]:
    """Aligned knob values from ``{"knobs": {name: {"fitted": v, ...}}}`` or a plain ``{name: value}``."""
    data, origin = _read_mapping(source, "knobs")
    if "schema" in data and not isinstance(data.get("knobs"), Mapping):
        # align's knobs.json (it has a schema): read as a plain mapping, its 'schema' would be the first "knob"
        raise DualtwinError(f"{origin}: 'knobs' must be an object of knob records, got {data.get('knobs')!r}")
    entries = data["knobs"] if isinstance(data.get("knobs"), Mapping) else data
    if not entries:
        # An "aligned" training run from a file that names no knob would train in the nominal twin while its
        # run records the alignment.
        raise DualtwinError(f"{origin}: names no knob (an aligned-knobs file holds at least one fitted knob)")
    values: dict[str, float] = {}
    for name, entry in entries.items():
        if isinstance(entry, Mapping):
            value = entry.get("fitted", entry.get("value"))
        else:
            value = entry
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise DualtwinError(f"{origin}: knob {name!r} needs a finite number (or a 'fitted' entry), "
                                f"got {entry!r}")
        values[str(name)] = float(value)
    return values


def read_aligned(source: Path | str | Mapping[str, Any]) -> dict[str, Any]:
    """An aligned-knobs record: ``values``, the ``twin`` they were fitted for (``None`` if the file does not
    say), and, for a file, its ``file`` path and ``sha256``. Reads ``align``'s ``knobs.json`` or a plain mapping."""
    from dualtwin.artifacts import sha256_file

    values = load_knob_values(source)
    data, _ = _read_mapping(source, "knobs")
    twin = data.get("twin")
    record: dict[str, Any] = {"twin": str(twin) if twin is not None else None, "values": values}
    if not isinstance(source, Mapping):
        record.update(file=str(Path(source).resolve()), sha256=sha256_file(Path(source)))
    return record


def check_aligned_twin(record: Mapping[str, Any], twin: str, env_id: str) -> None:
    """Refuse knobs fitted for another twin: a knob name can exist on both twins with another meaning."""
    if record.get("twin") not in (None, twin):
        where = record.get("file") or "the aligned knobs"
        raise DualtwinError(f"{where}: these knobs were fitted for the {record['twin']} twin, but {env_id} runs "
                            f"the {twin} twin (align with --target {twin}, or train in a {record['twin']} env)")


def _twin_knobs(env: gym.Env[Any, Any]) -> dict[str, Knob]:
    twin = getattr(env.unwrapped, "twin", None)
    if twin is None:
        raise DualtwinError(f"{env.unwrapped!r} is not a dualtwin env (it has no twin)")
    knobs: dict[str, Knob] = twin.knobs()
    return knobs


def check_knob_names(names: list[str], known: dict[str, Knob], origin: str) -> None:
    """Every name is a knob of the twin, else an error listing the knobs it has."""
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise DualtwinError(f"{origin}: the twin has no knobs named {', '.join(unknown)} "
                            f"(it has: {', '.join(sorted(known))})")


def check_ranges(ranges: Mapping[str, KnobRange], known: dict[str, Knob], origin: str) -> None:
    """Every range names a knob of the twin and stays inside the knob's bounds, else an error naming ``origin``."""
    check_knob_names(list(ranges), known, origin)
    for name, r in ranges.items():
        knob = known[name]
        lo, hi = (r.low, r.high) if r.operation == "abs" else (r.low * knob.nominal, r.high * knob.nominal)
        if min(lo, hi) < knob.lower or max(lo, hi) > knob.upper:
            raise DualtwinError(f"{origin}: range of {name!r} [{lo:g}, {hi:g}] leaves the knob's "
                                f"bounds [{knob.lower:g}, {knob.upper:g}]")


def draw_knobs(ranges: Mapping[str, KnobRange], nominal: Mapping[str, float],
               rng: np.random.Generator) -> dict[str, float]:
    """One draw per knob, in sorted-name order so the stream does not depend on file order. Pure."""
    values: dict[str, float] = {}
    for name in sorted(ranges):
        r = ranges[name]
        if r.integer:
            # Every integer in [low, high] equally likely: a uniform float rounded by the twin would give the
            # two end values half the weight of the others (e.g. control.delay_periods in [0, 2]).
            values[name] = float(rng.integers(math.ceil(r.low), math.floor(r.high) + 1))
            continue
        if r.distribution == "log_uniform":
            u = float(np.exp(rng.uniform(np.log(r.low), np.log(r.high))))
        else:
            u = float(rng.uniform(r.low, r.high))
        values[name] = u * nominal[name] if r.operation == "scale" else u
    return values


class DomainRandomization(gym.Wrapper[Any, Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Fresh knob values at every reset, from nominal, logged in ``info["dr"]``.

    Every ``reset(seed=...)`` restarts the draws, as Gymnasium's ``reset`` contract asks (the same seed gives
    the same episode): from this wrapper's own ``seed`` if given, else from the reset's seed, so a seeded env is
    reproducible with or without it. Leave it off evaluation envs.
    """

    def __init__(self, env: gym.Env[Any, Any], ranges: Path | str | Mapping[str, Any], seed: int | None = None
                 ) -> None:
        # Recorded in env.spec, so gym.make(env.spec) rebuilds the wrapped env (Gymnasium's wrappers do the same).
        gym.utils.RecordConstructorArgs.__init__(self, ranges=str(ranges) if isinstance(ranges, Path) else ranges,
                                                 seed=seed)
        super().__init__(env)
        if isinstance(ranges, Mapping) and ranges and all(isinstance(v, KnobRange) for v in ranges.values()):
            self.ranges: dict[str, KnobRange] = dict(ranges)
        else:
            self.ranges = load_ranges(ranges)
        known = _twin_knobs(env)
        check_ranges(self.ranges, known, "domain randomisation")
        self.nominal = {name: known[name].nominal for name in self.ranges}
        self._own_seed = seed
        self._rng = np.random.default_rng(seed)
        self.last_draw: dict[str, float] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Any, dict[str, Any]]:
        if seed is not None:
            # A distinct stream from the env's own (same seed, different spawn key); restarted at every seed.
            self._rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0xD1,))) \
                if self._own_seed is None else np.random.default_rng(self._own_seed)
        values = draw_knobs(self.ranges, self.nominal, self._rng)
        self.last_draw = values
        options = dict(options or {})
        options["knobs"] = {**dict(options.get("knobs") or {}), **values}
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, {**info, "dr": dict(values)}


class FixedKnobs(gym.Wrapper[Any, Any, Any, Any], gym.utils.RecordConstructorArgs):
    """The same knob values (aligned parameters, say) at every reset, from nominal; logged in ``info["knobs"]``."""

    def __init__(self, env: gym.Env[Any, Any], values: Mapping[str, float]) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, values=dict(values))
        super().__init__(env)
        self.values = {k: float(v) for k, v in values.items()}
        known = _twin_knobs(env)
        check_knob_names(list(self.values), known, "aligned knobs")

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Any, dict[str, Any]]:
        options = dict(options or {})
        options["knobs"] = {**dict(options.get("knobs") or {}), **self.values}
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, {**info, "knobs": dict(self.values)}


def apply_knobs(env: gym.Env[Any, Any], knobs_file: Path | str | Mapping[str, Any]) -> FixedKnobs:
    """Wrap ``env`` so every reset applies the aligned knob values in ``knobs_file`` (see :func:`load_knob_values`)."""
    return FixedKnobs(env, load_knob_values(knobs_file))


__all__ = ["DomainRandomization", "FixedKnobs", "KnobRange", "apply_knobs", "check_aligned_twin", "draw_knobs",
           "check_ranges", "load_knob_values", "load_ranges", "read_aligned"]
