"""The files an alignment writes (``knobs.json``, ``dr_ranges.json``, the patched model, ``align_record.json``),
the result it returns, and its terminal summary. The HTML reports are :mod:`dualtwin.align.report`'s.

Every objective writes the same files through these functions, so a fitted folder reads the same whatever
objective produced it; the prediction objective adds ``"objective": "prediction"`` to ``knobs.json`` and
its error tables to the record.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape

from dualtwin.align.analyze import Analysis
from dualtwin.align.config import AlignConfig
from dualtwin.align.core import Outcome, Uncertainty
from dualtwin.align.dr import dr_document
from dualtwin.align.knobs import KnobSpec, expand_ties
from dualtwin.align.optimize import sysid_status
from dualtwin.align.patch import PatchResult, patch_mjcf, patch_webots
from dualtwin.align.propose import ProposalOutcome
from dualtwin.artifacts import json_safe, package_versions, sha256_file, write_json, write_text
from dualtwin.robots.binding import RobotBinding

ALIGN_SCHEMA = "dualtwin.align/1"
KNOBS_SCHEMA = "dualtwin.knobs/1"
#: Held-out objective this much above its value before fitting counts as overfitting ...
OVERFIT_RATIO = 1.05
#: ... and so does ending this much above its best value during the fit.
OVERFIT_FROM_BEST = 1.25


@dataclass(frozen=True)
class KnobFit:
    """One knob's nominal and fitted value, its 95 % half-width (if known) and bound status."""

    name: str
    unit: str
    nominal: float
    fitted: float
    lower: float
    upper: float
    half_width_95: float | None = None
    at_bound: str | None = None
    #: The 95 % interval (possibly asymmetric; the bounds where the data pin nothing) and the method that gave it.
    interval_95: tuple[float, float] | None = None
    method: str | None = None
    #: The glob this knob is tied by (one value shared with its other members), if any.
    tied: str | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"nominal": self.nominal, "fitted": self.fitted, "lower": self.lower,
                               "upper": self.upper, "unit": self.unit, "half_width_95": self.half_width_95,
                               "at_bound": self.at_bound}
        if self.method is not None:
            out["interval_95"] = list(self.interval_95) if self.interval_95 is not None else None
            out["interval_method"] = self.method
        if self.tied is not None:
            out["tied"] = self.tied
        return out


@dataclass
class AlignResult:
    """What `align` did and where it wrote it."""

    out_dir: Path
    optimizer: str
    knobs: dict[str, KnobFit]
    objective_before: float
    objective_after: float
    holdout_before: float | None
    holdout_after: float | None
    residual_before: float
    residual_after: float
    evaluations: int
    iterations: int
    #: Wall-clock seconds of the whole run. Printed (the terminal summary, ``align --json``) but written into
    #: no file of the run folder: the same seed and inputs give byte-identical folders, and wall time depends
    #: on the machine's load.
    wall_time_s: float
    stop_reason: str
    warnings: list[str] = field(default_factory=list)
    condition_number: float | None = None
    files: dict[str, str] = field(default_factory=dict)
    proposals: list[ProposalOutcome] = field(default_factory=list)
    #: The LLM narrative (labelled as LLM output) when the proposer was an LLM; None otherwise.
    narrative: dict[str, Any] | None = None
    #: Fitted nuisance knobs (per-scenario initial conditions, time offsets): about the reference, not the
    #: model, so never in ``knobs``, ``fitted``, knobs.json, the patched model or the DR ranges.
    nuisance: dict[str, KnobFit] = field(default_factory=dict)
    #: Scenarios and channels of the suite or the reference that only one side has, with why (not fitted).
    left_out: dict[str, dict[str, str]] = field(default_factory=dict)
    #: ``before``: the identifiability check (:mod:`dualtwin.align.identifiability`); ``after``: the correlation
    #: matrix, the pairs with |r| > 0.9 and the noise estimate.
    identifiability: dict[str, Any] = field(default_factory=dict)
    #: When the fit could not move: what the analysis suggests instead (sign flip, carried-over state, ...).
    advice: list[str] = field(default_factory=list)
    #: Scenarios left out of the objective with the user's consent (``AlignConfig.exclude``) -> why.
    excluded: dict[str, str] = field(default_factory=dict)
    #: Each judged scenario against the target's reproducibility floor (:mod:`dualtwin.align.floor_check`).
    floor_check: dict[str, Any] = field(default_factory=dict)

    @property
    def fitted(self) -> dict[str, float]:
        """Fitted physics values, ready for ``twin.set_knobs`` (nuisance knobs excluded)."""
        return {name: k.fitted for name, k in self.knobs.items()}



