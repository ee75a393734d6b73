"""The optimiser core's data: the problem protocol, evaluated points, and uncertainty at an optimum.

An alignment objective is a *problem*: it maps points of the unit cube (one coordinate per knob, in the
knob's normalised range, see :mod:`dualtwin.align.knobs`) to a training value, an optional held-out value
and a residual vector. The optimisers of :mod:`dualtwin.align.optimize` (CMA-ES, least squares) and the
uncertainty below see only the :class:`Problem` protocol, so every objective (trajectory, ensemble,
prediction) is a peer: each subclasses :class:`CachedProblem` and says how it evaluates knob values.

Uncertainty is taken from the Jacobian at the optimum: covariance ``s²(JᵀJ)⁻¹`` and 95 % Student-t
half-widths, with a conditioning check. Residuals of a trajectory are autocorrelated, so these intervals are
optimistic: read them as a lower bound on the uncertainty.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from dualtwin.align.knobs import KnobSpec, unit_from_values, values_from_unit

#: cond(JᵀJ) above this (in normalised knob units) is reported as ill-conditioned.
ILL_CONDITIONED = 1e10


@dataclass(frozen=True)
class GenerationInfo:
    """Progress after one CMA generation or least-squares iteration (passed to ``callback``)."""

    iteration: int
    evaluations: int
    best_value: float
    best_knobs: dict[str, float]
    holdout_value: float | None
    sigma: float | None = None


@dataclass
class Point:
    """One evaluated unit-cube point: training and held-out values, residuals (regularisation included)."""

    u: list[float]
    train: float
    holdout: float | None
    residual: np.ndarray


@dataclass
class Evaluation:
    """What an objective says about one knob setting: its training value (before regularisation), its
    held-out value (None without held-out data), its residual vector, any per-point detail to keep, and what
    was simulated (offered to :meth:`CachedProblem.keep`, not kept for every point)."""

    train: float
    holdout: float | None
    residual: np.ndarray
    detail: Any = None
    simulated: Any = None


class Problem(Protocol):
    """What the optimisers and the uncertainty estimate need from an objective."""

    specs: list[KnobSpec]
    evaluations: int

    def values(self, u: Sequence[float]) -> dict[str, float]: ...

    def run(self, points: Sequence[Sequence[float]]) -> list[Point]: ...

    def run_values(self, values: Sequence[Mapping[str, float]]) -> list[float]: ...

    def point_state(self, u: Sequence[float]) -> dict[str, Any] | None: ...

    def restore_point(self, state: Mapping[str, Any]) -> None: ...


class CachedProblem(ABC):
    """Unit-cube points -> :meth:`evaluate_knobs` -> points, with evaluation counting, a point cache and the
    pull toward nominal. An objective implements :meth:`evaluate_knobs` only."""

    def __init__(self, specs: Sequence[KnobSpec], budget: int, regularization: float = 0.0) -> None:
        self.specs = list(specs)
        self.regularization = regularization
        self.u0 = np.array(unit_from_values(specs, {}))
        # The pull toward nominal is relative to the nominal mismatch, so λ means the same on any problem.
        self.objective_scale = 0.0
        self.residual_scale = 0.0
        self.budget = budget
        self.evaluations = 0
        # Simulations are deterministic: a point seen before (an injected incumbent) costs nothing.
        self._cache: dict[tuple[float, ...], Point] = {}
        #: Per-point detail an objective keeps (the prediction objective's error tables).
        self.details: dict[tuple[float, ...], Any] = {}

    @abstractmethod
    def evaluate_knobs(self, values: Sequence[Mapping[str, float]]) -> list[Evaluation]:
        """Evaluate each knob setting (simulating them together, in parallel where the objective can)."""

    def calibrate(self, nominal: Point) -> None:
        """Fix the regularization scales from the nominal twin's objective and residuals."""
        self.objective_scale = nominal.train
        self.residual_scale = float(nominal.residual @ nominal.residual)

    def values(self, u: Sequence[float]) -> dict[str, float]:
        return values_from_unit(self.specs, u)

    def point_state(self, u: Sequence[float]) -> dict[str, Any] | None:
        """A cached point as JSON (for checkpoints), or None if it was never simulated."""
        point = self._cache.get(tuple(u))
        if point is None:
            return None
        return {"u": point.u, "train": point.train, "holdout": point.holdout, "residual": point.residual.tolist()}

    def restore_point(self, state: Mapping[str, Any]) -> None:
        """Put a checkpointed point back into the cache, so a resumed run simulates exactly what the original would.

        Raises:
            ValueError: A point this problem cannot have produced (the checkpoint was edited): its unit-cube
                coordinates are not one per knob in [0, 1], or its residual is not finite or not as long as
                those simulated here (a Jacobian would subtract residuals of different lengths).
        """
        u = [float(x) for x in state["u"]]
        if len(u) != len(self.specs) or not all(0.0 <= x <= 1.0 for x in u):
            raise ValueError(f"point {u} is not {len(self.specs)} unit-cube coordinates in [0, 1]")
        residual = np.asarray(state["residual"], float)
        simulated = next(iter(self._cache.values()), None)
        if residual.ndim != 1 or not np.isfinite(residual).all() or (
                simulated is not None and residual.shape != simulated.residual.shape):
            entries = "" if simulated is None else f" of {len(simulated.residual)} entries"
            raise ValueError(f"the residual of point {u} is not a finite vector{entries}")
        self._cache[tuple(u)] = Point(u, float(state["train"]), state["holdout"], residual)

    def run(self, points: Sequence[Sequence[float]]) -> list[Point]:
        points = [[min(1.0, max(0.0, float(x))) for x in p] for p in points]
        fresh = [p for i, p in enumerate(points) if tuple(p) not in self._cache and p not in points[:i]]
        results = self.evaluate_knobs([self.values(p) for p in fresh])
        self.evaluations += len(fresh)
        for p, evaluation in zip(fresh, results, strict=True):
            self._cache[tuple(p)] = self._score(list(p), evaluation)
            if evaluation.detail is not None:
                self.details[tuple(p)] = evaluation.detail
            self.keep(tuple(p), self._cache[tuple(p)], evaluation.simulated)
        return [self._cache[tuple(p)] for p in points]

    def simulated(self) -> list[Point]:
        """Every point simulated so far (by the fit and by the interval checks), in the order first simulated."""
        return list(self._cache.values())

    def keep(self, key: tuple[float, ...], point: Point, simulated: Any) -> None:
        """Offered what was simulated for each new point (``Evaluation.simulated``); kept by none here."""
        return None

    def run_values(self, values: Sequence[Mapping[str, float]]) -> list[float]:
        """Training values of explicit knob settings (for proposals; no regularisation, not cached)."""
        results = self.evaluate_knobs(list(values))
        self.evaluations += len(values)
        return [e.train for e in results]

    def _score(self, u: list[float], evaluation: Evaluation) -> Point:
        train, r = evaluation.train, evaluation.residual
        if self.regularization:
            # Ridge toward nominal in normalised units: data must pay for every move away from the model.
            shift = np.asarray(u) - self.u0
            train += self.regularization * self.objective_scale * float(np.mean(shift ** 2))
            r = np.concatenate([r, math.sqrt(self.regularization * self.residual_scale / shift.size) * shift])
        return Point(u, train, evaluation.holdout, r)


