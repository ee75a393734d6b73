"""Alignment: explain why two twins diverge, and fit knobs so they stop.

Typical use::

    from dualtwin.align import align, analyze_runs, write_analysis

    analysis = analyze_runs(Path("runs/webots"), Path("runs/mujoco"), robot="cartpole", twin_b="mujoco")
    write_analysis(analysis, Path("runs/analysis"))
    result = align(Path("runs/webots"), "mujoco", "cartpole", suite, ["joint.*.damping"], Path("runs/align"))

Modules: `knobs` (selection, bounds, the knob table), `simulate` (in-memory suite runs, process/Ray
pools), `objective` (pure objective and residuals), `analyze` (findings, sensitivities), `fit` (CMA-ES /
least squares, checkpoints), `dr` (calibrated randomisation ranges), `patch` (model files), `propose`
(the proposal hook), `report` (before/after HTML), `nuisance` (per-scenario initial conditions and time
offsets fitted next to the physics, never written into the model) and `reference` (what a reference shares
with the suite, its ensemble members).
"""

from __future__ import annotations

from dualtwin.align.analyze import (
    Analysis,
    AnalysisConfig,
    Finding,
    KnobSensitivity,
    analyze_runs,
    print_analysis,
    write_analysis,
)
from dualtwin.align.fit import (
    AlignConfig,
    AlignResult,
    GenerationInfo,
    KnobFit,
    align,
    print_result,
    sysid_status,
)
from dualtwin.align.knobs import KnobSpec, select_knobs
from dualtwin.align.objective import ObjectiveWeights
from dualtwin.align.propose import ProposalOutcome, ProposeFn

__all__ = [
    "AlignConfig",
    "AlignResult",
    "Analysis",
    "AnalysisConfig",
    "Finding",
    "GenerationInfo",
    "KnobFit",
    "KnobSensitivity",
    "KnobSpec",
    "ObjectiveWeights",
    "ProposalOutcome",
    "ProposeFn",
    "align",
    "analyze_runs",
    "print_analysis",
    "print_result",
    "select_knobs",
    "sysid_status",
    "write_analysis",
]
