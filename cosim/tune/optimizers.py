"""The optimisers a tuning drives, from SciPy (`scipy.optimize`), each asking the evaluator
(`cosim.tune.evaluations.Evaluator`) for batches of points.

- `DifferentialEvolution` (the default): global, derivative-free, bounded; a whole generation
  is one batch (SciPy's ``vectorized=True``, ``updating="deferred"``), run in parallel on the
  sweep's engines; constraints are SciPy's own (Lampinen's feasibility rules: a feasible
  point beats an infeasible one, infeasible ones compare by their violation), measured on the
  same runs as the objective; Integer parameters by SciPy's ``integrality``; the scenario's
  own values, when all are within the bounds, replace the first member of the initial
  population (``x0``), so the tuning is never worse than what it started from.
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
    has ``popsize`` × (number of parameters) points (at least 5)."""
    popsize: int = 10
    tol: float = 0.01
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    strategy: str = "best1bin"
    init: str = "latinhypercube"

    name = "differential-evolution"

    def generation(self, dimensions: int) -> int:
        return max(5, self.popsize * dimensions)

    def run(self, evaluator: Evaluator, budget: int, seed: int) -> str:
        from scipy.optimize import NonlinearConstraint, differential_evolution

        space = evaluator.space
        size = self.generation(len(space.parameters))
        if budget < size:
            raise SetupError(f"--max-evaluations {budget} is less than one generation of differential evolution "
                             f"({size} points: --popsize {self.popsize} x {len(space.parameters)} parameters); "
                             "raise it or lower --popsize.", element="--max-evaluations")

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
        integral = space.integrality()
        result = differential_evolution(
            objective, space.bounds(), maxiter=budget // size - 1, popsize=self.popsize, tol=self.tol,
            mutation=self.mutation, recombination=self.recombination, strategy=self.strategy, init=self.init,
            polish=False, vectorized=True, updating="deferred",
            x0=None if x0 is None else np.where(integral, np.round(x0), x0),
            integrality=integral if integral.any() else None, **_random(differential_evolution, seed), **extra)
        return str(result.message)


@dataclass(frozen=True)
class NelderMead:
    """`scipy.optimize.minimize` with ``method="Nelder-Mead"`` from the scenario's values (the
    centre of the bounds for a parameter that has none there), the first simplex spanning
    ``step`` of each parameter's range."""
    step: float = 0.1
    xatol: float = 1e-4
    fatol: float = 0.0

    name = "nelder-mead"

    def run(self, evaluator: Evaluator, budget: int, seed: int) -> str:
        from scipy.optimize import minimize

        space = evaluator.space
        if evaluator.objective.constraints:
            raise SetupError("Nelder-Mead takes no constraints; tune with --method differential-evolution, "
                             "or fold the constraint into the objective as a weighted term.", element="--constraint")
        if space.integrality().any():
            raise SetupError("Nelder-Mead searches Real parameters only; tune Integer parameters with "
                             "--method differential-evolution.", element="--method")
        bounds = np.array(space.bounds())
        x0 = np.array([p.coordinate(v) if v is not None else (lo + hi) / 2
                       for p, v, (lo, hi) in zip(space.parameters, space.current, bounds)])
        simplex = [x0]
        for i, (lo, hi) in enumerate(bounds):
            vertex = x0.copy()
            step = self.step * (hi - lo)
            vertex[i] = x0[i] + step if x0[i] + step <= hi else x0[i] - step
            simplex.append(vertex)
        result = minimize(lambda x: evaluator([x])[0].value, x0, method="Nelder-Mead", bounds=bounds,
                          options={"maxfev": budget, "initial_simplex": np.array(simplex),
                                   "xatol": self.xatol * float(np.max(bounds[:, 1] - bounds[:, 0])),
                                   "fatol": self.fatol})
        return str(result.message)


METHODS = {m.name: m for m in (DifferentialEvolution, NelderMead)}


def _random(function, seed: int) -> dict:
    """SciPy's random-state keyword: ``rng`` (a Generator; SciPy >= 1.15) or ``seed``."""
    if "rng" in inspect.signature(function).parameters:
        return {"rng": np.random.default_rng(seed)}
    return {"seed": seed}