def fit_records(specs: Sequence[KnobSpec], fitted: Mapping[str, float],
                half_widths: Mapping[str, float | None], unc: Uncertainty | None = None
                ) -> tuple[dict[str, KnobFit], list[str]]:
    """Per-knob fit records (one per member of a tied knob), and a warning for every knob that left its nominal
    value to end at a bound. ``unc`` adds each knob's interval and its method."""
    records: dict[str, KnobFit] = {}
    warnings: list[str] = []
    flat, column = expand_ties(specs)
    for spec, col in zip(flat, column, strict=True):
        source = specs[col].name
        value = fitted[spec.name]
        bound = spec.at_bound(value)
        records[spec.name] = KnobFit(spec.name, spec.unit, spec.nominal, value, spec.lower, spec.upper,
                                     half_widths.get(source), bound,
                                     unc.intervals.get(source) if unc is not None else None,
                                     unc.methods.get(source) if unc is not None else None,
                                     source if specs[col].members else None)
        if bound is not None and value != spec.nominal:
            edge = spec.lower if bound == "lower" else spec.upper
            warnings.append(f"{spec.name} ended at its {bound} bound ({edge:g}): the best value may lie beyond "
                            "it; widen the bounds if that is physical, or suspect a structural mismatch")
    return records, warnings


def overfit_warning(train_before: float, train_after: float, hold_before: float, hold_after: float,
                    hold_best: float) -> str | None:
    """A warning when the training objective fell while the held-out one rose (above its start or its best)."""
    if train_after >= train_before:
        return None
    if hold_after > hold_before * OVERFIT_RATIO or hold_after > hold_best * OVERFIT_FROM_BEST + 1e-12:
        return (f"overfitted: the training criterion fell {train_before:.4g} → {train_after:.4g} while the held-out "
                f"one rose to {hold_after:.4g} (before {hold_before:.4g}, best during the fit {hold_best:.4g}); "
                "fit fewer knobs, add regularization or add scenarios")
    return None



def write_knobs(out_dir: Path, files: dict[str, str], twin: str, robot: str, optimizer: str,
                fitted: Mapping[str, float], fits: Mapping[str, KnobFit], objective: str | None = None) -> None:
    """``knobs.json``: the fitted values (ready for ``set_knobs``) and each knob's record."""
    doc: dict[str, Any] = {"schema": KNOBS_SCHEMA, "twin": twin, "robot": robot, "optimizer": optimizer}
    if objective is not None:
        doc["objective"] = objective
    doc.update({"values": dict(fitted), "knobs": {n: k.to_dict() for n, k in fits.items()}})
    write_json(out_dir / "knobs.json", doc)
    files["knobs"] = "knobs.json"


def write_dr_ranges(out_dir: Path, files: dict[str, str], specs: Sequence[KnobSpec], fitted: Mapping[str, float],
                    ranges: Mapping[str, tuple[float, float]], source: str, min_rel_width: float) -> None:
    """``dr_ranges.json``: calibrated domain-randomisation ranges (:mod:`dualtwin.align.dr`)."""
    write_json(out_dir / "dr_ranges.json", dr_document(specs, fitted, ranges, source, min_rel_width))
    files["dr_ranges"] = "dr_ranges.json"