@dataclass
class Outcome:
    """Where an optimiser ended: the point, its iterations, why it stopped, its trace and last populations."""

    u: list[float]
    iterations: int
    stop_reason: str
    trace: list[dict[str, Any]]
    population: list[tuple[list[float], float]] = field(default_factory=list)
    #: True when the optimiser stopped because its evaluation budget ran out, not by a convergence rule.
    ended_on_budget: bool = False



def screen_integers(problem: Problem, u: Sequence[float], integer: Sequence[int], budget: int,
                     criterion: Callable[[Point], float]) -> list[float]:
    """Set each integer knob to its best value by ``criterion``, trying every integer with the others held.

    An integer knob's effect does not change smoothly (least squares cannot follow it, and CMA-ES's rounded
    steps rarely cross a rough landscape to a distant value). Its values are few, so they are all simulated
    (in parallel) and the optimiser starts from the best.
    """
    u = list(u)
    for i in integer:
        _, points = integer_sweep(problem, u, i)
        if problem.evaluations + len(points) > budget:
            break
        scored = problem.run([u, *points])
        u = min(scored, key=criterion).u
    return u


def t_quantile(dof: float, p: float = 0.975) -> float:
    """The Student-t quantile (what ``scipy.stats.t.ppf`` computes). ``scipy.special`` is imported here, not with
    the module: its import costs about half a CPU-second that a fit without intervals need not pay, and
    ``scipy.stats`` a second."""
    from scipy import special

    return float(special.stdtrit(dof, p))


