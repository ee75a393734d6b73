"""`AlignConfig`: the one field list of an alignment.

Every input and setting of an alignment is a field here, and nowhere else: :func:`dualtwin.align.run_align`
takes it, the ``dualtwin align`` command derives its options from it (field descriptions become ``--help``,
``Literal`` fields listed choices, list and mapping fields repeatable options), and it is saved next to the
artifacts as ``align_config.json`` (a resumed run requires it unchanged).

Decisions:

* Fields marked ``derived`` (``reference_kind``, ``reference_sha256``) are filled in by ``run_align`` from the
  inputs (is the reference a run or a twin, the reference file's hash); a user leaves them unset, and the
  CLI offers no option for them.
* The saved file keeps the format it had before this model was the one field list: the trajectory
  objective's file does not list the prediction objective's fields (``objective``, ``horizons``, ``stride``,
  ``scales``, ``reference_sha256``), so folders written before stay resumable and outputs stay byte-identical.
  :meth:`AlignConfig.saved` is that document, and :meth:`AlignConfig.digest` (the checkpoint's config hash)
  hashes the same JSON.
"""

from __future__ import annotations

import hashlib
import json
from typing import Annotated, Any, Literal

from pydantic import Field

from dualtwin.align.weights import ObjectiveWeights
from dualtwin.models import FrozenModel
from dualtwin.parallel import ExecutorKind

Optimizer = Literal["cma", "lsq"]
Objective = Literal["trajectory", "prediction"]
GlobalSearch = Literal["multistart", "off"]
#: A crossing threshold is a level the channel's magnitude crosses (divergence.metrics.Threshold, mode 'abs'):
#: zero or below is refused here with the other options, not as Threshold's ValueError inside the objective.
CrossingThreshold = Annotated[float, Field(gt=0)]
Intervals = Literal["auto", "profile", "off"]
#: Fields added after folders were written without them: left out of the saved config while at their default,
#: so those folders stay resumable and a run that does not use them writes the same bytes as before.
LATER_FIELDS = frozenset({"global_search", "starts", "tie", "sysid_params", "batch", "exclude", "intervals"})
#: Horizons of the prediction objective: 1 and 5 periods stay smooth in the knobs; 25 periods already cross
#: impacts (a pole landing on its stop) and make the residual as rough as an open-loop one.
OBJECTIVE_HORIZONS = (1, 5)
#: Fields only the prediction objective uses (absent from the trajectory objective's saved config).
PREDICTION_FIELDS = frozenset({"objective", "horizons", "stride", "scales", "reference_sha256"})


#: Marks a field that ``run_align`` fills in from the inputs.
DERIVED: dict[str, Any] = {"derived": True}