def write_patched_model(out_dir: Path, files: dict[str, str], binding: RobotBinding, twin: str,
                        fitted: Mapping[str, float], control_period: float | None = None) -> PatchResult:
    """The target's model file with the fitted values, when the twin has a patcher (else only knobs.json)."""
    patch = patch_model(binding, twin, fitted, control_period)
    if patch.text is not None:
        suffix = ".xml" if twin == "mujoco" else ".wbt"
        name = f"{binding.name}_aligned{suffix}"
        write_text(out_dir / name, patch.text)
        files["model"] = name
    return patch


def _condition(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else value


def prediction_record(config: AlignConfig, result: AlignResult, outcome: Outcome, patch: PatchResult,
                      binding: RobotBinding, ref_path: Path, kind: str, specs: Sequence[KnobSpec],
                      table_before: Mapping[str, Any], table_after: Mapping[str, Any], periods: int) -> dict[str, Any]:
    """``align_record.json`` of the prediction objective."""
    return {
        "schema": ALIGN_SCHEMA, "objective": "prediction", "config": config.saved(),
        "seed": config.seed, "versions": package_versions(),
        "inputs": {"reference": {"path": str(ref_path), "sha256": config.reference_sha256, "kind": kind},
                   "binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)},
                   "model": {"path": str(binding.model_path(config.target)),
                             "sha256": sha256_file(binding.model_path(config.target))}},
        "knob_specs": [s.to_dict() for s in specs],
        "result": {"knobs": {n: k.to_dict() for n, k in result.knobs.items()},
                   "objective_before": result.objective_before, "objective_after": result.objective_after,
                   "condition_number": _condition(result.condition_number),
                   "stop_reason": result.stop_reason, "warnings": result.warnings},
        "prediction": {"before": json_safe(table_before), "after": json_safe(table_after)},
        "evaluations": result.evaluations, "simulated_periods": periods, "iterations": result.iterations,
        "trace": outcome.trace,
        "model_patch": {"applied": patch.applied, "not_applied": patch.not_applied, "note": patch.note},
        "sysid": sysid_status(), "files": result.files}


def patch_model(binding: RobotBinding, twin: str, fitted: Mapping[str, float],
                 control_period: float | None = None) -> PatchResult:
    """The patched target model; ``control_period`` (default: the binding's) is the one the knobs were fitted at."""
    if twin == "mujoco":
        section = binding.spec.twins.get("mujoco")
        period = control_period if control_period is not None else binding.spec.control_period_ms / 1000.0
        return patch_mjcf(binding.model_path("mujoco"), fitted, dict(section.aliases) if section else None, period)
    if twin == "webots":
        return patch_webots(binding.model_path("webots"), fitted)
    return PatchResult(None, note=f"no model patcher for twin {twin!r}; knobs.json holds the values")


def trajectory_record(config: AlignConfig, result: AlignResult, outcome: Outcome, patch: PatchResult,
                      binding: RobotBinding, suite_path: Path, ref_dir: Path, kind: str, sim_seed: int,
                      specs: Sequence[KnobSpec], analysis: Analysis) -> dict[str, Any]:
    """``align_record.json`` of the trajectory (and ensemble) objective."""
    inputs: dict[str, Any] = {
        "suite": {"path": str(suite_path), "sha256": sha256_file(suite_path)},
        "binding": {"path": str(binding.path), "sha256": sha256_file(binding.path)},
        "model": {"path": str(binding.model_path(config.target)), "sha256": sha256_file(binding.model_path(config.target))},
        "reference": {"path": str(ref_dir), "kind": kind, "manifest_sha256": sha256_file(ref_dir / "manifest.json")},
    }
    return {
        "schema": ALIGN_SCHEMA,
        "config": config.saved(),
        "seed": config.seed,
        "simulation_seed": sim_seed,
        "versions": package_versions(),
        "inputs": inputs,
        "knob_specs": [s.to_dict() for s in specs],
        "result": {
            "knobs": {n: k.to_dict() for n, k in result.knobs.items()},
            # Per-scenario initial conditions and time offsets: about the reference, not in the aligned model.
            "nuisance": {n: k.to_dict() for n, k in result.nuisance.items()},
            "left_out": result.left_out,
            "objective_before": result.objective_before, "objective_after": result.objective_after,
            "holdout_before": result.holdout_before, "holdout_after": result.holdout_after,
            "residual_norm2_before": result.residual_before, "residual_norm2_after": result.residual_after,
            "condition_number": _condition(result.condition_number),
            "stop_reason": result.stop_reason, "warnings": result.warnings,
            "identifiability": result.identifiability, "advice": result.advice,
            "excluded": result.excluded, "floor_check": result.floor_check,
        },
        "evaluations": result.evaluations,
        "iterations": result.iterations,
        "trace": outcome.trace,
        "findings_before": [f.model_dump(mode="json") for f in analysis.findings],
        "proposals": [p.to_dict() for p in result.proposals],
        **({"llm_narrative": result.narrative} if result.narrative is not None else {}),
        "model_patch": {"applied": patch.applied, "not_applied": patch.not_applied, "note": patch.note},
        "sysid": sysid_status(),
        "files": result.files,
    }


def print_result(result: AlignResult, console: Console) -> None:
    """The fitted knobs, before → after objectives and warnings, for the terminal."""
    console.print(f"{result.optimizer}: {result.stop_reason}; {result.evaluations} evaluations, "
                  f"{result.iterations} iterations, {result.wall_time_s:.1f} s")
    if result.optimizer == "lsq":
        # Least squares minimises the trajectory residual; the DTW/event/endpoint objective is reported too.
        console.print(f"trajectory residual (train, minimised): {result.residual_before:.4g} → "
                      f"[bold]{result.residual_after:.4g}[/]")
    console.print(f"DTW + event-time + endpoint objective (train): {result.objective_before:.4g} → "
                  f"{'[bold]' if result.optimizer == 'cma' else ''}{result.objective_after:.4g}"
                  f"{'[/]' if result.optimizer == 'cma' else ''}")
    if result.holdout_before is not None and result.holdout_after is not None:
        console.print(f"DTW + event-time + endpoint objective (held out): {result.holdout_before:.4g} → "
                      f"{result.holdout_after:.4g}")
    from dualtwin.reporting import Column, print_table

    before = result.identifiability.get("before", {})
    for line in before.get("advice", []):
        console.print(f"[yellow]identifiability (before the fit):[/] {escape(line)}")
    columns = [Column("knob", False), Column("nominal"), Column("fitted"), Column("± 95 %"),
               Column("95 % interval", False), Column("method", False), Column("unit", False), Column("note", False)]

    def knob_rows(knobs: Mapping[str, KnobFit]) -> list[list[str]]:
        return [[k.name, f"{k.nominal:.5g}", f"{k.fitted:.5g}",
                 f"{k.half_width_95:.2g}" if k.half_width_95 is not None else "∞",
                 f"[{k.interval_95[0]:.4g}, {k.interval_95[1]:.4g}]" if k.interval_95 is not None else "–",
                 k.method or "", k.unit,
                 "; ".join(x for x in (f"at {k.at_bound} bound" if k.at_bound else "",
                                       f"tied: {k.tied}" if k.tied else "") if x)] for k in knobs.values()]

    print_table(console, columns, knob_rows(result.knobs))
    if result.nuisance:
        console.print("nuisance knobs (this reference's initial conditions and time offsets; not in the aligned model):")
        print_table(console, columns, knob_rows(result.nuisance))
    for warning in result.warnings:
        console.print(f"[yellow]warning:[/] {escape(warning)}")
    console.print(f"wrote {result.out_dir / result.files.get('report', 'report.html')}")
