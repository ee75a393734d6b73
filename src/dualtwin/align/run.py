"""One entry point: :func:`run_align` fits a twin's knobs as one :class:`~dualtwin.align.config.AlignConfig` says.

The objective (``config.objective``) picks the problem: ``trajectory`` runs the suite on the target twin and
minimises the objective of :mod:`dualtwin.align.objective` over the training scenarios
(:class:`~dualtwin.align.trajectory.TrajectoryProblem`, or with ``ensemble="mean"``
:class:`~dualtwin.align.ensemble.EnsembleProblem`); ``prediction`` fits short-horizon prediction errors
(:mod:`dualtwin.align.prediction`). The optimiser (``config.optimizer``) is one of
:mod:`dualtwin.align.optimize`, the outputs are written by :mod:`dualtwin.align.writers` and
:mod:`dualtwin.align.report`.

Every input is checked before the output folder is touched, so a typo costs nothing; a fresh run needs an
empty folder, and ``resume=True`` continues an interrupted one whose saved config is unchanged.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Literal

from dualtwin.align import nuisance
from dualtwin.align.analyze import ProposeFn, analyze_runs
from dualtwin.align.config import PREDICTION_FIELDS, AlignConfig
from dualtwin.align.core import GenerationInfo, Point, fd_jacobian, residual_norm
from dualtwin.align.dr import ranges_from_intervals, ranges_from_population
from dualtwin.align.ensemble import EnsembleProblem
from dualtwin.align.floor_check import FLOOR_EPS, FLOOR_LIMIT, beyond_floor, check_floors, within_resolution
from dualtwin.align.identifiability import Identifiability, check, check_skipped
from dualtwin.align.intervals import estimate_intervals, intervals_skipped, not_computed
from dualtwin.align.knobs import (
    check_values,
    expand_ties,
    select_knobs,
    tie_knobs,
    unit_from_values,
    values_from_unit,
)
from dualtwin.align.objective import ObjectiveWeights, build_spec, mean_trace
from dualtwin.align.optimize import fit_cma, fit_lsq
from dualtwin.align.propose import ProposalOutcome, try_proposals
from dualtwin.align.reference import check_reference_run, ensemble_members_of, shared_with_reference
from dualtwin.align.report import write_align_report
from dualtwin.align.simulate import (
    Evaluator,
    SimJob,
    Traces,
    check_executor,
    load_member_traces,
    load_traces,
    scenario_logs,
)
from dualtwin.align.stuck import stuck_advice
from dualtwin.align.sysid_io import read_sysid_params, write_sysid_params
from dualtwin.align.trajectory import TrajectoryProblem
from dualtwin.align.writers import (
    AlignResult,
    fit_records,
    overfit_warning,
    trajectory_record,
    write_dr_ranges,
    write_knobs,
    write_patched_model,
)
from dualtwin.artifacts import remove_output_dir, write_json
from dualtwin.divergence.comparison import resolve_thresholds
from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.loader import load_suite, read_json
from dualtwin.suite.runner import SuiteRun, check_against_binding
from dualtwin.twins import TWINS, make_twin
from dualtwin.twins.base import Twin
from dualtwin.twins.io import RobotIO

#: How many times a fit moves to a lower point its intervals' profile found (each move computes them again).
MAX_PROFILE_MOVES = 2


def run_align(config: AlignConfig, out_dir: Path, *, resume: bool = False, propose_fn: ProposeFn | None = None,
              callback: Callable[[GenerationInfo], None] | None = None) -> AlignResult:
    """Fit the target twin's knobs as ``config`` says; write every artifact to ``out_dir``.

    Args:
        config: Every input and setting (see :class:`~dualtwin.align.config.AlignConfig`; ``reference`` is a
            twin name, a run folder, or for ``objective="prediction"`` a trajectory file or its folder).
        out_dir: Output folder (must be empty unless ``resume``).
        resume: Continue an interrupted alignment in ``out_dir`` (its saved config must be the same).
        propose_fn: Optional proposer ``analysis -> [knob values]``; proposals that lower the objective
            seed the search (see :mod:`dualtwin.align.propose`; trajectory objective only).
        callback: Called after every generation/iteration, after the checkpoint is written.

    ``regularization`` λ adds ``λ·f₀·mean((u - u_nominal)²)`` to the training objective (``f₀`` its nominal
    value; likewise as residuals), with ``u`` the normalised knob values: λ = 0.1 means that moving every knob
    across its whole range costs 10 % of the nominal mismatch; 0.05 to 0.5 keeps weakly identified knobs near
    their model values in cross-simulator fits. ``ensemble="mean"`` needs a reference run with ensemble members
    (see :mod:`dualtwin.align.ensemble`).

    Raises:
        DualtwinError: Bad input (unknown knobs, bounds excluding nominal, mismatched reference, ...).
    """
    if config.objective == "prediction":
        unused = [name for name, given in (
            ("holdout", bool(config.holdout)), ("channels", config.channels is not None),
            ("thresholds", config.thresholds is not None), ("weights", config.weights != ObjectiveWeights()),
            ("ensemble", config.ensemble != "off"), ("propose_fn", propose_fn is not None),
            ("intervals", config.intervals != "auto")) if given]
        if unused or config.executor == "ray":
            raise DualtwinError(f"the prediction objective does not take {', '.join(unused) or 'executor ray'}")
        from dualtwin.align.prediction import run_prediction

        return run_prediction(config, Path(out_dir), resume=resume, callback=callback)
    defaults = AlignConfig(reference="", target="", robot="", knobs=[])
    changed = sorted(name for name in PREDICTION_FIELDS - {"objective"}
                     if getattr(config, name) != getattr(defaults, name))
    if changed:
        raise DualtwinError(f"{', '.join(changed)} apply only to the prediction objective")
    return run_trajectory(config, Path(out_dir), resume=resume, propose_fn=propose_fn, callback=callback)


def reference_kind(reference: str | Path) -> Literal["run", "twin"]:
    """``run`` for a run folder (manifest.json), ``twin`` for a twin name."""
    path = Path(reference)
    if (path / "manifest.json").is_file():
        return "run"
    if str(reference) in TWINS:
        return "twin"
    raise DualtwinError(f"reference {str(reference)!r} is neither a run directory (no manifest.json there) nor a "
                        f"twin ({', '.join(sorted(TWINS))})")


def _record_run_knobs(run_dir: Path, knobs: Mapping[str, float]) -> None:
    """Add the knob values a run was made with to its manifest (provenance)."""
    manifest = read_json(run_dir / "manifest.json")
    manifest["knobs"] = dict(knobs)
    write_json(run_dir / "manifest.json", manifest)


def run_suite(suite: Path, twin_name: str, robot: RobotBinding, out: Path, seed: int, twin: Twin,
              knobs: Mapping[str, float], resume: bool, replay: Traces | None = None) -> Path:
    """The suite on ``twin`` with ``knobs`` into ``out`` (replacing only a suite run this alignment wrote).

    ``replay``: every scenario's traces, already simulated with these knobs, suite and seed: written as the
    simulation would write them, not simulated again (None when some scenario cannot be rebuilt)."""
    if out.exists() and not resume:
        remove_output_dir(out, "suite-run")  # only a suite run this alignment wrote, never a foreign folder
    logs = None
    if replay is not None:
        spec = robot.spec
        rebuilt = {sid: scenario_logs(trace, list(spec.ground_truth), list(spec.onboard))
                   for sid, trace in replay.items()}
        logs = {sid: log for sid, log in rebuilt.items() if log is not None} if all(rebuilt.values()) else None
    if logs is None:
        twin.set_knobs(dict(knobs))
    SuiteRun(suite, twin_name, robot, out, seed=seed, twin=twin).run(resume=resume, replay=logs)
    _record_run_knobs(out, knobs)
    return out


def run_trajectory(config: AlignConfig, out_dir: Path, *, resume: bool = False, propose_fn: ProposeFn | None = None,
                   callback: Callable[[GenerationInfo], None] | None = None) -> AlignResult:
    """The trajectory (or ensemble) objective; see :func:`run_align`."""
    t_start = time.perf_counter()
    binding = resolve_robot(config.robot)
    if not config.suite:
        raise DualtwinError("the trajectory objective needs a suite (--scenarios)")
    suite_path = Path(config.suite)
    suite = load_suite(suite_path)
    check_against_binding(suite, suite_path, binding)
    ids = suite.scenario_ids()
    held = list(config.holdout)
    unknown = sorted(set(held) - set(ids))
    if unknown:
        raise DualtwinError(f"holdout names unknown scenarios {unknown}; the suite has {ids}")
    excluded = list(config.exclude)
    unknown = sorted(set(excluded) - set(ids))
    if unknown:
        raise DualtwinError(f"exclude names unknown scenarios {unknown}; the suite has {ids}")
    both = sorted(set(excluded) & set(held))
    if both:
        raise DualtwinError(f"scenarios {both} are both held out and excluded; give each to one of them")
    if not [s for s in ids if s not in held and s not in excluded]:
        raise DualtwinError("every scenario is held out or excluded; nothing is left to fit")
    check_executor(config.executor)
    kind = reference_kind(config.reference)
    if config.reference_kind not in (None, kind):
        raise DualtwinError(f"reference {config.reference!r} is a {kind}, not a {config.reference_kind}")
    if kind == "run" and config.reference_knobs:
        raise DualtwinError("reference_knobs apply only when the reference is a twin, not a recorded run")
    # The saved config names resolved inputs: the reference run and suite as absolute paths, the binding file.
    config = config.model_copy(update={
        "reference": str(Path(config.reference).resolve()) if kind == "run" else config.reference,
        "reference_kind": kind, "robot": str(binding.path), "suite": str(suite_path.resolve())})
    optimizer, thresholds = config.optimizer, config.thresholds

    period = suite.global_settings.control_period_s
    target = make_twin(config.target, binding, period)
    try:
        # Everything checkable is checked before the output folder is touched, so a typo costs nothing.
        channel_info = RobotIO(binding, target).channel_info()
        channel_names = list(channel_info)
        fitted_ids = [s for s in ids if s not in held and s not in excluded]
        left: dict[str, dict[str, str]] = {}
        if kind == "run":
            shared = shared_with_reference(load_traces(Path(config.reference)), ids, channel_names,
                                           Path(config.reference))
            missing_held = [s for s in held if s not in shared.scenarios]
            if missing_held:
                raise DualtwinError(f"holdout names scenarios the reference does not have: {missing_held}")
            fitted_ids = [s for s in shared.scenarios if s not in held and s not in excluded]
            if not fitted_ids:
                raise DualtwinError(f"every scenario the reference has ({shared.scenarios}) is held out; "
                                    "nothing is left to fit")
            if config.channels is not None:
                absent = [c for c in config.channels if c not in shared.channels]
                if absent:
                    raise DualtwinError(f"channels {absent} are not shared by the reference and the robot binding; "
                                        f"shared: {shared.channels}")
            left = shared.left_out
            check_reference_run(Path(config.reference), channel_info, shared.scenarios)
        if thresholds:  # the objective resolves them after the output folder is written: a typo is caught here
            fit_channels = (config.channels if config.channels is not None
                            else shared.channels if kind == "run" else channel_names)
            resolve_thresholds(fit_channels, thresholds)
        members: list[dict[str, float]] = []
        if config.ensemble != "off":
            members = ensemble_members_of(config.reference, kind, fitted_ids + held, binding)
        # Physics knobs of the target twin, and nuisance knobs (initial conditions, time offsets) of the
        # fitted scenarios; `nuisance` explains why the two are kept apart.
        registry = {**target.knobs(), **nuisance.registry(suite, binding, fitted_ids)}
        patterns, bounds = list(config.knobs), dict(config.bounds)
        if config.sysid_params:
            sysid_names, sysid_bounds = read_sysid_params(Path(config.sysid_params))
            # each of the file's names must match a knob, in an error that names the file
            select_knobs(registry, sysid_names, sysid_bounds, where=f"{config.sysid_params}: twin {config.target!r}")
            patterns += [n for n in sysid_names if n not in patterns]
            bounds = {**sysid_bounds, **bounds}  # bounds given to align win over the file's
        specs = select_knobs(registry, patterns, bounds, where=f"twin {config.target!r}")
        specs = tie_knobs(specs, config.tie, where=f"twin {config.target!r}")

        # Output folder: fresh, or the same configuration when resuming.
        config_path = out_dir / "align_config.json"
        if resume and config_path.is_file():
            if read_json(config_path) != config.saved():
                raise DualtwinError(f"{config_path}: cannot resume: the configuration differs from the interrupted run")
        elif out_dir.exists() and any(out_dir.iterdir()):
            raise DualtwinError(f"{out_dir}: output folder is not empty; use resume to continue an alignment, "
                                "or choose another folder")
        write_json(config_path, config.saved())

        # The reference: a recorded run, or a twin run once into out_dir/reference.
        if kind == "run":
            ref_dir = Path(config.reference)
            sim_seed = load_run(ref_dir).seed or 0
        else:
            ref_dir = out_dir / "reference"
            sim_seed = config.seed
            ref_twin = make_twin(config.reference, binding, period)
            try:
                values = check_values(ref_twin.knobs(), config.reference_knobs, f"reference twin {config.reference!r}")
                run_suite(suite_path, config.reference, binding, ref_dir, sim_seed, ref_twin, values, resume)
            finally:
                ref_twin.close()
        reference = load_traces(ref_dir)
        member_traces = load_member_traces(ref_dir) if members else {}
        # The mean is the reference of both ensemble modes' reports (and its scales those of the members' specs).
        reference.update({sid: mean_trace(m) for sid, m in member_traces.items()})
        shared = shared_with_reference(reference, ids, channel_names, ref_dir)
        train_ids = [s for s in shared.scenarios if s not in held and s not in excluded]
        train = build_spec(reference, train_ids, config.channels if config.channels is not None else shared.channels,
                           thresholds=thresholds, weights=config.weights)
        hold = build_spec(reference, held, train.channels, thresholds=thresholds, weights=config.weights) if held else None
        warnings = [f"scenario {s} is unstable in the reference and is not fitted" for s in train.skipped]
        left = shared.left_out
        warnings += [f"left out: {what[:-1]} {name}: {why}" for what, names in left.items() for name, why in names.items()]

        before_dir = run_suite(suite_path, config.target, binding, out_dir / "runs" / "before", sim_seed, target,
                                {}, resume)
        job = SimJob(str(binding.path), config.target, str(suite_path.resolve()), tuple(shared.scenarios), (),
                     sim_seed)
        with Evaluator(config.executor, config.workers, config.ray_address, config.batch) as evaluator:
            problem: TrajectoryProblem
            if members:
                problem = EnsembleProblem(specs, job, train, hold, evaluator, config.budget, config.regularization,
                                          members, "members" if config.ensemble == "members" else "mean", member_traces)
            else:
                problem = TrajectoryProblem(specs, job, train, hold, evaluator, config.budget, config.regularization)
            nominal_u = unit_from_values(specs, {})
            # The nominal twin's run was just written to runs/before: scored from there, not simulated again
            # (an ensemble simulates members, and nuisance knobs change the suite, so those are simulated).
            reuse = not members and problem.values(nominal_u) == {
                s.name: s.nominal for s in expand_ties(specs)[0] if not nuisance.is_nuisance(s.name)}
            before = (problem.remember(nominal_u, load_traces(before_dir, shared.scenarios)) if reuse
                      else problem.run([nominal_u])[0])
            problem.calibrate(before)
            analysis_before = analyze_runs(ref_dir, before_dir, thresholds=thresholds)
            x0, f0 = nominal_u, before.train
            # Identifiability before the fit, from the suite and the knobs alone: one batch of perturbed runs,
            # unless it would take more than half the budget.
            identifiability = (check_skipped([s.name for s in specs if not s.integer], config.budget)
                               or identify(problem, nominal_u, config.fd_step))
            proposals: list[ProposalOutcome] = []
            if propose_fn is not None:
                proposals = try_proposals(propose_fn, analysis_before, specs, before.train, problem.run_values)
                accepted = [p for p in proposals if p.accepted and p.objective is not None]
                if accepted:
                    best = min(accepted, key=lambda p: p.objective or math.inf)
                    x0, f0 = unit_from_values(specs, best.knobs), float(best.objective or before.train)
            fit = fit_cma if optimizer == "cma" else fit_lsq
            outcome = fit(problem, config, out_dir, x0, f0, resume, callback)
            after = problem.run([outcome.u])[0]

            def criterion(p: Point) -> float:
                # Each optimiser is judged by what it minimises: the objective, or the residual norm.
                return p.train if optimizer == "cma" else residual_norm(p)

            if criterion(after) > criterion(before):
                # Never hand back something worse than where we started.
                outcome.u, after = nominal_u, before
                warnings.append("no knob setting beat the nominal twin; the fitted values are the nominal ones")
            # The budget is the fit's: the interval checks after it are counted apart.
            fit_evaluations = problem.evaluations
            # Intervals cost 6 to 190 simulations per knob: with a budget too small for that, not computed.
            skipped = intervals_skipped(config.intervals, config.budget, sum(not s.integer for s in specs))
            uncertainty = (not_computed(specs, skipped) if skipped is not None
                           else estimate_intervals(problem, outcome.u, config.fd_step))
            # A profile point below the fit (by more than the criterion's jitter) shows the least-squares fit had
            # not converged: the fit moves there and its intervals are computed again, at most twice.
            moves: list[str] = []
            while optimizer == "lsq" and uncertainty.better is not None and len(moves) < MAX_PROFILE_MOVES:
                moves.append(f"{residual_norm(after):.4g} -> {uncertainty.better['criterion']:.4g}")
                outcome.u = list(uncertainty.better["u"])
                after = problem.run([outcome.u])[0]
                uncertainty = estimate_intervals(problem, outcome.u, config.fd_step)
            if moves:
                outcome.stop_reason += (f"; then moved to a lower point the intervals' profile found (residual norm "
                                        f"{', '.join(moves)}): the fit had not converged")
            fitted, fitted_nuisance = nuisance.split(values_from_unit(specs, outcome.u))
            # The after run uses the fitted initial conditions too, so it shows what the fit matched; time
            # offsets only move the objective's time axis and are not in the run.
            after_suite = suite_path
            if any(nuisance.parse(n, ids)[1] != nuisance.TIME_OFFSET for n in fitted_nuisance):
                after_suite = out_dir / "suite_with_nuisance.json"
                write_json(after_suite, nuisance.apply_to_document(read_json(suite_path), ids, fitted_nuisance))
            # The fitted point's suite was simulated during the fit (or read from runs/before): its kept traces
            # are written, not simulated again, when they are the whole suite as run_suite would run it (no
            # ensemble members, no nuisance knobs moving the suite or its time axis).
            kept = problem.traces_at(outcome.u) if not members and not fitted_nuisance else None
            replay = kept if kept is not None and set(ids) <= set(kept) else None
            after_dir = run_suite(after_suite, config.target, binding, out_dir / "runs" / "after", sim_seed, target,
                                  fitted, False, replay)
            # Each fitted (and excluded) scenario against the target's reproducibility floor at the fit: what the
            # twins cannot share is named, never dropped without consent (not counted in the budget). Without
            # nuisance knobs the after run is the fit's run, so only the shifted members are simulated.
            judged = [s for s in shared.scenarios if s not in held]
            floors = check_floors(evaluator, job, problem.values(outcome.u), reference, judged, train.channels,
                                  binding, after=None if fitted_nuisance else load_traces(after_dir, judged))
        warnings += uncertainty.warnings
        beyond = beyond_floor(floors)
        warnings += [f"scenario {sid} is beyond its reproducibility floor after the fit ({why}); it stays in the "
                     f"objective: to fit without it, exclude it with --exclude {sid} (AlignConfig.exclude)"
                     for sid, why in beyond.items() if sid not in excluded]
        unseen = within_resolution(floors)
        warnings += [f"scenario {sid} is more than {FLOOR_LIMIT:g}x its reproducibility floor after the fit, by a "
                     f"difference within its channels' resolution ({why}); it stays in the objective"
                     for sid, why in unseen.items() if sid not in excluded]
        excluded_why = {sid: "excluded by the user" + (f"; measured after the fit: {beyond[sid]}" if sid in beyond
                                                        else "") for sid in excluded}
        warnings += [f"scenario {sid} {why}" for sid, why in excluded_why.items()]
        warnings += [f"after the fit, {a} and {b} are correlated (r = {e['r']:+.3f}): the data fix a combination of "
                     "them, not each" for e in uncertainty.correlated for a, b in [e["knobs"]]]
        all_fits, bound_warnings = fit_records(specs, {**fitted, **fitted_nuisance}, uncertainty.half_widths,
                                               uncertainty)
        knob_fits = {n: k for n, k in all_fits.items() if not nuisance.is_nuisance(n)}
        nuisance_fits = {n: k for n, k in all_fits.items() if nuisance.is_nuisance(n)}
        warnings += bound_warnings
        if hold is not None and before.holdout is not None and after.holdout is not None:
            best_seen = min((t["holdout_of_best"] for t in outcome.trace if t.get("holdout_of_best") is not None),
                            default=after.holdout)
            overfit = overfit_warning(criterion(before), criterion(after), before.holdout, after.holdout, best_seen)
            if overfit:
                warnings.append(overfit)

        analysis_after = analyze_runs(ref_dir, after_dir, thresholds=thresholds)
        advice = stuck_advice(criterion(before), criterion(after), knob_fits, analysis_before, ref_dir,
                              outcome.stop_reason, outcome.ended_on_budget)
        warnings += advice
        if not advice and outcome.ended_on_budget:
            # Issue 24: a fit cut off by its budget is not shown to be at the minimum; intervals around an
            # unfinished point can be too narrow (measured in the coverage study), so say so.
            warnings.append(f"the fit ended on its budget ({outcome.stop_reason}), not by a convergence rule: "
                            "the fitted values may not be the minimum and intervals around them may not cover; "
                            "raise --budget to let it converge")
    finally:
        target.close()

    files: dict[str, str] = {"config": "align_config.json", "reference": str(ref_dir),
                             "before": "runs/before", "after": "runs/after"}
    write_knobs(out_dir, files, config.target, binding.name, optimizer, fitted, knob_fits)

    flat, column = expand_ties(specs)
    if optimizer == "cma" and outcome.population:
        population = [([u[c] for c in column], f) for u, f in outcome.population]
        ranges = ranges_from_population(flat, population, config.dr_top_fraction)
        source = "cma-population"
    else:
        flat_half = {s.name: uncertainty.half_widths.get(specs[c].name) for s, c in zip(flat, column, strict=True)}
        ranges = ranges_from_intervals([s for s in flat if not nuisance.is_nuisance(s.name)], fitted, flat_half)
        source = "lsq-interval" if optimizer == "lsq" else "jacobian-interval"
        if skipped is not None:
            source = "bounds (intervals not computed)"
    physics_specs = [s for s in flat if not nuisance.is_nuisance(s.name)]
    ranges = {k: v for k, v in ranges.items() if not nuisance.is_nuisance(k)}
    write_dr_ranges(out_dir, files, physics_specs, fitted, ranges, source, config.dr_min_rel_width)
    patch = write_patched_model(out_dir, files, binding, config.target, fitted, period)
    write_sysid_params(out_dir, files, knob_fits)
    result = AlignResult(
        out_dir=out_dir, optimizer=optimizer, knobs=knob_fits, objective_before=before.train,
        objective_after=after.train, holdout_before=before.holdout, holdout_after=after.holdout,
        residual_before=float(before.residual @ before.residual), residual_after=float(after.residual @ after.residual),
        evaluations=fit_evaluations, iterations=outcome.iterations, wall_time_s=0.0,
        stop_reason=outcome.stop_reason, warnings=warnings, condition_number=uncertainty.condition,
        files=files, proposals=proposals, nuisance=nuisance_fits, left_out=left,
        identifiability={"before": identifiability.to_dict(), "after": {
            "correlation": uncertainty.correlation, "correlated": uncertainty.correlated,
            "noise": uncertainty.noise, **({"not_computed": skipped} if skipped is not None else {})}},
        advice=advice, excluded=excluded_why,
        floor_check={"eps": FLOOR_EPS, "limit": FLOOR_LIMIT, "beyond": beyond, "within_resolution": unseen,
                     "rows": [r.to_dict() for r in floors]})
    narrative = getattr(propose_fn, "narrative", None)
    if narrative is not None:
        result.narrative = narrative.to_dict()

    files["report"] = write_align_report(out_dir, result, ref_dir, before_dir, after_dir, analysis_before,
                                         analysis_after, train_ids, held, thresholds).name
    record = trajectory_record(config, result, outcome, patch, binding, suite_path, ref_dir, kind, sim_seed, specs,
                     analysis_before)
    write_json(out_dir / "align_record.json", record)
    files["record"] = "align_record.json"
    result.wall_time_s = time.perf_counter() - t_start  # printed only: no file of the run folder holds it
    return result


def identify(problem: TrajectoryProblem, u: list[float], step: float) -> Identifiability:
    """The identifiability check at ``u`` (continuous knobs), with each scenario's stretch of the residuals."""
    cont = [i for i, spec in enumerate(problem.specs) if not spec.integer]
    jac, _ = fd_jacobian(problem, u, step, cont)
    blocks: dict[str, list[tuple[int, int]]] = {}
    for b in problem.residual_blocks():
        blocks.setdefault(b.scenario, []).append((b.start, b.stop))
    return check(jac, [problem.specs[i] for i in cont], blocks)
