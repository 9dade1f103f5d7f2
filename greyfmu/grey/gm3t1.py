"""GM(3/t,1): second-order grey model and the constants k_s, ω_n, ζ of a second-order process.

Jukić & Božičević (2005), "Calculating the constants of the second-order process using grey
model GM(3/t,1)" (seeds 002_*).  The process (1) ``ÿ/ω_n² + 2ζ·ẏ/ω_n + y = k_s·x`` with a
step x = a is, in the measured samples x1(k) = y(k) ((2), (5)),

    α2(x1(k)) + a1·α1(x1(k)) + a2·z1(k) = b,  k = 2..n                              (8)
    α1(x1(k)) = x1(k) − x1(k−1),  α2(x1(k)) = α1(x1(k)) − α1(x1(k−1)),              (9), (10)
    z1(k) = 0.5·x1(k) + 0.5·x1(k−1),  x1(0) = 0,                                    (11), (6)

with a1 = 2ζω_n, a2 = ω_n², b = a·k_s·ω_n² (4) per sample interval.  θ = [a1 a2 b] is the
least-squares solution (12)-(16).  The row k = 2 uses x1(0) = 0 (the paper's (6)): the
output was 0 one sample before the first one.  ``x_before=None`` drops that row instead.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from greyfmu.grey.ago import finite_vector
from greyfmu.grey.errors import GreyModelError

RCOND = 1e-10
"""Singular values of the column-scaled regressor below this fraction of the largest count as zero."""


def equations(x1: np.ndarray, x_before: float | None = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Y (13) and B (14) of (12) for samples x1(1..n) along the last axis (one record or a stack of them).

    ``x_before`` is x1(0) (the paper's (6): 0), giving rows k = 2..n; None gives rows k = 3..n.
    Returns Y of shape (..., rows) and B of shape (..., rows, 3).  Raises `GreyModelError` for
    fewer than 3 rows.
    """
    x1 = np.asarray(x1, dtype=float)
    n = x1.shape[-1]
    first_row = 3 if x_before is None else 2
    if n - first_row + 1 < 3:
        raise GreyModelError(f"GM3t1.fit: {n} samples give {max(n - first_row + 1, 0)} equations for 3 unknowns")
    before = np.full(x1.shape[:-1] + (1,), 0.0 if x_before is None else x_before)
    padded = np.concatenate((before, x1), axis=-1)
    x0 = np.diff(padded, axis=-1)  # x0[..., k-1] = α1(x1(k)) = x1(k) − x1(k−1), k = 1..n   (6), (10)
    k = np.arange(first_row, n + 1)
    Y = x0[..., k - 1] - x0[..., k - 2]  # (9), (13)
    B = np.stack((-x0[..., k - 1], -0.5 * (padded[..., k] + padded[..., k - 1]), np.ones_like(Y)), axis=-1)  # (11), (14)
    return Y, B


def rounding_draws(samples: Sequence[float] | np.ndarray, resolution: float, draws: int, seed: int,
                   x_before: float | None = 0.0) -> np.ndarray:
    """θ = [a1, a2, b] by (16) for ``draws`` records uniformly within ±resolution/2 of the printed ``samples``.

    The question it answers: which θ could unrounded data behind a table printed to ``resolution``
    give?  Returns an array (draws, 3); the normal equations (16) are solved as printed.
    """
    printed = finite_vector(samples, "rounding_draws")
    rng = np.random.default_rng(seed)
    records = printed + rng.uniform(-0.5 * resolution, 0.5 * resolution, size=(draws, printed.size))
    Y, B = equations(records, x_before)
    normal = np.einsum("dki,dkj->dij", B, B)
    return np.linalg.solve(normal, np.einsum("dki,dk->di", B, Y)[..., None])[..., 0]


@dataclass(frozen=True)
class SecondOrderConstants:
    """k_s, ω_n, ζ of (1) from θ by (4), in the paper's sign convention (all three positive).

    ``k_s = b/(a·a2)``, ``ω_n = √a2 / Ts`` (``Ts`` = 1: per sample, as the paper reports),
    ``ζ = |a1|/(2√a2)``: the paper takes ω_n = −√a2 to compute ζ when a1 < 0 and reports
    ω_n = +√a2.  ``stable`` keeps the sign that convention hides: True when a1 > 0 and
    a2 > 0, i.e. the identified model's roots (of λ² + a1·λ + a2 = 0) are in the left half
    plane.  The paper's own θ has a1 < 0 (stable is False).
    """

    ks: float
    wn: float
    zeta: float
    stable: bool

    def roots(self) -> tuple[complex, complex]:
        """Roots ``λ1,2 = ω_n(−ζ ± √(ζ² − 1))`` of the characteristic equation of (1), (19); complex when ζ < 1."""
        root = cmath.sqrt(self.zeta * self.zeta - 1.0)
        return self.wn * (-self.zeta + root), self.wn * (-self.zeta - root)

    def dominant_response(self, t: float | np.ndarray, t1: float, y1: float, a: float) -> float | np.ndarray:
        """The paper's (20): ``y(t) = c·exp(λ1(t − t1)) + a·k_s`` with the fast root dropped and y(t1) = y1.

        Only for real roots (ζ >= 1); λ1 is the slow one.
        """
        if self.zeta < 1.0:
            raise GreyModelError(f"GM(3/t,1): (20) needs real roots, ζ = {self.zeta} < 1")
        slow = self.roots()[0].real
        level = a * self.ks
        return (y1 - level) * np.exp(slow * (np.asarray(t, dtype=float) - t1)) + level


