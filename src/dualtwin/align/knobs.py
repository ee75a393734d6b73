"""Knob selection: which named twin parameters an alignment varies, in which bounds and on which scale.

Knobs come from ``twin.knobs()`` and are always applied from nominal through ``twin.set_knobs(values)``,
which returns every knob not named to its nominal value, so repeated evaluations never compound.

Knob table. Names are shared by both twins where both have the parameter; ``<j>``, ``<g>``, ``<b>``,
``<m>``, ``<s>`` are joint, geom, body, motor and sensor names (the converter keeps them equal), and
``<p>`` is a Webots contact-material pair ``material1:material2``. "–" means the twin has no such knob yet.

=================================  =========  =====================================  ==========================================
knob                               unit       MuJoCo twin                            Webots twin (ODE)
=================================  =========  =====================================  ==========================================
``joint.<j>.damping``              N·m·s/rad  ``dof_damping``                        JointParameters ``dampingConstant``
``joint.<j>.friction``             N·m        ``dof_frictionloss``                   JointParameters ``staticFriction``
``joint.<j>.armature``             kg·m²      ``dof_armature`` (rotor inertia)       –  (Webots models no rotor inertia)
``joint.<j>.limit_timeconst``      s          ``jnt_solref[0]`` (limit softness)     –  (stops use world ERP/CFM)
``joint.<j>.limit_impedance``      –          ``jnt_solimp`` dmax (limit hardness)   –  (stops use world ERP/CFM)
``body.<b>.mass``                  kg         ``body_mass``, inertia scaled with it  Physics ``mass``
``body.<b>.inertia_scale``         –          factor on ``body_inertia``             –
``body.<b>.com_offset_x|y|z``      m          shift of ``body_ipos``                 –
``motor.<m>.max_torque``           N·m        Webots-motor emulation limit           RotationalMotor ``maxTorque``
``motor.<m>.max_velocity``         rad/s      Webots-motor emulation limit           RotationalMotor ``maxVelocity``
``motor.<m>.gain``                 –          command × gain (sign included)         command × gain (controller side)
``motor.<m>.kp``                   1/s        P of the emulated Webots position PID  –  (``controlPID``, fixed at load)
``control.delay_periods``          periods    commands act k control periods late    –
``physics.substeps``               steps      timestep = control period / k          –  (``basicTimeStep``, fixed at load)
``sensor.<s>.noise``               unit of s  Gaussian σ added in ``sensor()``       –  (sensor ``noise``)
``sensor.<s>.bias``                unit of s  offset added in ``sensor()``           –
``sensor.<s>.delay``               periods    readings k control periods old         –
``sensor.<s>.quantization``        unit of s  Webots' resolution rule (0 = off)      –  (sensor ``resolution``)
contact friction                   –          ``geom.<g>.friction`` (per geom,       ``contact.<p>.friction`` (per material
                                              ``geom_friction[0]``)                  pair, ContactProperties ``coulombFriction``)
contact restitution                –          ``geom.<g>.restitution``: solref       ``contact.<p>.bounce``
                                              damping ratio ζ, e = exp(-ζπ/√(1-ζ²))
contact softness                   s / –      ``geom.<g>.solref_timeconst``          ``contact.<p>.soft_erp``,
                                              (``geom_solref[0]``),                  ``contact.<p>.soft_cfm``
                                              ``geom.<g>.impedance`` (``geom_solimp``
                                              dmax, dmin keeps its ratio)
world softness                     –          –                                      ``world.erp``, ``world.cfm`` (WorldInfo)
``geom.<g>.radius``                m          ``geom_size[0]`` of a cylinder,        –  (a wheel's rolling radius; ODE's soft
                                              sphere or capsule                      contacts let it sink)
``option.impratio``                –          friction/normal impedance ratio        –  (closest: ``forceDependentSlip``)
=================================  =========  =====================================  ==========================================

MuJoCo combines a contact's sliding friction as the *maximum* of its two geoms' values (unless geom
priorities say otherwise). Lowering ``geom.floor.friction`` below the wheels' therefore changes nothing;
fit the wheel geoms' friction, or both. The alignment's identifiability check reports such knobs.

Contact knobs are per geom in MuJoCo and per material pair in Webots, so their names differ between the
twins. That does not matter for alignment, because only the *target* twin's knobs are fitted. For
ODE, a contact spring ``k`` and damper ``c`` with time step ``h`` give ``ERP = hk/(hk+c)`` and
``CFM = 1/(hk+c)``: that is how a MuJoCo time constant and damping ratio map onto soft ERP/CFM.

Knobs whose unit is ``periods`` (or ``steps``) are integer-valued: optimisers see a continuous value that
the twin rounds. Both optimisers first try every integer in their bounds and start from the best; least
squares then holds it while it fits the continuous knobs, CMA-ES moves it in rounded steps. Knobs whose
bounds span a factor of 50 or more above zero (masses, velocity limits, contact time constants) are searched
in log space.

Tied knobs: a glob given to ``tie`` (``motor.*.gain``) turns the selected knobs it matches into one knob named
by the glob, whose single value every member takes. Four wheel gains that the suite can only see as one
number are then fitted as one number, instead of four values fighting along a flat valley. The tied knob's
bounds are the intersection of its members' bounds and its nominal value their mean.
"""

