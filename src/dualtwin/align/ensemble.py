"""The ensemble objectives: the trajectory objective on an ensemble's members, by their mean or member by member.

A reference run made with ``suite run --ensemble N --perturb KEY=EPS`` holds N members per scenario, each
started from slightly shifted initial conditions. The target is simulated once per member, with the same
initial-condition shifts, so each candidate costs N simulations (the budget still counts candidates). Two
ways to score them:

* ``mean``: the members' mean trace (:func:`dualtwin.align.objective.mean_trace`) against the reference
  members' mean. What no engine reproduces (which member's pole leaves its stop one control period earlier)
  averages out, but so does what the members would each have told: N different trajectories collapse into
  one smeared one, and a target whose members swap their behaviours scores the same.
* ``members``: every target member against the reference member started from the same shift, their
  residuals stacked (each member weighted ``1/√N``, so the squared norm is the members' mean). Each trajectory
  keeps its information, and a dent that fits one member by chance (a needle of a rough criterion) no longer
  pays off unless the others fit too.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from dualtwin.align.core import Evaluation
from dualtwin.align.knobs import KnobSpec
from dualtwin.align.objective import ObjectiveSpec, ResidualBlock, evaluate, mean_trace, residuals
from dualtwin.align.simulate import Evaluator, ScenarioTrace, SimJob, Traces
from dualtwin.align.trajectory import TrajectoryProblem
from dualtwin.errors import DualtwinError

EnsembleMode = Literal["mean", "members"]
ENSEMBLE_MODES: tuple[EnsembleMode, ...] = ("mean", "members")


def member_spec(spec: ObjectiveSpec, reference_members: Mapping[str, Sequence[ScenarioTrace]], k: int) -> ObjectiveSpec:
    """``spec`` scored against member ``k`` of each scenario that has members (scales and thresholds unchanged,
    so every member's residuals are in the same units)."""
    return dataclasses.replace(spec, reference={**spec.reference,
                                                **{sid: m[k] for sid, m in reference_members.items()
                                                   if sid in spec.reference}})


class EnsembleProblem(TrajectoryProblem):
    """Each point simulated once per member (its initial-condition shifts), scored by the members' mean trace
    (``mode="mean"``) or member by member (``mode="members"``, which needs ``reference_members``)."""

    def __init__(self, specs: Sequence[KnobSpec], job: SimJob, train: ObjectiveSpec, holdout: ObjectiveSpec | None,
                 evaluator: Evaluator, budget: int, regularization: float,
                 members: Sequence[Mapping[str, float]], mode: EnsembleMode = "mean",
                 reference_members: Mapping[str, Sequence[ScenarioTrace]] | None = None) -> None:
        super().__init__(specs, job, train, holdout, evaluator, budget, regularization)
        if mode not in ENSEMBLE_MODES:
            raise DualtwinError(f"unknown ensemble mode {mode!r}; use one of {', '.join(ENSEMBLE_MODES)}")
        self.members = [dict(m) for m in members]
        self.mode = mode
        self.train_members: list[ObjectiveSpec] = []
        self.holdout_members: list[ObjectiveSpec] = []
        if mode == "members":
            if reference_members is None:
                raise DualtwinError("ensemble 'members' needs the reference's member traces")
            lacking = [s for s in train.scenarios if len(reference_members.get(s, ())) != len(self.members)]
            if lacking:
                raise DualtwinError(f"scenarios {lacking} do not hold all {len(self.members)} ensemble members")
            n = range(len(self.members))
            self.train_members = [member_spec(train, reference_members, k) for k in n]
            if holdout is not None:
                self.holdout_members = [member_spec(holdout, reference_members, k) for k in n]

    def simulate_members(self, values: Sequence[Mapping[str, float]]) -> list[list[Traces]]:
        """Per knob setting, one run per member (member order)."""
        n = len(self.members)
        runs = self.evaluator.map([self.job.with_knobs(v).with_offsets(m) for v in values for m in self.members])
        return [runs[i * n:(i + 1) * n] for i in range(len(values))]

    def simulate(self, values: Sequence[Mapping[str, float]]) -> list[Traces]:
        """Per knob setting, the members' mean traces."""
        return [{sid: mean_trace([g[sid] for g in group]) for sid in group[0]}
                for group in self.simulate_members(values)]

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        if self.mode == "mean":
            return super().evaluate_knobs(values)
        weight = 1.0 / math.sqrt(len(self.members))
        out: list[Evaluation] = []
        for group in self.simulate_members(values):
            train = float(np.mean([evaluate(s, g).total for s, g in zip(self.train_members, group, strict=True)]))
            holdout = (float(np.mean([evaluate(s, g).total for s, g in zip(self.holdout_members, group, strict=True)]))
                       if self.holdout_members else None)
            stacked = np.concatenate([residuals(s, g) for s, g in zip(self.train_members, group, strict=True)])
            out.append(Evaluation(train, holdout, stacked * weight))
        return out

    def residual_blocks(self) -> list[ResidualBlock]:
        """One layout per member, one after the other (``members``), or the trajectory's (``mean``)."""
        layout = super().residual_blocks()
        if self.mode == "mean":
            return layout
        size = layout[-1].stop if layout else 0
        return [dataclasses.replace(b, start=b.start + k * size, stop=b.stop + k * size)
                for k in range(len(self.members)) for b in layout]
