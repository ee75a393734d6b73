"""Identifiability: which knobs a suite can pin down, checked before the fit from sensitivities and after it from
the covariance.

Before the fit, the finite-difference Jacobian of the residuals at the start point (one batch of simulations)
says, from the suite and the knobs alone:

* knobs with no measurable effect (a zero column): nothing in the suite moves them;
* pairs whose effects are nearly parallel (``|cos| > PARALLEL``): the suite sees them as one combination, and
  the fit can trade one for the other along a valley;
* groups along a near-null direction of the column-normalised Jacobian (a three-way trade-off such as an
  initial kick, a time offset and a damping that all set how fast a pole falls) and the rank;
* for each parallel pair, the scenario of the suite whose own residuals separate the pair best, and the
  scenario family that would separate them (excitation advice, by knob property: a free decay for a damping,
  driven runs at several command levels for a gain, ...);
* a suggested tie (``tie``) where knobs of the same property are interchangeable (four wheel gains that only
  move the cart together).

After the fit, the correlation matrix of the fitted knobs (from the interval estimate's covariance) names every
pair with ``|r| > CORRELATED`` in the terminal, the report and ``align_record.json``.

The check's Jacobian costs one simulation per continuous knob, counted in the fit's budget (the least-squares
fit reuses them). It runs when the nominal point and it take at most half the budget
(:func:`check_skipped`); with a smaller budget it would leave the fit nothing, so it is skipped and the
advice says so, with the budget that would run it.

Cosines are of columns in normalised knob units, so they do not depend on the knobs' physical units.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dualtwin.align.knobs import KnobSpec

#: Column cosine above which two knobs' effects count as near-parallel (before the fit).
PARALLEL = 0.95
#: Cosine above which two knobs of the same property count as interchangeable (a tie is suggested).
INTERCHANGEABLE = 0.99
#: Singular value of the column-normalised Jacobian (relative to the largest) below which its direction is a
#: trade-off the suite cannot resolve.
NEAR_NULL = 0.1
#: Correlation above which a pair of fitted knobs is named (after the fit).
CORRELATED = 0.9
#: Scenario families that separate a knob, by the last part of its name.
EXCITES: dict[str, str] = {
    "damping": "a free decay from a displaced start with no drive (its decay rate)",
    "friction": "slow driven motion at two speeds (friction is the speed-independent part)",
    "stiffness": "a free oscillation (its frequency)",
    "mass": "driven steps at two amplitudes (acceleration under a known force)",
    "inertia_scale": "driven steps at two amplitudes (angular acceleration under a known torque)",
    "armature": "fast driven reversals (rotor inertia shows in acceleration)",
    "gain": "driven runs at two or more command levels and both signs",
    "max_velocity": "a driven run commanding more than the velocity limit",
    "max_torque": "a driven run hard enough to saturate the motor",
    "kp": "position steps of several sizes",
    "delay_periods": "a fast command reversal (a square wave)",
    "delay": "a fast command reversal (a square wave)",
    "time_offset": "a driven scenario whose command starts at a known time (a step from rest)",
    "initial_angular_velocity": "a scenario that starts at rest from a held state (no kick to explain)",
    "initial_velocity": "a scenario that starts at rest from a held state (no kick to explain)",
}


def excitation(name: str) -> str:
    """The scenario family that excites knob ``name`` on its own."""
    prop = name.rsplit(".", 1)[-1]
    if prop.startswith("initial_") and prop not in EXCITES:
        return "a scenario that starts from a held, measured state"
    return EXCITES.get(prop, "a scenario that moves this knob's joint or body alone")


def common_glob(names: Sequence[str]) -> str | None:
    """``motor.*.gain`` for ``motor.left.gain`` and ``motor.right.gain``: a glob differing in one dotted part."""
    parts = [n.split(".") for n in names]
    if len({len(p) for p in parts}) != 1:
        return None
    glob = [p[0] if len({q[i] for q in parts}) == 1 else "*" for i, p in enumerate(zip(*parts, strict=True))]
    if glob.count("*") != 1 or glob[-1] == "*":
        return None
    return ".".join(glob)


@dataclass
class Identifiability:
    """What the suite can and cannot pin down (before the fit), as data and as sentences."""

    knobs: list[str]
    rank: int
    unmoved: list[str] = field(default_factory=list)
    parallel: list[dict[str, Any]] = field(default_factory=list)
    tradeoffs: list[list[str]] = field(default_factory=list)
    ties: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    #: Why the check was not run (None: it was).
    not_computed: str | None = None

    def to_dict(self) -> dict[str, Any]:
        if self.not_computed is not None:
            return {"knobs": self.knobs, "not_computed": self.not_computed, "advice": self.advice}
        return {"knobs": self.knobs, "rank": self.rank, "unmoved": self.unmoved, "parallel": self.parallel,
                "tradeoffs": self.tradeoffs, "suggested_ties": self.ties, "advice": self.advice}


def check_skipped(names: Sequence[str], budget: int) -> Identifiability | None:
    """The check's stand-in when the nominal point and the check's Jacobian (one simulation per knob of ``names``,
    the continuous ones) would take more than half of ``budget``; None when the check fits."""
    cost = 1 + len(names)
    if not names or 2 * cost <= budget:
        return None
    why = (f"not computed: the check's {len(names)} simulations (counted in the fit's budget) and the nominal run "
           f"would take more than half of the budget of {budget}; give --budget {2 * cost} or more to run it")
    return Identifiability(list(names), 0, advice=[why], not_computed=why)


def _unit_columns(jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    norms = np.linalg.norm(jac, axis=0)
    live = norms > 1e-12 * max(float(norms.max(initial=0.0)), 1e-300)
    unit = np.zeros_like(jac)
    unit[:, live] = jac[:, live] / norms[live]
    return unit, live


def check(jac: np.ndarray, specs: Sequence[KnobSpec], blocks: Mapping[str, Sequence[tuple[int, int]]] | None = None
          ) -> Identifiability:
    """Identifiability of ``specs`` from the residual Jacobian ``jac`` (columns in unit coordinates).

    ``blocks`` maps each scenario to its stretches of the residual vector, for per-scenario advice.
    """
    names = [s.name for s in specs]
    unit, live = _unit_columns(jac)
    report = Identifiability(names, 0)
    report.unmoved = [n for n, ok in zip(names, live, strict=True) if not ok]
    for n in report.unmoved:
        report.advice.append(f"{n} has no measurable effect on the fitted channels: the suite cannot identify it "
                             f"(add {excitation(n)}, or drop it)")
    idx = [j for j in range(len(names)) if live[j]]
    if not idx:
        return report
    sv = np.linalg.svd(unit[:, idx], compute_uv=True, full_matrices=False)
    singular, vt = sv[1], sv[2]
    report.rank = int(np.sum(singular > 1e-6 * singular[0]))
    cos = unit.T @ unit
    for a_i, a in enumerate(idx):
        for b in idx[a_i + 1:]:
            c = float(cos[a, b])
            if abs(c) <= PARALLEL:
                continue
            entry: dict[str, Any] = {"knobs": [names[a], names[b]], "cosine": c}
            best = _separating_scenario(jac, a, b, blocks) if blocks else None
            if best is not None:
                entry["separated_best_by"] = {"scenario": best[0], "cosine": best[1]}
            report.parallel.append(entry)
            where = (f"; in this suite {best[0]} separates them best (|cos| {abs(best[1]):.2f} there)"
                     if best is not None else "")
            report.advice.append(
                f"{names[a]} and {names[b]} have nearly parallel effects (|cos| {abs(c):.3f}): the suite sees "
                f"one combination of them{where}; to separate them add {excitation(names[a])}"
                + ("" if excitation(names[a]) == excitation(names[b]) else f", or {excitation(names[b])}"))
            glob = common_glob([names[a], names[b]])
            if glob and abs(c) > INTERCHANGEABLE and glob not in report.ties:
                report.ties.append(glob)
    # Trade-offs among three or more knobs: directions the (normalised) suite barely sees.
    for k in range(len(singular)):
        if len(idx) < 2 or singular[k] >= NEAR_NULL * singular[0]:
            continue
        loading = vt[k]
        group = [names[idx[j]] for j in np.argsort(-np.abs(loading)) if abs(loading[j]) > 0.25]
        pairs = [set(e["knobs"]) for e in report.parallel]
        if len(group) >= 2 and group not in report.tradeoffs and set(group) not in pairs:
            report.tradeoffs.append(group)
            report.advice.append(f"trade-off: {', '.join(group)} move together along a direction the suite barely "
                                 f"sees (singular value {singular[k] / singular[0]:.2g} of the largest); the fit "
                                 "can exchange one for the others, so their intervals will be wide or correlated")
    for glob in report.ties:
        members = [n for n in names if fnmatch.fnmatchcase(n, glob)]
        report.advice.append(f"{', '.join(members)} act as one number in this suite: tie them (tie {glob!r}) to "
                             "fit one shared value")
    return report


def _separating_scenario(jac: np.ndarray, a: int, b: int, blocks: Mapping[str, Sequence[tuple[int, int]]]
                         ) -> tuple[str, float] | None:
    """The scenario whose own residuals see knobs ``a`` and ``b`` least alike (both moving it measurably)."""
    best: tuple[str, float] | None = None
    scale = max(float(np.linalg.norm(jac[:, a])), float(np.linalg.norm(jac[:, b])), 1e-300)
    for sid, spans in blocks.items():
        rows = np.concatenate([np.arange(lo, hi) for lo, hi in spans]) if spans else np.zeros(0, int)
        ja, jb = jac[rows, a], jac[rows, b]
        na, nb = float(np.linalg.norm(ja)), float(np.linalg.norm(jb))
        if min(na, nb) < 0.05 * scale:
            continue
        c = float(ja @ jb) / (na * nb)
        if best is None or abs(c) < abs(best[1]):
            best = (sid, c)
    return best


def correlated_pairs(names: Sequence[str], correlation: np.ndarray, threshold: float = CORRELATED
                     ) -> list[dict[str, Any]]:
    """Every pair of fitted knobs with ``|r| > threshold``, most correlated first."""
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            r = float(correlation[i, j])
            if math.isfinite(r) and abs(r) > threshold:
                out.append({"knobs": [names[i], names[j]], "r": r})
    return sorted(out, key=lambda e: -abs(e["r"]))