from __future__ import annotations

import difflib
import fnmatch
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from dualtwin.errors import DualtwinError
from dualtwin.twins.base import Knob

#: Units of integer-valued knobs.
INTEGER_UNITS = frozenset({"periods", "steps"})
#: A positive range spanning at least this factor is searched in log space.
LOG_RATIO = 50.0
_GLOB_CHARS = frozenset("*?[")


@dataclass(frozen=True)
class KnobSpec:
    """A selected knob with the bounds an optimiser may use and its search scale."""

    name: str
    nominal: float
    lower: float
    upper: float
    unit: str = ""
    description: str = ""
    scale: Literal["linear", "log"] = "linear"
    integer: bool = False
    #: The knobs that take this knob's value (a tied knob, named by its glob); () for an ordinary knob.
    members: tuple[str, ...] = ()
    #: The members' own nominal values (same order).
    member_nominals: tuple[float, ...] = ()

    def names(self) -> tuple[str, ...]:
        """The twin knobs this knob sets: its members when tied, else itself."""
        return self.members or (self.name,)

    def to_unit(self, value: float) -> float:
        """Map a physical value into ``[0, 1]`` (clipped)."""
        if self.scale == "log":
            u = math.log(max(value, self.lower) / self.lower) / math.log(self.upper / self.lower)
        else:
            u = (value - self.lower) / (self.upper - self.lower)
        return min(1.0, max(0.0, u))

    def from_unit(self, u: float) -> float:
        """Map ``u`` in ``[0, 1]`` (clipped) to a physical value; integer knobs are rounded."""
        u = min(1.0, max(0.0, float(u)))
        if self.scale == "log":
            value = self.lower * (self.upper / self.lower) ** u
        else:
            value = self.lower + u * (self.upper - self.lower)
        if self.integer:
            value = float(round(value))
        return min(self.upper, max(self.lower, value))

    def dvalue_du(self, value: float) -> float:
        """Derivative of the physical value with respect to the unit coordinate at ``value``."""
        if self.scale == "log":
            return value * math.log(self.upper / self.lower)
        return self.upper - self.lower

    def at_bound(self, value: float, rel: float = 1e-3) -> str | None:
        """``"lower"``/``"upper"`` when ``value`` lies within ``rel`` of the range from a bound."""
        u = self.to_unit(value)
        if u <= rel:
            return "lower"
        if u >= 1.0 - rel:
            return "upper"
        return None

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"name": self.name, "nominal": self.nominal, "lower": self.lower,
                                  "upper": self.upper, "unit": self.unit, "scale": self.scale, "integer": self.integer}
        if self.members:
            out["tied"] = list(self.members)
        return out


def _is_glob(pattern: str) -> bool:
    return any(c in _GLOB_CHARS for c in pattern)


def close_matches(name: str, available: Sequence[str], n: int = 8) -> list[str]:
    """Knob names resembling ``name``: difflib's close matches, else those of the same kind and property."""
    names = sorted(available)
    found = difflib.get_close_matches(name, names, n=n, cutoff=0.6)
    if not found:
        kind, _, rest = name.partition(".")
        prop = rest.rsplit(".", 1)[-1] if rest else ""
        found = [k for k in names if k.startswith(kind + ".") and (not prop or k.endswith("." + prop))][:n]
    return found


