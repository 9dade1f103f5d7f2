"""Algebraic loops of direct feedthrough, solved at a communication point by iteration.

A loop (`cosim.model.structure.AlgebraicLoop`) is a set of outputs that depend on each other
at the same instant through the inputs they feed: y = g(y) at that instant, g being
"route the outputs to the inputs, set them, read the outputs again".  FMI 2.0 reads an
output without ``dependencies`` as depending on every input (§2.2.8), so plant FMUs
that omit them (20-sim's, and many others) close such loops wherever they are fed back.

`LoopSolver` solves y = g(y) by fixed-point iteration with relaxation, Gauss–Seidel
style, and by Newton's method where that iteration is slow or diverges: one iteration is the
execution's settling sweep (``sweep``: each component of
the feedthrough sequence in dependency order, inputs routed and set, outputs read), so
inside a sweep each component sees the outputs its predecessors just computed; the
values carried from one sweep to the next (the loop's outputs, the tear variables) are
relaxed, y ← y_prev + ω (y − y_prev), Real ones only.  It stops when every loop output
changed by at most atol + rtol·|y| in the last sweep and fails, naming the loop, the time,
the iterations and the residual, when it has not after ``max_iterations`` sweeps.  The
start value of each solve is the solution at the previous communication point.

Newton (``method="newton"``, the default): a loop whose sweeps do not contract fast enough
to converge in about as many sweeps as a Newton solve costs (three sweeps decide: the last
residual ratio predicts the rest; after a point that needed Newton, one sweep decides), or
whose sweeps diverge, is solved instead as g(y) − y = 0 by MINPACK's hybrd (Powell's hybrid
Newton method, ``scipy.optimize.root`` with ``method="hybr"``; the Jacobian by finite
differences, one sweep per loop output, then Broyden updates), from the best sweep so far,
as OMSimulator solves loops by Newton.  It ends at the first point it tries that passes the
same test as the sweeps (one sweep at it changes no loop output by more than the
tolerance), so the buffers hold that sweep; if none does, the fixed point goes on from
hybrd's answer for the sweeps left (the fallback).  Loops that converge in a few sweeps
(the declared loops of FMUs that omit ``dependencies``) never reach Newton, so their
results are those of the fixed point bit for bit.  Newton needs Real loop outputs only;
with an Integer or Boolean one the fixed point runs alone.

A NaN or infinity in a loop output is not a convergence failure: the run stops naming the
component and variable that produced it first in the sweep (its inputs were finite), and t.

`cosim.plan.build.build_plan` with ``loops="delay"`` instead leaves the components on a loop out
of the settling: their outputs are read once per communication point, so each loop is
broken by one step of delay, as libcosim (which never reads dependencies) runs every
connection; the execution warns, naming the loop.

The step's program (`cosim.run.program`) holds the iteration as one operation (OP_SOLVE) followed by
its sweep: ``solve(t, sweep) -> (iterations, residual)`` over NumPy views of the exchange
buffers, made by Python in either interpreter (`cosim.run.interpreters`).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import RunError, SetupError
from ..model.structure import AlgebraicLoop


@dataclass(frozen=True)
class LoopSettings:
    """How `LoopSolver` iterates: a loop output has converged when it changed by at most
    ``atol + rtol·|y|`` in one sweep; ``relaxation`` ω in (0, 1] (1: plain fixed point);
    ``method``: "newton" (fixed point, Newton where it is slow) or "fixed-point" (alone)."""
    rtol: float = 1e-10
    atol: float = 1e-12
    max_iterations: int = 100
    relaxation: float = 1.0
    method: str = "newton"

    def __post_init__(self):
        if not (self.rtol >= 0 and self.atol >= 0 and self.rtol + self.atol > 0
                and math.isfinite(self.rtol) and math.isfinite(self.atol)):
            raise SetupError(f"loop tolerances must be finite, not negative and not both 0; got rtol "
                             f"{self.rtol}, atol {self.atol}.", element="--loop-tolerance")
        if self.max_iterations < 1:
            raise SetupError(f"the loop iteration limit must be at least 1; got {self.max_iterations}.",
                             element="--loop-iterations")
        if not 0 < self.relaxation <= 1:
            raise SetupError(f"the relaxation factor must be in (0, 1]; got {self.relaxation}.",
                             element="--relaxation")
        if self.method not in METHODS:
            raise SetupError(f"the loop method must be one of {', '.join(METHODS)}; got {self.method!r}.",
                             element="--loop-method")


#: `LoopSettings.method` -> the method as the metadata records it
METHODS = {"newton": "fixed point (Gauss-Seidel sweeps) with relaxation; Newton (MINPACK hybrd, "
                     "finite-difference Jacobian) where the sweeps are slow or diverge",
           "fixed-point": "fixed point (Gauss-Seidel sweeps) with relaxation"}
#: fixed-point sweeps before the contraction is judged (`_newton_pays`)
_SWEEPS_BEFORE_JUDGING = 3


@dataclass
class Watched:
    """The loop outputs of one exchange type: a view of the exchange's output buffer and the
    positions of the loop outputs in it; ``relax``: Real values, relaxed between sweeps (and
    solved for by Newton); ``names``: (component, variable) of each position."""
    Y: np.ndarray
    positions: np.ndarray
    relax: bool
    names: Sequence[tuple[str, str]] = ()


class _NonFinite(Exception):
    """A loop output became NaN or infinite in a sweep: its (component, variable) and value."""

    def __init__(self, name: tuple[str, str], value: float):
        super().__init__(name)
        self.name, self.value = name, value


class _Converged(Exception):
    """A sweep inside Newton's method passed the sweep test: ends ``scipy.optimize.root`` there."""

    def __init__(self, residual: float):
        super().__init__(residual)
        self.residual = residual


