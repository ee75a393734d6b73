"""The trajectory objective as a problem: suite runs of the target twin scored against the reference's.

Each knob setting is one run of the fitted (and held-out) scenarios on the target twin, scored by the objective
of :mod:`dualtwin.align.objective` (DTW, event times, endpoints; residuals for least squares). Held-out
scenarios are simulated for every candidate but never steer the search: they show whether the fit generalises.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from dualtwin.align.core import CachedProblem, Evaluation, Point, residual_norm
from dualtwin.align.knobs import KnobSpec
from dualtwin.align.objective import ObjectiveSpec, ResidualBlock, evaluate, residual_layout, residuals
from dualtwin.align.simulate import Evaluator, SimJob, Traces


class TrajectoryProblem(CachedProblem):
    """Unit-cube points -> suite runs -> objective values and residuals."""

    def __init__(self, specs: Sequence[KnobSpec], job: SimJob, train: ObjectiveSpec, holdout: ObjectiveSpec | None,
                 evaluator: Evaluator, budget: int, regularization: float = 0.0) -> None:
        super().__init__(specs, budget, regularization)
        self.job = job
        self.train = train
        self.holdout = holdout
        self.evaluator = evaluator
        # The traces of a few points, so the fitted point's suite run is written, not simulated again: the best
        # by either optimiser's criterion (objective, residual norm), the last point evaluated, and points
        # scored from a run folder (`remember`). A few suite runs in memory, whatever the budget.
        self._kept: dict[str, tuple[float, tuple[float, ...], Traces]] = {}
        self._remembered: dict[tuple[float, ...], Traces] = {}

    def simulate(self, values: Sequence[Mapping[str, float]]) -> list[Traces]:
        """One suite run per knob setting (in parallel through the evaluator)."""
        return self.evaluator.map([self.job.with_knobs(v) for v in values])

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        return [self.score(traces) for traces in self.simulate(values)]

    def score(self, traces: Traces) -> Evaluation:
        """The objective of one knob setting's traces."""
        train = evaluate(self.train, traces).total
        holdout = evaluate(self.holdout, traces).total if self.holdout is not None else None
        return Evaluation(train, holdout, residuals(self.train, traces), simulated=traces)

    def keep(self, key: tuple[float, ...], point: Point, simulated: Any) -> None:
        if simulated is None:
            return
        for slot, value in (("objective", point.train), ("residual", residual_norm(point)), ("last", 0.0)):
            held = self._kept.get(slot)
            if slot == "last" or held is None or value < held[0]:
                self._kept[slot] = (value, key, simulated)

    def traces_at(self, u: Sequence[float]) -> Traces | None:
        """The traces simulated at ``u`` if they were kept (see ``_kept``), else None."""
        key = tuple(min(1.0, max(0.0, float(x))) for x in u)
        if key in self._remembered:
            return self._remembered[key]
        return next((traces for _, k, traces in self._kept.values() if k == key), None)

    def remember(self, u: Sequence[float], traces: Traces) -> Point:
        """The point ``u`` from traces already simulated there (a suite run this alignment wrote), counted as
        one evaluation like :meth:`run` and cached: the same simulation is not run twice."""
        key = tuple(min(1.0, max(0.0, float(x))) for x in u)
        if key not in self._cache:
            self.evaluations += 1
            self._cache[key] = self._score(list(key), self.score(traces))
            self._remembered[key] = traces
        return self._cache[key]

    def residual_blocks(self) -> list[ResidualBlock]:
        """The training residuals' layout (scenario and channel per stretch), for intervals and identifiability."""
        return residual_layout(self.train)