def unknown_knob_error(name: str, available: Sequence[str], where: str = "") -> DualtwinError:
    """The error for a knob name (or glob) that matches nothing, listing the close matches."""
    matches = close_matches(name, available)
    hint = f"; did you mean: {', '.join(matches)}" if matches else ""
    prefix = f"{where}: " if where else ""
    what = "knob pattern" if _is_glob(name) else "knob"
    return DualtwinError(f"{prefix}{what} {name!r} matches no knob of the twin ({len(available)} knobs){hint}")


def match_knobs(available: Sequence[str], patterns: Sequence[str], where: str = "") -> list[str]:
    """Knob names selected by exact names or fnmatch globs, in pattern order, without duplicates.

    Raises:
        DualtwinError: For a pattern that matches nothing (listing close matches) or no pattern at all.
    """
    if not patterns:
        raise DualtwinError(f"{where + ': ' if where else ''}no knobs selected; give names or globs "
                            "such as 'joint.*.damping' (--knobs), or a mujoco.sysid parameter file (--sysid-params)")
    names = sorted(available)
    out: list[str] = []
    for pattern in patterns:
        hits = [pattern] if pattern in available else fnmatch.filter(names, pattern) if _is_glob(pattern) else []
        if not hits:
            raise unknown_knob_error(pattern, names, where)
        out.extend(h for h in hits if h not in out)
    return out


def _scale_for(lower: float, upper: float, integer: bool) -> Literal["linear", "log"]:
    return "log" if not integer and lower > 0 and upper / lower >= LOG_RATIO else "linear"


def select_knobs(
    available: Mapping[str, Knob],
    patterns: Sequence[str],
    bounds: Mapping[str, tuple[float, float]] | None = None,
    *,
    where: str = "",
) -> list[KnobSpec]:
    """Resolve knob patterns against a twin's registry, with optional bound overrides.

    Args:
        available: ``twin.knobs()``.
        patterns: Exact names or fnmatch globs (``joint.*.damping``).
        bounds: Optional ``(lower, upper)`` per knob name or glob, replacing the twin's bounds.
        where: Prefix for error messages (e.g. the twin name).

    Raises:
        DualtwinError: Unknown knob or pattern (close matches listed), bounds that exclude the nominal
            value, empty ranges, or bound overrides naming no selected knob.
    """
    names = match_knobs(list(available), patterns, where)
    overrides = dict(bounds or {})
    used: set[str] = set()
    specs: list[KnobSpec] = []
    for name in names:
        knob = available[name]
        lower, upper = knob.lower, knob.upper
        for key, (lo, hi) in overrides.items():
            if key == name or (_is_glob(key) and fnmatch.fnmatchcase(name, key)):
                lower, upper = float(lo), float(hi)
                used.add(key)
        if not (math.isfinite(lower) and math.isfinite(upper)) or lower >= upper:
            raise DualtwinError(f"{where + ': ' if where else ''}knob {name!r}: bounds [{lower:g}, {upper:g}] are "
                                "empty or not finite; give a lower bound below the upper one")
        if not lower <= knob.nominal <= upper:
            raise DualtwinError(f"{where + ': ' if where else ''}knob {name!r}: bounds [{lower:g}, {upper:g}] "
                                f"exclude its nominal value {knob.nominal:g}")
        integer = knob.unit in INTEGER_UNITS
        specs.append(KnobSpec(name, float(knob.nominal), float(lower), float(upper), knob.unit,
                              knob.description, _scale_for(lower, upper, integer), integer))
    unused = sorted(set(overrides) - used)
    if unused:
        raise DualtwinError(f"{where + ': ' if where else ''}bounds given for {unused}, which name no selected "
                            f"knob (selected: {', '.join(names)})")
    return specs