class LoopSolver:
    """Solves the algebraic loops of a plan at one communication point (see the module docstring).
    ``sequence``: the components in sweep order, to name the first one with a non-finite output."""

    def __init__(self, loops: Sequence[AlgebraicLoop], watched: Sequence[Watched], settings: LoopSettings,
                 sequence: Sequence[str] = ()):
        self.loops = list(loops)
        self.watched = [w for w in watched if len(w.positions)]
        self.settings = settings
        self.newton = settings.method == "newton" and all(w.relax for w in self.watched)
        names = [n for w in self.watched for n in (w.names or [("?", "?")] * len(w.positions))]
        rank = {c: i for i, c in enumerate(sequence)}
        self._names = names
        self._by_sweep_order = sorted(range(len(names)), key=lambda i: rank.get(names[i][0], 0))
        self.solves = 0
        self.iterations_total = 0
        self.iterations_max = 0
        self.residual_max = 0.0
        self.newton_solves = 0
        self.fallbacks = 0
        #: the last solve needed Newton: judge after one sweep, not `_SWEEPS_BEFORE_JUDGING`
        self._prefer_newton = False

    # ----------------------------------------------------------------- values

    def _values(self) -> np.ndarray:
        return np.concatenate([w.Y[w.positions].astype(float) for w in self.watched]) if self.watched \
            else np.zeros(0)

    def _write(self, x: np.ndarray) -> None:
        k = 0
        for w in self.watched:
            n = len(w.positions)
            w.Y[w.positions] = x[k:k + n]
            k += n

    def _finite(self, values: np.ndarray) -> np.ndarray:
        bad = ~np.isfinite(values)
        if bad.any():
            i = next(i for i in self._by_sweep_order if bad[i])
            raise _NonFinite(self._names[i], float(values[i]))
        return values

    def _residual(self, current: np.ndarray, previous: np.ndarray) -> float:
        s = self.settings
        if not len(current):
            return 0.0
        return float(np.max(np.abs(current - previous) / (s.atol + s.rtol * np.abs(current))))

    # ----------------------------------------------------------------- solving

    def solve(self, t: float, sweep: Callable[[float], None]) -> tuple[int, float]:
        """Sweep (and, where it pays, Newton) until the loop outputs settle; returns the sweeps and
        the last scaled residual (max |Δy| / (atol + rtol·|y|), at most 1 on success)."""
        self._t, self._sweep, self._sweeps = t, sweep, 0
        try:
            x = self._finite(self._values())
            return self._fixed_point(x, self.settings.max_iterations, judge=self.newton)
        except _NonFinite as e:
            raise self._non_finite_error(e) from None

    def _evaluate(self, x: np.ndarray | None = None) -> np.ndarray:
        """One sweep (from ``x`` written into the loop outputs, if given): the loop outputs after it."""
        if x is not None:
            self._write(x)
        self._sweep(self._t)
        self._sweeps += 1
        return self._finite(self._values())

    def _fixed_point(self, x: np.ndarray, budget: int, judge: bool, why: str = "") -> tuple[int, float]:
        """Sweeps from ``x`` (the values in the buffers) for at most ``budget`` of them; with
        ``judge``, hands over to `_newton` when it pays."""
        s = self.settings
        residuals: list[float] = []
        best = (math.inf, x, x)  # the smallest residual so far, its point and that point's sweep
        residual = math.inf
        for _ in range(budget):
            try:
                current = self._evaluate()
            except _NonFinite as e:
                if not (judge and self._sweeps > 1):
                    raise  # from the start values, not from a diverging iteration: the FMU's
                return self._newton(*best[1:], f"the sweeps diverged ({'.'.join(e.name)} became {e.value})")
            residual = self._residual(current, x)
            if residual <= 1.0:
                self._prefer_newton = False
                return self._converged(residual)
            residuals.append(residual)
            if residual < best[0]:
                best = (residual, x, current)
            if judge and (self._prefer_newton or _newton_pays(residuals, len(x))):
                return self._newton(*best[1:], "")
            if s.relaxation != 1.0:
                current = np.where(self._relaxed_mask(), x + s.relaxation * (current - x), current)
                self._write(current)
            x = current
        raise self._not_converged(residual, why)

    def _relaxed_mask(self) -> np.ndarray:
        return np.concatenate([np.full(len(w.positions), w.relax) for w in self.watched])

    def _newton(self, x0: np.ndarray, y0: np.ndarray, why: str) -> tuple[int, float]:
        """g(y) − y = 0 by MINPACK hybrd from ``x0`` (``y0`` = g(x0), known from a sweep), ended by
        the first point that passes the
        sweep test; if none does, the fixed point from hybrd's answer (or from ``x0`` when hybrd
        reached a non-finite value) for the sweeps left."""
        from scipy.optimize import root

        s = self.settings

        def f(x: np.ndarray) -> np.ndarray:
            x = np.array(x, dtype=float)
            y = y0 if np.array_equal(x, x0) else self._evaluate(x)
            residual = self._residual(y, x)
            if residual <= 1.0:  # the sweep test, at any point hybrd tries: done, y in the buffers
                raise _Converged(residual)
            return y - x

        try:
            sol = root(f, x0, method="hybr", options={"xtol": 1e-15, "maxfev": s.max_iterations * (len(x0) + 1)})
            failure = f"Newton's method did not pass the sweep test ({' '.join(sol.message.split())})"
            x = self._evaluate(np.array(sol.x, dtype=float))  # hybrd's answer, in the buffers
        except _Converged as done:
            self.newton_solves += 1
            self._prefer_newton = True  # the next point starts Newton after one sweep
            return self._converged(done.residual)
        except _NonFinite as e:
            failure = f"Newton's method reached a point where {'.'.join(e.name)} is {e.value}"
            x = self._evaluate(x0)  # back to the start point, in the buffers
        self.fallbacks += 1
        left = max(1, s.max_iterations - self._sweeps)
        return self._fixed_point(x, left, judge=False, why="; ".join(w for w in (why, failure) if w))

    def _converged(self, residual: float) -> tuple[int, float]:
        self.solves += 1
        self.iterations_total += self._sweeps
        self.iterations_max = max(self.iterations_max, self._sweeps)
        self.residual_max = max(self.residual_max, residual)
        return self._sweeps, residual

    def _not_converged(self, residual: float, why: str) -> RunError:
        s = self.settings
        t = self._t
        loops = "; ".join(loop.describe() for loop in self.loops)
        newton = f" {why};" if why else ""
        return RunError(f"the algebraic loop did not converge at t = {t:g}: after {self._sweeps} iterations the "
                       f"loop outputs still change by {residual:.3g} times the tolerance (rtol {s.rtol:g}, atol "
                       f"{s.atol:g}, relaxation {s.relaxation:g});{newton} loop: {loops}.", time=t,
                       component=", ".join(c for loop in self.loops for c in loop.components),
                       element="algebraic loop",
                       hint="Lower the relaxation factor (--relaxation 0.5), allow more iterations "
                            "(--loop-iterations), or break the loop by one step of delay (--loops delay).")

    def _non_finite_error(self, e: _NonFinite) -> RunError:
        component, variable = e.name
        where = (f"in iteration {self._sweeps} of the algebraic loop, from finite inputs" if self._sweeps
                 else "read after the step, before the algebraic loop iteration")
        return RunError(f"output '{variable}' is {e.value} at t = {self._t:g} "
                        f"({where}); loop: "
                        + "; ".join(loop.describe() for loop in self.loops) + ".", time=self._t,
                        component=component, element=f"component '{component}'")

    def metadata(self) -> dict:
        return {"mode": "iterate", "loops": [loop.describe() for loop in self.loops], **asdict(self.settings),
                "method": METHODS[self.settings.method] if self.newton else METHODS["fixed-point"],
                "solves": self.solves, "iterations_total": self.iterations_total,
                "iterations_max": self.iterations_max, "residual_max": self.residual_max,
                "newton_solves": self.newton_solves, "fallbacks": self.fallbacks}


def _newton_pays(residuals: list[float], n: int) -> bool:
    """After `_SWEEPS_BEFORE_JUDGING` sweeps: the sweeps diverge, or the last residual ratio ρ
    predicts more sweeps to converge (log r / log(1/ρ)) than a Newton solve costs (a
    finite-difference Jacobian, n + 1 sweeps, and a few steps)."""
    if len(residuals) < _SWEEPS_BEFORE_JUDGING:
        return False
    rho = residuals[-1] / residuals[-2] if residuals[-2] > 0 else 0.0
    if rho >= 1.0:
        return True
    if rho == 0.0:
        return False
    return math.log(residuals[-1]) / -math.log(rho) > n + 3