class AlignConfig(FrozenModel):
    """Every input and setting of an alignment (saved as ``align_config.json``; resume requires it unchanged)."""

    reference: str = Field(description="the reference twin, run once (with the reference knobs); the library "
                           "also takes a run folder (the CLI's --reference-run) and, for the prediction objective, "
                           "a trajectories.npz file or its folder")
    reference_kind: Literal["run", "twin"] | None = Field(
        default=None, description="whether the reference is a recorded run or a twin (set from reference)",
        json_schema_extra=DERIVED)
    reference_knobs: dict[str, float] = Field(default_factory=dict,
                                              description="knob values of a reference twin (NAME=VALUE)")
    target: str = Field(description="twin whose knobs are fitted")
    robot: str = Field(description="bundled robot name or binding file")
    suite: str = Field(default="", description="suite JSON file", json_schema_extra={"cli": "scenarios", "path": True})
    knobs: list[str] = Field(default_factory=list, description="knob names or globs of the target twin (at least "
                             "one, here or in --sysid-params)")
    bounds: dict[str, tuple[float, float]] = Field(default_factory=dict,
                                                   description="(lower, upper) per knob name or glob "
                                                   "(NAME=LOWER,UPPER)")
    channels: list[str] | None = Field(default=None, description="channels to fit (default: every shared one)")
    holdout: list[str] = Field(default_factory=list, description="scenario ids held out for validation")
    exclude: list[str] = Field(default_factory=list, description="scenario ids left out of the objective with "
                               "your consent (neither fitted nor held out), e.g. one the fit names as beyond its "
                               "reproducibility floor; the record and report say what was excluded and why")
    thresholds: dict[str, CrossingThreshold] | None = Field(default=None, description="crossing threshold per channel "
                                                "(CHANNEL=VALUE; default 0.99 rad on *_angle_rad)")
    optimizer: Optimizer = Field(default="cma", description="CMA-ES or least squares")
    seed: int = Field(default=0, description="optimiser seed (simulations use the reference run's seed)")
    budget: int = Field(default=600, ge=2, description="maximum number of suite simulations")
    popsize: int | None = Field(default=None, ge=2, description="CMA population size (default 4 + 3 ln n)")
    sigma0: float = Field(default=0.25, gt=0, le=1, description="CMA initial step, in normalised units")
    tolfun: float = Field(default=1e-9, ge=0, description="CMA objective tolerance")
    tolx: float = Field(default=1e-4, ge=0, description="CMA step-size tolerance, normalised units")
    patience: int | None = Field(default=None, ge=1,
                                 description="CMA generations without improvement before stopping (max(15, 3n))")
    fd_step: float = Field(default=0.03, gt=0, lt=0.5, description="finite-difference step, normalised units")
    intervals: Intervals = Field(
        default="auto", description="95 % intervals after the fit: profile (the Jacobian with effective samples, "
        "checked for roughness and profiled where needed: 6 to 190 simulations per knob, not counted in the "
        "budget), off (not computed, and the outputs say so), or auto: profile when the budget is at least 6 "
        "simulations per knob plus one, off below that")
    lsq_max_iter: int = Field(default=50, ge=1, description="least-squares iterations per start")
    lsq_restarts: int = Field(default=3, ge=0, description="restarts from a better neighbour after a stall")
    global_search: GlobalSearch = Field(
        default="multistart", description="least squares: find the basin first (a Sobol screen of the knob box, "
        "then polish the best distinct starts) or polish from the start point only (off)")
    starts: int = Field(default=0, ge=0, description="points of the basin screen (0: max(8, 4 per knob), at most "
                        "a quarter of the budget)")
    tie: list[str] = Field(default_factory=list, description="globs of knobs fitted as one shared value (e.g. "
                           "'motor.*.gain')")
    sysid_params: str = Field(default="", description="a mujoco.sysid parameter file (YAML) whose parameters, "
                              "named as knobs, add to --knobs with their bounds", json_schema_extra={"path": True})
    executor: ExecutorKind = Field(default="process", description="where candidates are simulated")
    workers: int = Field(default=2, ge=1,
                         description="process-pool size, or the threads of the MuJoCo batch (--batch threads)")
    batch: Literal["auto", "threads", "off"] = Field(
        default="auto", description="auto: a MuJoCo target's candidates (populations, Jacobians) run as "
        "mujoco.batch calls, one single-thread batch per pool worker (in this process with --executor serial), "
        "bit-identical to the executor; threads: one batch in this process on WORKERS threads; off: one at a "
        "time on the executor (Webots targets and --executor ray always are)")
    ray_address: str | None = Field(default=None, description="Ray cluster address, with --executor ray")
    weights: ObjectiveWeights = Field(default_factory=ObjectiveWeights,
                                      description="objective weights (TERM=VALUE: dtw, event, endpoint, rmse, "
                                      "trajectory, robust_delta)")
    regularization: float = Field(default=0.0, ge=0, description="pull toward nominal, relative to the nominal mismatch")
    dr_top_fraction: float = Field(default=0.25, gt=0, le=1,
                                   description="share of the last CMA populations that sets the DR ranges")
    dr_generations: int = Field(default=3, ge=1, description="CMA generations that set the DR ranges")
    dr_min_rel_width: float = Field(default=0.02, ge=0, description="narrowest DR range, relative to the value")
    ensemble: Literal["off", "mean", "members"] = Field(
        default="off", description="mean: fit the ensemble mean of the reference run's members, the target "
        "simulated with the same initial-condition shifts; members: fit each member against the target run "
        "with its shift, residuals stacked")
    objective: Objective = Field(default="trajectory", description="trajectory (suite runs) or prediction (short "
                                 "horizons from synchronised start states)")
    horizons: list[int] = Field(default_factory=lambda: list(OBJECTIVE_HORIZONS),
                                description="prediction horizons in control periods")
    stride: int = Field(default=5, ge=1, description="a prediction start every STRIDE periods")
    scales: dict[str, float] = Field(default_factory=dict, description="prediction channel scale overrides "
                                     "(PATTERN=SCALE; inf ignores a channel)")
    reference_sha256: str = Field(default="", description="hash of the prediction reference's trajectory file",
                                  json_schema_extra=DERIVED)

    def saved(self) -> dict[str, Any]:
        """The document saved as ``align_config.json`` (and in ``align_record.json``)."""
        return json.loads(self.saved_json())

    def saved_json(self) -> str:
        exclude = set(PREDICTION_FIELDS) if self.objective == "trajectory" else set()
        exclude |= {name for name in LATER_FIELDS
                    if getattr(self, name) == AlignConfig.model_fields[name].get_default(call_default_factory=True)}
        return self.model_dump_json(exclude=exclude)

    def digest(self) -> str:
        return hashlib.sha256(self.saved_json().encode()).hexdigest()


def derived_fields() -> frozenset[str]:
    """Fields that ``run_align`` fills in from the inputs (no CLI option)."""
    return frozenset(name for name, f in AlignConfig.model_fields.items()
                     if isinstance(f.json_schema_extra, dict) and f.json_schema_extra.get("derived"))