def residual_norm(p: Point) -> float:
    return float(p.residual @ p.residual)


def integer_sweep(problem: Problem, u: Sequence[float], i: int) -> tuple[list[int], list[list[float]]]:
    """Every integer value of knob ``i`` within its bounds, and ``u`` with knob ``i`` set to each of them."""
    spec = problem.specs[i]
    values = list(range(math.ceil(spec.lower), math.floor(spec.upper) + 1))
    return values, [[*u[:i], spec.to_unit(v), *u[i + 1:]] for v in values]


# ------------------------------------------------------------------ uncertainty
@dataclass
class Uncertainty:
    """95 % half-widths per knob (None: unidentifiable or not estimated), cond(JᵀJ), and what to warn about.

    :mod:`dualtwin.align.intervals` fills in the rest: each knob's 95 % interval (``(lower, upper)``, possibly
    asymmetric, the knob's bounds where the data pin nothing) and the method that gave it, the correlation
    matrix of the fitted knobs, the pairs with ``|r| > 0.9``, and the noise estimate.
    """

    half_widths: dict[str, float | None]
    condition: float | None
    warnings: list[str]
    intervals: dict[str, tuple[float, float] | None] = field(default_factory=dict)
    methods: dict[str, str] = field(default_factory=dict)
    correlation: dict[str, Any] = field(default_factory=dict)
    correlated: list[dict[str, Any]] = field(default_factory=list)
    noise: dict[str, float] = field(default_factory=dict)
    #: A point the interval checks simulated whose residual norm is below the fit's by more than the
    #: criterion's jitter (the fit had not reached the minimum), as ``{"u": [...], "criterion": f}``; else None.
    better: dict[str, Any] | None = None


