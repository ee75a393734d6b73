"""The proposal hook: anything that reads an analysis and suggests knob settings (an LLM later, any function now).

A proposer is ``propose_fn(analysis) -> list[dict[knob, value]]``. Every proposal is checked (selected
knobs only, values within bounds), re-simulated, and kept only if it lowers the training objective below
the nominal twin's. Nothing a proposer says is trusted without that test. The best kept proposal becomes
the starting point of the optimiser, and all outcomes are recorded in ``align_record.json``.

A proposer may also define ``select(specs)``, called first with the knobs it may set (names and bounds), and
``record(outcomes)``, called last with the re-simulation outcomes in proposal order. The LLM proposer
(`dualtwin.align.narrate.LLMProposer`) uses them to tell the LLM its options and to keep its narrative.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from dualtwin.align.knobs import KnobSpec, close_matches

#: What the proposer reads. This module only passes it through, so it is generic here and the analysis module
#: (which calls `try_proposals`) names the concrete type in ``dualtwin.align.analyze.ProposeFn``: propose
#: does not import analyze, and the align package has no import cycle (type-only imports included).
A = TypeVar("A")


@dataclass
class ProposalOutcome:
    """One proposal and what re-simulating it showed."""

    knobs: dict[str, float]
    objective: float | None
    baseline: float
    accepted: bool
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"knobs": self.knobs, "objective": self.objective, "baseline": self.baseline,
                "accepted": self.accepted, "reason": self.reason}


def _invalid(proposal: Mapping[str, Any], specs: Mapping[str, KnobSpec]) -> str | None:
    if not proposal:
        return "empty proposal"
    for name, value in proposal.items():
        if name not in specs:
            near = close_matches(str(name), list(specs))
            return f"knob {name!r} is not being fitted" + (f" (close: {', '.join(near)})" if near else "")
        try:
            number = float(value)
        except (TypeError, ValueError):
            return f"knob {name!r}: value {value!r} is not a number"
        spec = specs[name]
        if not math.isfinite(number) or not spec.lower <= number <= spec.upper:
            return f"knob {name!r}: value {value!r} is outside its bounds [{spec.lower:g}, {spec.upper:g}]"
    return None


def try_proposals(
    propose_fn: Callable[[A], Sequence[Mapping[str, float]]],
    analysis: A,
    specs: Sequence[KnobSpec],
    baseline: float,
    evaluate: Callable[[Sequence[Mapping[str, float]]], list[float]],
) -> list[ProposalOutcome]:
    """Ask ``propose_fn``, re-simulate the valid proposals in one batch, keep those that beat ``baseline``.

    Args:
        propose_fn: The proposer.
        analysis: Analysis of the reference against the nominal target.
        specs: The knobs being fitted (proposals may only set these).
        baseline: Training objective of the nominal target.
        evaluate: Objective of each knob setting (simulates them, e.g. in parallel).
    """
    by_name = {s.name: s for s in specs}
    select = getattr(propose_fn, "select", None)
    if callable(select):
        select(list(specs))
    proposals = [dict(p) for p in propose_fn(analysis)]
    outcomes: list[ProposalOutcome | None] = []
    valid: list[dict[str, float]] = []
    for proposal in proposals:
        reason = _invalid(proposal, by_name)
        if reason is not None:
            outcomes.append(ProposalOutcome({str(k): v for k, v in proposal.items()}, None, baseline, False, reason))
        else:
            valid.append({k: float(v) for k, v in proposal.items()})
            outcomes.append(None)
    values = iter(evaluate(valid) if valid else [])
    settings = iter(valid)
    out: list[ProposalOutcome] = []
    for outcome in outcomes:
        if outcome is not None:
            out.append(outcome)
            continue
        knobs, value = next(settings), next(values)
        better = value < baseline - 1e-12 * max(1.0, abs(baseline))
        reason = (f"objective {baseline:.4g} → {value:.4g}: " + ("kept" if better else "rejected, not lower"))
        out.append(ProposalOutcome(knobs, value, baseline, better, reason))
    record = getattr(propose_fn, "record", None)
    if callable(record):
        record(out)
    return out
