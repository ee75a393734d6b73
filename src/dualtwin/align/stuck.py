"""When a fit cannot move: say what the analysis suggests instead.

A fit whose criterion did not fall, or whose every knob ended at a bound, has not found a better model: the
mismatch is of a kind the chosen knobs cannot express. Typical causes are structural and are already visible
in the analysis of the runs before the fit: a sign flip (a wheel or motor driven the other way), one twin
unstable where the other is not, a lag, and, for recordings, a state carried over from the previous scenario
(the import's notes in the reference's manifest). The advice lists those findings with what to try.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from dualtwin.align.analyze import Analysis
from dualtwin.align.writers import KnobFit

#: A criterion that fell by less than this fraction counts as unchanged.
UNCHANGED = 1e-6
#: Findings that no knob of the usual families explains, with what to try.
REMEDY = {
    "sign_inversion": "a sign flip: fit the drive's sign (tie 'motor.*.gain' with bounds -2,2) or correct the "
                      "binding's axis",
    "one_sided_instability": "one twin is unstable: fix the model (time step, contacts) before fitting",
    "lag": "a lag: fit control.delay_periods or a shared time offset (scenario.*.time_offset)",
}


def stuck_advice(before: float, after: float, knobs: Mapping[str, KnobFit], analysis: Analysis,
                 reference: Path, stop_reason: str = "", on_budget: bool = False) -> list[str]:
    """Sentences for the terminal and the report when the fit could not move (empty otherwise).

    A fit that ran out of budget has not shown that its knobs cannot express the mismatch: the first sentence
    then names the budget instead (``on_budget``: the optimiser stopped on it; ``stop_reason``: its words)."""
    unchanged = after >= before * (1.0 - UNCHANGED)
    moved = [k for k in knobs.values() if k.fitted != k.nominal]
    all_at_bounds = bool(moved) and all(k.at_bound for k in moved)
    if not (unchanged or all_at_bounds):
        return []
    why = ("the criterion did not change" if unchanged else "every knob that moved ended at a bound")
    if on_budget:
        out = [f"the fit did not move ({why}: {before:.4g} → {after:.4g}) before its budget ran out "
               f"({stop_reason}): that says nothing yet about the knobs; raise --budget"]
        return out
    out = [f"the fit could not move ({why}: {before:.4g} → {after:.4g}): the chosen knobs cannot express this "
           "mismatch"]
    for finding in analysis.findings:
        remedy = REMEDY.get(finding.kind)
        if remedy is not None:
            out.append(f"analysis suggests {remedy} ({finding.message})")
    out += [f"the reference {note}" for note in carried_over_notes(reference)]
    if len(out) == 1:
        out.append("no structural finding explains it: try other knob families (see dualtwin analyze), wider "
                   "bounds, or nuisance knobs for the reference's initial state")
    return out


def carried_over_notes(run: Path) -> list[str]:
    """Notes of a recorded run's manifest saying a scenario's state may have carried over (no reset)."""
    try:
        manifest = json.loads((run / "manifest.json").read_text())
    except (OSError, ValueError):
        return []
    found: list[str] = []

    def walk(node: Any, where: str) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                walk(value, where or str(key))
        elif isinstance(node, list):
            for item in node:
                walk(item, where)
        elif isinstance(node, str) and "carried over" in node:
            text = f"({where}) {node}" if where else node
            if text not in found:
                found.append(text)

    walk(manifest, "")
    return [f"may carry state over between scenarios: {n}; fit the initial conditions as nuisance knobs "
            "(scenario.<id>.initial_*) or re-import with resets" for n in found[:4]]
