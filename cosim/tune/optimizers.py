"""The optimisers a tuning drives, from SciPy (`scipy.optimize`), each asking the evaluator
(`cosim.tune.evaluations.Evaluator`) for batches of points.

- `DifferentialEvolution` (the default): global, derivative-free, bounded; a whole generation
  is one batch (SciPy's ``vectorized=True``, ``updating="deferred"``), run in parallel on the
  sweep's engines; constraints are SciPy's own (Lampinen's feasibility rules: a feasible
  point beats an infeasible one, infeasible ones compare by their violation), measured on the
  same runs as the objective; Integer parameters by SciPy's ``integrality``; the scenario's
  own values, when all are within the bounds, replace the first member of the initial
  population (``x0``), so the tuning is never worse than what it started from.  The last
  ``polish`` share of the budget refines the best feasible point with Nelder–Mead (infeasible
  points are +inf to it, a barrier), where SciPy's own ``polish`` runs L-BFGS-B on
  finite-difference gradients without a budget.  The defaults (``currenttobest1bin``,
  ``popsize`` 5, ``polish`` 0.2) come from docs/tune_surrogate_study.py: on a cubic
  surrogate of the committed FOPDT grid, none of 32 seeds ended more than 2 % above the grid's
  best in 240 evaluations, against 2 of 32 with SciPy's default strategy ``best1bin`` and 18
  of 32 without the polish (31 of 32 with SciPy's defaults, popsize 15).
- `NelderMead`: a local simplex search from the scenario's own values, one point at a time
  (the noise seeds of a point run in parallel); no constraints.

Both are deterministic for a given ``seed`` and given answers, which is what makes a tuning
resumable from its table (`cosim.tune.evaluations`).
"""
from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError
from .evaluations import Evaluator


@dataclass(frozen=True)
class DifferentialEvolution:
    """`scipy.optimize.differential_evolution`; ``popsize`` is SciPy's multiplier: a generation
    has ``popsize`` × (number of parameters) points (at least 5); ``polish``: the share of the
    budget left to `NelderMead` from the best point (0: none; none with Integer parameters)."""
    popsize: int = 5
    tol: float = 0.01
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    strategy: str = "currenttobest1bin"
    init: str = "latinhypercube"
    polish: float = 0.2

    name = "differential-evolution"

    def generation(self, dimensions: int) -> int:
        return max(5, self.popsize * dimensions)

    def run(self, evaluator: Evaluator, budget: int, seed: int) -> str:
        from scipy.optimize import NonlinearConstraint, differential_evolution

        space = evaluator.space
        size = self.generation(len(space.parameters))
        integral = space.integrality()
        polish = 0 if integral.any() else int(budget * self.polish)
        if budget - polish < size:
            raise SetupError(f"{budget} evaluations leave less than one generation of differential evolution "
                             f"({size} points: --popsize {self.popsize} x {len(space.parameters)} parameters) before "
                             f"the Nelder-Mead polish ({polish}); raise it or lower --popsize.",
                             element="--max-evaluations")

        def answers(x: np.ndarray):
            points = np.atleast_2d(np.asarray(x, dtype=float).T) if np.ndim(x) == 2 else [np.asarray(x, dtype=float)]
            return evaluator(list(points))

        def objective(x: np.ndarray) -> np.ndarray | float:
            values = np.array([ev.value for ev in answers(x)])
            return values if np.ndim(x) == 2 else float(values[0])

        constraints = evaluator.objective.constraints
        extra = {}
        if constraints:
            lower = np.array([c.lower for c in constraints])
            upper = np.array([c.upper for c in constraints])
            missing = np.where(np.isfinite(upper), math.inf, -math.inf)

            def measured(x: np.ndarray) -> np.ndarray:
                out = np.array([[missing[j] if ev.constraints.get(c.text()) is None else ev.constraints[c.text()]
                                 for j, c in enumerate(constraints)] for ev in answers(x)]).T
                return out if np.ndim(x) == 2 else out[:, 0]

            extra["constraints"] = NonlinearConstraint(measured, lower, upper)
        x0 = space.x0()
        result = differential_evolution(
            objective, space.bounds(), maxiter=(budget - polish) // size - 1, popsize=self.popsize, tol=self.tol,
            mutation=self.mutation, recombination=self.recombination, strategy=self.strategy, init=self.init,
            polish=False, vectorized=True, updating="deferred",
            x0=None if x0 is None else np.where(integral, np.round(x0), x0),
            integrality=integral if integral.any() else None, **_random(differential_evolution, seed), **extra)
        message = str(result.message).rstrip(".")
        best = evaluator.best
        left = budget - len(evaluator.evaluations)
        if polish and left > len(space.parameters) + 1 and best is not None and best.feasible:
            start = np.array([p.coordinate(best.values[p.name]) for p in space.parameters])
            message += "; polished by Nelder-Mead: " + _nelder_mead(evaluator, start, left, 0.05, barrier=True)
        return message


@dataclass(frozen=True)
class NelderMead:
    """`scipy.optimize.minimize` with ``method="Nelder-Mead"`` from the scenario's values (the
    centre of the bounds for a parameter that has none there), the first simplex spanning
    ``step`` of each parameter's range."""
    step: float = 0.1

    name = "nelder-mead"

    def run(self, evaluator: Evaluator, budget: int, seed: int) -> str:
        space = evaluator.space
        if evaluator.objective.constraints:
            raise SetupError("Nelder-Mead takes no constraints; tune with --method differential-evolution, "
                             "or fold the constraint into the objective as a weighted term.", element="--constraint")
        if space.integrality().any():
            raise SetupError("Nelder-Mead searches Real parameters only; tune Integer parameters with "
                             "--method differential-evolution.", element="--method")
        x0 = np.array([p.coordinate(v) if v is not None else sum(p.bounds()) / 2
                       for p, v in zip(space.parameters, space.current)])
        return _nelder_mead(evaluator, x0, budget, self.step, barrier=False)


def _nelder_mead(evaluator: Evaluator, x0: np.ndarray, budget: int, step: float, barrier: bool) -> str:
    """SciPy's Nelder–Mead from ``x0`` within the bounds, at most ``budget`` evaluations, the
    first simplex ``step`` of each range from ``x0`` (inward at a bound); ``barrier``: a point
    that is not feasible is +inf."""
    from scipy.optimize import minimize

    bounds = np.array(evaluator.space.bounds())
    simplex = [x0]
    for i, (lo, hi) in enumerate(bounds):
        vertex = x0.copy()
        width = step * (hi - lo)
        vertex[i] = x0[i] + width if x0[i] + width <= hi else x0[i] - width
        simplex.append(vertex)

    def value(x: np.ndarray) -> float:
        ev = evaluator([x])[0]
        return ev.value if ev.feasible or not barrier else math.inf

    result = minimize(value, x0, method="Nelder-Mead", bounds=bounds,
                      options={"maxfev": budget, "initial_simplex": np.array(simplex),
                               "xatol": 1e-4 * float(np.max(bounds[:, 1] - bounds[:, 0])), "fatol": 0.0})
    return str(result.message)


METHODS = {m.name: m for m in (DifferentialEvolution, NelderMead)}


def _random(function, seed: int) -> dict:
    """SciPy's random-state keyword: ``rng`` (a Generator; SciPy >= 1.15) or ``seed``."""
    if "rng" in inspect.signature(function).parameters:
        return {"rng": np.random.default_rng(seed)}
    return {"seed": seed}
