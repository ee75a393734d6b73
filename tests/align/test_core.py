"""The optimiser core on a problem with a closed-form answer: any objective that implements the protocol is fitted.

A straight line ``y = a t + b`` with seeded noise, as a :class:`CachedProblem` peer of the trajectory and
prediction objectives (no simulator): least squares must land on the ordinary-least-squares solution and its
95 % intervals must equal the textbook ``t · sqrt(s² (XᵀX)⁻¹)``; CMA-ES must get close to the same point.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from dualtwin.align import AlignConfig, CachedProblem, Evaluation, estimate_uncertainty, fit_cma, fit_lsq
from dualtwin.align.knobs import KnobSpec, unit_from_values, values_from_unit

SPECS = [KnobSpec("a", nominal=1.0, lower=0.0, upper=4.0), KnobSpec("b", nominal=0.0, lower=-2.0, upper=2.0)]
T = np.linspace(0.0, 1.0, 40)
Y = 2.5 * T - 0.7 + np.random.default_rng(7).normal(0.0, 0.05, T.size)
X = np.stack([T, np.ones_like(T)], axis=1)


class LineProblem(CachedProblem):
    """Residuals of a straight line against the data; the training value is ``‖r‖²``."""

    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        out = []
        for v in values:
            r = v["a"] * T + v["b"] - Y
            out.append(Evaluation(float(r @ r), None, r))
        return out


def config(optimizer: str, budget: int) -> AlignConfig:
    return AlignConfig(reference="line", target="line", robot="line", knobs=["a", "b"], optimizer=optimizer,
                       budget=budget, seed=3)  # type: ignore[arg-type]


def start(problem: LineProblem) -> tuple[list[float], float]:
    x0 = unit_from_values(SPECS, {})
    nominal = problem.run([x0])[0]
    problem.calibrate(nominal)
    return x0, nominal.train


def test_least_squares_gives_the_ols_line_and_its_intervals(tmp_path: Path) -> None:
    problem = LineProblem(SPECS, budget=200)
    x0, f0 = start(problem)
    outcome = fit_lsq(problem, config("lsq", 200), tmp_path, x0, f0, False, None)
    fitted = values_from_unit(SPECS, outcome.u)
    ols, *_ = np.linalg.lstsq(X, Y, rcond=None)
    assert [fitted["a"], fitted["b"]] == pytest.approx(list(ols), abs=1e-6)
    uncertainty = estimate_uncertainty(problem, outcome.u, 0.03)
    residual = X @ ols - Y
    dof = T.size - 2
    s2 = float(residual @ residual) / dof
    expected = stats.t.ppf(0.975, dof) * np.sqrt(s2 * np.diag(np.linalg.inv(X.T @ X)))
    assert [uncertainty.half_widths["a"], uncertainty.half_widths["b"]] == pytest.approx(list(expected), rel=1e-4)
    assert uncertainty.condition is not None and uncertainty.condition > 1 and not uncertainty.warnings
    assert (tmp_path / "checkpoint.json").is_file() and problem.evaluations <= 200


def test_cma_reaches_the_same_line_within_its_budget(tmp_path: Path) -> None:
    problem = LineProblem(SPECS, budget=300)
    x0, f0 = start(problem)
    outcome = fit_cma(problem, config("cma", 300), tmp_path, x0, f0, False, None)
    fitted = values_from_unit(SPECS, outcome.u)
    ols, *_ = np.linalg.lstsq(X, Y, rcond=None)
    assert [fitted["a"], fitted["b"]] == pytest.approx(list(ols), abs=0.01)
    assert problem.evaluations <= 300 and outcome.trace and outcome.population


def test_the_pull_toward_nominal_holds_an_unpaid_move_back(tmp_path: Path) -> None:
    # With a strong regularization the fit stays between nominal (1, 0) and the data's line (2.5, -0.7).
    problem = LineProblem(SPECS, budget=200, regularization=50.0)
    x0, f0 = start(problem)
    fitted = values_from_unit(SPECS, fit_lsq(problem, config("lsq", 200), tmp_path, x0, f0, False, None).u)
    assert 1.0 < fitted["a"] < 2.4
