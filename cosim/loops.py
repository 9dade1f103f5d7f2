"""Algebraic loops of direct feedthrough, solved at a communication point by iteration.

A loop (`cosim.structure.AlgebraicLoop`) is a set of outputs that depend on each other
at the same instant through the inputs they feed: y = g(y) at that instant, g being
"route the outputs to the inputs, set them, read the outputs again".  FMI 2.0 reads an
output without ``dependencies`` as depending on every input (§2.2.8), so plant FMUs
that omit them (20-sim's, and many others) close such loops wherever they are fed back.

`LoopSolver` solves y = g(y) by fixed-point iteration with relaxation, Gauss–Seidel
style: one iteration is the execution's settling sweep (``sweep``: each component of
the feedthrough sequence in dependency order, inputs routed and set, outputs read), so
inside a sweep each component sees the outputs its predecessors just computed; the
values carried from one sweep to the next (the loop's outputs, the tear variables) are
relaxed, y ← y_prev + ω (y − y_prev), Real ones only.  It stops when every loop output
changed by at most atol + rtol·|y| in the last sweep and fails, naming the loop, the time,
the iterations and the residual, when it has not after ``max_iterations`` sweeps.  The
start value of each solve is the solution at the previous communication point.

`cosim.plan.build_plan` with ``loops="delay"`` instead leaves the components on a loop out
of the settling: their outputs are read once per communication point, so each loop is
broken by one step of delay, as libcosim (which never reads dependencies) runs every
connection; the execution warns, naming the loop.

Kept apart from `cosim.execution` so a compiled stepping kernel can take the same interface:
``solve(t, sweep) -> (iterations, residual)`` over NumPy views of the exchange buffers.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .errors import RunError, SetupError
from .structure import AlgebraicLoop


@dataclass(frozen=True)
class LoopSettings:
    """How `LoopSolver` iterates: a loop output has converged when it changed by at most
    ``atol + rtol·|y|`` in one sweep; ``relaxation`` ω in (0, 1] (1: plain fixed point)."""
    rtol: float = 1e-10
    atol: float = 1e-12
    max_iterations: int = 100
    relaxation: float = 1.0

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


@dataclass
class Watched:
    """The loop outputs of one exchange type: a view of the exchange's output buffer and the
    positions of the loop outputs in it; ``relax``: Real values, relaxed between sweeps."""
    Y: np.ndarray
    positions: np.ndarray
    relax: bool


class LoopSolver:
    """Solves the algebraic loops of a plan at one communication point (see the module docstring)."""

    def __init__(self, loops: Sequence[AlgebraicLoop], watched: Sequence[Watched], settings: LoopSettings):
        self.loops = list(loops)
        self.watched = [w for w in watched if len(w.positions)]
        self.settings = settings
        self.solves = 0
        self.iterations_total = 0
        self.iterations_max = 0
        self.residual_max = 0.0

    def _values(self) -> list[np.ndarray]:
        return [w.Y[w.positions].astype(float) for w in self.watched]

    def solve(self, t: float, sweep: Callable[[float], None]) -> tuple[int, float]:
        """Sweep until the loop outputs settle; returns the sweeps and the last scaled residual
        (max |Δy| / (atol + rtol·|y|), at most 1 on success)."""
        s = self.settings
        previous = self._values()
        residual = math.inf
        for iteration in range(1, s.max_iterations + 1):
            sweep(t)
            current = self._values()
            residual = max((float(np.max(np.abs(c - p) / (s.atol + s.rtol * np.abs(c)))) for c, p in
                            zip(current, previous) if len(c)), default=0.0)
            if not math.isfinite(residual):
                break
            if residual <= 1.0:
                self.solves += 1
                self.iterations_total += iteration
                self.iterations_max = max(self.iterations_max, iteration)
                self.residual_max = max(self.residual_max, residual)
                return iteration, residual
            if s.relaxation != 1.0:
                for w, c, p in zip(self.watched, current, previous):
                    if w.relax:
                        c = p + s.relaxation * (c - p)
                        w.Y[w.positions] = c
            previous = current if s.relaxation == 1.0 else self._values()
        loops = "; ".join(loop.describe() for loop in self.loops)
        raise RunError(f"the algebraic loop did not converge at t = {t:g}: after {iteration} iterations the "
                       f"loop outputs still change by {residual:.3g} times the tolerance (rtol {s.rtol:g}, atol "
                       f"{s.atol:g}, relaxation {s.relaxation:g}); loop: {loops}.", time=t,
                       component=", ".join(c for loop in self.loops for c in loop.components),
                       element="algebraic loop",
                       hint="Lower the relaxation factor (--relaxation 0.5), allow more iterations "
                            "(--loop-iterations), or break the loop by one step of delay (--loops delay).")

    def metadata(self) -> dict:
        return {"mode": "iterate", "loops": [loop.describe() for loop in self.loops],
                "method": "fixed point (Gauss-Seidel sweeps) with relaxation", **asdict(self.settings),
                "solves": self.solves, "iterations_total": self.iterations_total,
                "iterations_max": self.iterations_max, "residual_max": self.residual_max}