def check_values(available: Mapping[str, Knob], values: Mapping[str, float], where: str = "") -> dict[str, float]:
    """Validate a knob-value mapping (names exist, values finite) and return it as plain floats."""
    out: dict[str, float] = {}
    for name, value in values.items():
        if name not in available:
            raise unknown_knob_error(name, list(available), where)
        if not math.isfinite(float(value)):
            raise DualtwinError(f"{where + ': ' if where else ''}knob {name!r}: value {value!r} is not finite")
        out[name] = float(value)
    return out


def values_from_unit(specs: Sequence[KnobSpec], u: Sequence[float]) -> dict[str, float]:
    """Physical knob values for a point of the unit cube (a tied knob's value given to each member)."""
    return {name: spec.from_unit(float(x)) for spec, x in zip(specs, u, strict=True) for name in spec.names()}


def spec_value(spec: KnobSpec, values: Mapping[str, float]) -> float:
    """``spec``'s value in ``values`` (by its name, else the mean of its members given there), else nominal."""
    if spec.name in values:
        return float(values[spec.name])
    given = [float(values[m]) for m in spec.members if m in values]
    return sum(given) / len(given) if given else spec.nominal


def unit_from_values(specs: Sequence[KnobSpec], values: Mapping[str, float]) -> list[float]:
    """Unit-cube point of knob values (nominal for knobs not given)."""
    return [spec.to_unit(spec_value(spec, values)) for spec in specs]


def tie_knobs(specs: Sequence[KnobSpec], patterns: Sequence[str], where: str = "") -> list[KnobSpec]:
    """``specs`` with the knobs each glob of ``patterns`` matches replaced by one tied knob (at the first one's place).

    Raises:
        DualtwinError: A pattern matching fewer than two selected knobs, knobs of different units or kinds
            (integer and continuous), members whose bounds do not overlap, or a knob claimed by two patterns.
    """
    prefix = f"{where}: " if where else ""
    out = list(specs)
    claimed: dict[str, str] = {}
    for pattern in patterns:
        group = [s for s in out if not s.members and (s.name == pattern or fnmatch.fnmatchcase(s.name, pattern))]
        if len(group) < 2:
            taken = [n for n, p in claimed.items() if fnmatch.fnmatchcase(n, pattern)]
            why = f" (already tied by {claimed[taken[0]]!r})" if taken else ""
            raise DualtwinError(f"{prefix}tie {pattern!r} matches {len(group)} of the selected knobs{why}; a tie "
                                f"needs at least two (selected: {', '.join(s.name for s in out)})")
        if len({(s.unit, s.integer) for s in group}) > 1:
            raise DualtwinError(f"{prefix}tie {pattern!r} groups knobs of different units: "
                                + ", ".join(f"{s.name} [{s.unit or '-'}]" for s in group))
        lower, upper = max(s.lower for s in group), min(s.upper for s in group)
        nominal = sum(s.nominal for s in group) / len(group)
        if not lower < upper:
            raise DualtwinError(f"{prefix}tie {pattern!r}: the members' bounds do not overlap "
                                f"([{lower:g}, {upper:g}]); give common bounds with bounds {pattern}=LOW,HIGH")
        nominal = min(upper, max(lower, nominal))
        tied = KnobSpec(pattern, nominal, lower, upper, group[0].unit, f"one value shared by {len(group)} knobs",
                        _scale_for(lower, upper, group[0].integer), group[0].integer,
                        tuple(s.name for s in group), tuple(s.nominal for s in group))
        for s in group:
            claimed[s.name] = pattern
        first = out.index(group[0])
        out = [s for s in out if s not in group]
        out.insert(first, tied)
    return out


def expand_ties(specs: Sequence[KnobSpec]) -> tuple[list[KnobSpec], list[int]]:
    """One spec per twin knob (a tied knob's members take its bounds and scale, keep their own nominal), and for
    each the index of the spec it came from, so unit points, intervals and records map onto the twin's knobs."""
    out: list[KnobSpec] = []
    column: list[int] = []
    for i, spec in enumerate(specs):
        if not spec.members:
            out.append(spec)
            column.append(i)
            continue
        for name, nominal in zip(spec.members, spec.member_nominals or [spec.nominal] * len(spec.members),
                                 strict=True):
            out.append(KnobSpec(name, nominal, spec.lower, spec.upper, spec.unit, f"tied: {spec.name}",
                                spec.scale, spec.integer))
            column.append(i)
    return out, column