@dataclass(frozen=True)
class GM3t1:
    """Identified θ = [a1, a2, b] of (8), per sample interval."""

    a1: float
    a2: float
    b: float

    @classmethod
    def fit(cls, samples: Sequence[float] | np.ndarray, x_before: float | None = 0.0) -> GM3t1:
        """Least squares (12)-(16) on ``samples`` = x1(1..n).

        ``x_before`` is x1(0) (the paper: 0); None uses the rows k = 3..n only.  The normal
        equations (16) are solved as a column-scaled least-squares problem (same solution,
        no squared condition number).  Raises ValueError for a non-finite sample and
        `GreyModelError` for too few rows (fewer than 3) or a rank-deficient regressor —
        constant data, or data without a second-order trace.
        """
        x1 = finite_vector(samples, "GM3t1.fit")
        if x_before is not None and not math.isfinite(x_before):
            raise ValueError(f"GM3t1.fit: x_before = {x_before} is not a finite number")
        Y, B = equations(x1, x_before)
        scale = np.linalg.norm(B, axis=0)
        if not np.all(scale > 0.0):
            raise GreyModelError("GM3t1.fit: a column of the regressor (14) is zero — the data have no dynamics")
        theta, _, rank, _ = np.linalg.lstsq(B / scale, Y, rcond=RCOND)
        if rank < 3:
            raise GreyModelError(
                "GM3t1.fit: the normal matrix BᵀB of (16) is singular — constant data or data without a second-order trace"
            )
        a1, a2, b = theta / scale
        return cls(float(a1), float(a2), float(b))

    def recursion(self, x1_first: float, x1_second: float, count: int) -> np.ndarray:
        """x̂1(1..count) by (17) from x̂1(1) = x1(1), x̂1(2) = x1(2).

        (17): ``x̂1(k) = [(2 + a1 − 0.5a2)·x̂1(k−1) − x̂1(k−2) + b] / (1 + a1 + 0.5a2)``.
        """
        d = 1.0 + self.a1 + 0.5 * self.a2
        if d == 0.0:
            raise GreyModelError("GM3t1.recursion: 1 + a1 + 0.5·a2 = 0, (17) is undefined")
        values = np.empty(count)
        values[:2] = x1_first, x1_second
        for k in range(2, count):
            values[k] = ((2.0 + self.a1 - 0.5 * self.a2) * values[k - 1] - values[k - 2] + self.b) / d
        return values

    def constants(self, a: float, Ts: float = 1.0) -> SecondOrderConstants:
        """k_s, ω_n, ζ by (4) for a step of height ``a``; ω_n per unit of ``Ts`` (Ts = 1: per sample).

        Raises `GreyModelError` when a2 <= 0 (no real ω_n) and ValueError for a = 0 or Ts <= 0.
        """
        if not (math.isfinite(a) and a != 0.0):
            raise ValueError(f"GM3t1.constants: step height a must be finite and nonzero, got {a}")
        if not (math.isfinite(Ts) and Ts > 0.0):
            raise ValueError(f"GM3t1.constants: sample interval Ts must be finite and > 0, got {Ts}")
        if not self.a2 > 0.0:
            raise GreyModelError(f"GM3t1.constants: a2 = {self.a2} <= 0 gives no natural frequency ω_n = √a2")
        root = math.sqrt(self.a2)
        return SecondOrderConstants(
            ks=self.b / (a * self.a2),
            wn=root / Ts,
            zeta=abs(self.a1) / (2.0 * root),
            stable=self.a1 > 0.0,
        )


class StepIdentifier:
    """Collects ``count`` samples of a process output after a step of height ``a`` and identifies (1).

    Sample 1 is taken at the step instant, where the process is still at rest at
    ``baseline`` (its output before the step; None: sample 1 itself); the fit uses the
    deviations y − baseline with x1(0) = 0, which is exact for a process at rest (the
    paper's (6)).  ``result`` is None
    until ``count`` samples are in; then it is the `SecondOrderConstants`, or None with
    ``error`` set when no valid model came out (singular fit, a2 <= 0, an unstable model
    a1 <= 0).
    """

    def __init__(self, a: float, count: int, Ts: float, baseline: float | None = None) -> None:
        if not (math.isfinite(a) and a != 0.0):
            raise ValueError(f"StepIdentifier: step height a must be finite and nonzero, got {a}")
        if not (isinstance(count, int) and count >= 4):
            raise ValueError(f"StepIdentifier: count must be an integer >= 4 (3 equations), got {count!r}")
        if not (math.isfinite(Ts) and Ts > 0.0):
            raise ValueError(f"StepIdentifier: sample interval Ts must be finite and > 0, got {Ts}")
        self.a = a
        self.count = count
        self.Ts = Ts
        self.baseline = baseline
        self.samples: list[float] = []
        self.model: GM3t1 | None = None
        self.result: SecondOrderConstants | None = None
        self.error = ""

    @property
    def done(self) -> bool:
        return len(self.samples) >= self.count

    def add(self, y: float) -> None:
        """Take the next sample; the fit runs when the last one arrives, later samples are ignored."""
        if self.done:
            return
        if not math.isfinite(y):
            raise ValueError(f"StepIdentifier: sample {len(self.samples) + 1} = {y} is not a finite number")
        if self.baseline is None:
            self.baseline = y
        self.samples.append(y - self.baseline)
        if self.done:
            self._identify()

    def _identify(self) -> None:
        try:
            self.model = GM3t1.fit(self.samples, x_before=0.0)
            constants = self.model.constants(self.a, self.Ts)
        except GreyModelError as error:
            self.error = str(error)
            return
        if not constants.stable:
            self.error = f"GM(3/t,1): a1 = {self.model.a1} <= 0, the identified model is not stable"
            return
        self.result = constants
