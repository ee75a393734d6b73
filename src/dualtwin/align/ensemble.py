"""The ensemble objective: the trajectory objective on the mean of an ensemble's members.

A reference run made with ``suite run --ensemble N --perturb KEY=EPS`` holds N members per scenario, each
started from slightly shifted initial conditions. A chaotic scenario's single trajectory cannot be fitted
(a tiny change of a knob moves it anywhere later on), but what its members share can: the target is
simulated once per member, with the same initial-condition shifts, and the members' mean trace
(:func:`dualtwin.align.objective.mean_trace`) is scored against the reference members' mean. Each candidate
then costs N simulations (the budget still counts candidates).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from dualtwin.align.knobs import KnobSpec
from dualtwin.align.objective import ObjectiveSpec, mean_trace
from dualtwin.align.simulate import Evaluator, SimJob, Traces
from dualtwin.align.trajectory import TrajectoryProblem


class EnsembleProblem(TrajectoryProblem):
    """Each point simulated once per member (its initial-condition shifts), scored by the members' mean trace."""

    def __init__(self, specs: Sequence[KnobSpec], job: SimJob, train: ObjectiveSpec, holdout: ObjectiveSpec | None,
                 evaluator: Evaluator, budget: int, regularization: float,
                 members: Sequence[Mapping[str, float]]) -> None:
        super().__init__(specs, job, train, holdout, evaluator, budget, regularization)
        self.members = [dict(m) for m in members]

    def simulate(self, values: Sequence[Mapping[str, float]]) -> list[Traces]:
        n = len(self.members)
        runs = self.evaluator.map([self.job.with_knobs(v).with_offsets(m) for v in values for m in self.members])
        out: list[Traces] = []
        for i in range(len(values)):
            group = runs[i * n:(i + 1) * n]
            out.append({sid: mean_trace([g[sid] for g in group]) for sid in group[0]})
        return out