def fd_jacobian(problem: Problem, u: Sequence[float], step: float, columns: Sequence[int], central: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
    """Finite-difference Jacobian of the residuals at ``u`` for knobs ``columns`` (unit coordinates), and the
    residual at ``u``: the point and its perturbations are simulated as one batch (one ``problem.run``).

    ``central`` differences (both sides where both lie in the box) cost twice the simulations and remove the
    first-order bias of a forward difference, which at a 3 % step moves a Gauss-Newton optimum and an interval.
    """
    points = [list(u)]
    pairs: list[tuple[int, int | None, float]] = []  # (column's forward point, backward point or None, spacing)
    for i in columns:
        forward = u[i] + step <= 1.0
        p = list(u)
        p[i] = u[i] + step if forward else u[i] - step
        points.append(p)
        back: int | None = None
        if central and forward and u[i] - step >= 0.0:
            q = list(u)
            q[i] = u[i] - step
            points.append(q)
            back = len(points) - 1
        pairs.append((len(points) - 1 if back is None else len(points) - 2, back, p[i] - u[i]))
    results = problem.run(points)
    r0 = results[0].residual
    if not columns:
        return np.zeros((r0.size, 0)), r0
    cols = []
    for at, back, spacing in pairs:
        if back is None:
            cols.append((results[at].residual - r0) / spacing)
        else:
            cols.append((results[at].residual - results[back].residual) / (2 * spacing))
    return np.stack(cols, axis=1), r0


def estimate_uncertainty(problem: Problem, u: Sequence[float], step: float) -> Uncertainty:
    """Jacobian of the residuals at ``u`` (continuous knobs), covariance s²(JᵀJ)⁻¹ and 95 % half-widths."""
    specs = problem.specs
    cont = [i for i, s in enumerate(specs) if not s.integer]
    half: dict[str, float | None] = {s.name: None for s in specs}
    for i, spec in enumerate(specs):
        if spec.integer:
            half[spec.name] = integer_half_width(problem, u, i)
    if not cont:
        return Uncertainty(half, None, [])
    jac, r0 = fd_jacobian(problem, u, step, cont)
    return interval_estimate(jac, r0, [specs[i] for i in cont], [u[i] for i in cont], half)


def integer_half_width(problem: Problem, u: Sequence[float], i: int) -> float:
    """95 % half-width of an integer knob from its residuals at every integer, the other knobs held.

    An integer knob has no Jacobian column. Its interval holds the values whose residual sum of squares stays
    within the one-parameter likelihood-ratio bound ``SSR <= SSR_min (1 + t²/dof)``, the same 95 % level as the
    continuous knobs' intervals (conditional on the others, so it is, if anything, narrow).
    """
    values, points = integer_sweep(problem, u, i)
    results = problem.run(points)  # cached when the last screening ran at this point
    ssr = [float(r.residual @ r.residual) for r in results]
    dof = max(len(results[0].residual) - len(problem.specs), 1)
    limit = min(ssr) * (1.0 + t_quantile(dof) ** 2 / dof)
    fitted = problem.specs[i].from_unit(u[i])
    return float(max(abs(v - fitted) for v, s in zip(values, ssr, strict=True) if s <= limit))


def interval_estimate(jac: np.ndarray, r0: np.ndarray, specs: Sequence[KnobSpec], u: Sequence[float],
                      half: dict[str, float | None] | None = None) -> Uncertainty:
    """Covariance ``s²(JᵀJ)⁻¹`` in unit coordinates, 95 % Student-t half-widths in knob units, conditioning.

    Knobs whose Jacobian column vanishes are unidentifiable (no half-width). Trade-offs are named by the
    cosine between Jacobian columns, which stays meaningful when JᵀJ is singular.
    """
    half = dict(half or {s.name: None for s in specs})
    warnings: list[str] = []
    m, k = jac.shape
    norms = np.linalg.norm(jac, axis=0)
    live = [j for j in range(k) if norms[j] > 1e-12 * max(float(norms.max()), 1e-300)]
    for j in range(k):
        if j not in live:
            warnings.append(f"{specs[j].name} has no measurable effect on the fitted channels at its fitted value: "
                            "it cannot be identified from this suite (add a scenario that excites it, or drop it)")
    if not live:
        return Uncertainty(half, math.inf, warnings)
    sub = jac[:, live]
    jtj = sub.T @ sub
    eig, vec = np.linalg.eigh(jtj)
    top = float(eig.max())
    small = eig <= top * 1e-12
    condition = math.inf if len(live) < k or small.any() else float(top / eig.min())
    dof = max(m - len(live), 1)
    s2 = float(r0 @ r0) / dof
    t = t_quantile(dof)
    for col, j in enumerate(live):
        loading = vec[col] ** 2
        if float(loading[small].sum()) > 1e-8:
            continue  # lies along an unidentifiable direction: unbounded
        var = s2 * float(np.sum(loading[~small] / eig[~small]))
        value = specs[j].from_unit(u[j])
        half[specs[j].name] = float(t * math.sqrt(var) * specs[j].dvalue_du(value))
    if condition > ILL_CONDITIONED and len(live) > 1:
        unit = sub / np.linalg.norm(sub, axis=0)
        cosine = unit.T @ unit
        np.fill_diagonal(cosine, 0.0)
        a, b = np.unravel_index(int(np.argmax(np.abs(cosine))), cosine.shape)
        warnings.append(f"ill-conditioned: cond(JᵀJ) = {condition:.3g}; {specs[live[a]].name} and "
                        f"{specs[live[b]].name} trade off (their effects are {abs(cosine[a, b]):.3f} parallel); "
                        "the suite cannot pin these knobs down separately")
    return Uncertainty(half, condition, warnings)

