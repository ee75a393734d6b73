"""Alignment: explain why two twins diverge, and fit knobs so they stop.

Typical use::

    from dualtwin.align import AlignConfig, analyze_runs, run_align, write_analysis

    analysis = analyze_runs(Path("runs/webots"), Path("runs/mujoco"), robot="cartpole", twin_b="mujoco")
    write_analysis(analysis, Path("runs/analysis"))
    config = AlignConfig(reference="runs/webots", target="mujoco", robot="cartpole", suite="suite.json",
                         knobs=["joint.*.damping"], optimizer="lsq")
    result = run_align(config, Path("runs/align"))

A small library in the spirit of ``mujoco.sysid``, in layers:

* the field list and the entry point: `config` (:class:`AlignConfig`, the only list of an alignment's
  inputs and settings; the CLI derives its options from it) and `run` (:func:`run_align`);
* the optimiser core: `core` (the :class:`Problem` protocol and :class:`CachedProblem` base, evaluated
  points, uncertainty and intervals) and `optimize` (CMA-ES, least squares, checkpoints and resume);
* objectives as peers, each a problem: `trajectory` (suite runs against the reference), `ensemble` (the
  mean of an ensemble reference's members) and `prediction` (short-horizon prediction errors);
* writers: `writers` (knobs.json, dr_ranges.json, the patched model, align_record.json, the terminal
  summary) and `report` (the HTML reports);
* the pieces they use: `knobs` (selection, bounds, the knob table), `simulate` (in-memory suite runs,
  process/Ray pools), `objective` (pure objective terms and residuals), `analyze` (findings,
  sensitivities; `analysis_report` writes them), `dr` (calibrated randomisation ranges), `patch` (model files), `propose` and `narrate`
  (the proposal hook, the LLM narrative), `nuisance` (per-scenario initial conditions and time offsets
  fitted next to the physics, never written into the model) and `reference` (what a reference shares with
  the suite, its ensemble members), `sysid_io` (``mujoco.sysid`` parameter descriptions in, fitted knobs
  out in its format).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualtwin.align.analysis_report import print_analysis, write_analysis
    from dualtwin.align.analyze import (
        Analysis,
        AnalysisConfig,
        Finding,
        KnobSensitivity,
        ProposeFn,
        analyze_runs,
    )
    from dualtwin.align.config import AlignConfig
    from dualtwin.align.core import (
        CachedProblem,
        Evaluation,
        GenerationInfo,
        Outcome,
        Point,
        Problem,
        Uncertainty,
        estimate_uncertainty,
        interval_estimate,
    )
    from dualtwin.align.knobs import KnobSpec, select_knobs
    from dualtwin.align.optimize import fit_cma, fit_lsq, sysid_status
    from dualtwin.align.propose import ProposalOutcome
    from dualtwin.align.run import run_align
    from dualtwin.align.sysid_io import read_sysid_params, sysid_knobs, to_parameter_dict
    from dualtwin.align.weights import ObjectiveWeights
    from dualtwin.align.writers import AlignResult, KnobFit, print_result

# Where each public name lives. Imported on first use (PEP 562), so importing one light module of the package
# (the CLI reads AlignConfig to derive its options) does not import the optimiser, SciPy and the plots.
_HOME: dict[str, str] = {
    "print_analysis": "dualtwin.align.analysis_report",
    "write_analysis": "dualtwin.align.analysis_report",
    "Analysis": "dualtwin.align.analyze",
    "AnalysisConfig": "dualtwin.align.analyze",
    "Finding": "dualtwin.align.analyze",
    "KnobSensitivity": "dualtwin.align.analyze",
    "ProposeFn": "dualtwin.align.analyze",
    "analyze_runs": "dualtwin.align.analyze",
    "AlignConfig": "dualtwin.align.config",
    "CachedProblem": "dualtwin.align.core",
    "Evaluation": "dualtwin.align.core",
    "GenerationInfo": "dualtwin.align.core",
    "Outcome": "dualtwin.align.core",
    "Point": "dualtwin.align.core",
    "Problem": "dualtwin.align.core",
    "Uncertainty": "dualtwin.align.core",
    "estimate_uncertainty": "dualtwin.align.core",
    "interval_estimate": "dualtwin.align.core",
    "KnobSpec": "dualtwin.align.knobs",
    "select_knobs": "dualtwin.align.knobs",
    "ObjectiveWeights": "dualtwin.align.weights",
    "fit_cma": "dualtwin.align.optimize",
    "fit_lsq": "dualtwin.align.optimize",
    "sysid_status": "dualtwin.align.optimize",
    "ProposalOutcome": "dualtwin.align.propose",
    "run_align": "dualtwin.align.run",
    "read_sysid_params": "dualtwin.align.sysid_io",
    "sysid_knobs": "dualtwin.align.sysid_io",
    "to_parameter_dict": "dualtwin.align.sysid_io",
    "AlignResult": "dualtwin.align.writers",
    "KnobFit": "dualtwin.align.writers",
    "print_result": "dualtwin.align.writers",
}


def __getattr__(name: str) -> Any:
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(home), name)


__all__ = [
    "AlignConfig",
    "AlignResult",
    "Analysis",
    "AnalysisConfig",
    "CachedProblem",
    "Evaluation",
    "Finding",
    "GenerationInfo",
    "KnobFit",
    "KnobSensitivity",
    "KnobSpec",
    "ObjectiveWeights",
    "Outcome",
    "Point",
    "Problem",
    "ProposalOutcome",
    "ProposeFn",
    "Uncertainty",
    "analyze_runs",
    "estimate_uncertainty",
    "fit_cma",
    "fit_lsq",
    "interval_estimate",
    "print_analysis",
    "print_result",
    "read_sysid_params",
    "run_align",
    "select_knobs",
    "sysid_knobs",
    "sysid_status",
    "to_parameter_dict",
    "write_analysis",
]
