"""GM(1,1): the first-order grey model of thesis 000_*, §3.1.2-§3.1.3, (3.5a)-(3.7b), Theorem 3.4.

For a positive sequence e0(1..n) with AGO e1 and background values Z (3.5b), the model is

    e0(k) + a·Z(k) = b,  k = 2..n                                        (3.5a)

fitted by least squares (Theorem 3.2) in the closed form (3.6a)/(3.6b).  Its solution

    ê1(k) = (e0(1) − b/a)·r^(k−1) + b/a,   r = (1 − 0.5a)/(1 + 0.5a),  |a| < 2     (3.7a)
    ê0(k) = ê1(k) − ê1(k−1) = [(b − a·e0(1))/(1 − 0.5a)]·r^(k−1),  k >= 2          (3.7b)

estimates the window's samples for k <= n and predicts them for k >= n + 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from greyfmu.grey.ago import finite_vector, ago, background
from greyfmu.grey.errors import GreyModelError

SINGULAR = 1e-12
"""C(i) of (3.6b) below this fraction of (n − 1)·ΣZ² counts as zero: the fit is singular."""


def gm11_coefficients(window: Sequence[float]) -> tuple[float, float] | None:
    """(a, b) of (3.6a)/(3.6b) for ``window`` = e0(1..n), n >= 3; None when C(i) is (numerically) zero.

    Plain floats, no checks: the hot path of `GreyPredictor`; `GM11.fit` validates and calls it.

        A = ΣZ·Σe0 − (n−1)·ΣZ·e0,  B = ΣZ²·Σe0 − ΣZ·ΣZ·e0,  C = (n−1)·ΣZ² − (ΣZ)²,  sums over k = 2..n
    """
    e1 = window[0]
    sum_z = sum_e = sum_zz = sum_ze = 0.0
    for e0 in window[1:]:
        z = e1 + 0.5 * e0
        e1 += e0
        sum_z += z
        sum_e += e0
        sum_zz += z * z
        sum_ze += z * e0
    n1 = len(window) - 1
    C = n1 * sum_zz - sum_z * sum_z
    if not C > SINGULAR * n1 * sum_zz:
        return None
    A = sum_z * sum_e - n1 * sum_ze
    B = sum_zz * sum_e - sum_z * sum_ze
    return A / C, B / C


def gm11_value(a: float, b: float, first: float, exponent: float) -> float:
    """ê0 of (3.7b) at k = exponent + 1: ``[(b − a·e0(1))/(1 − 0.5a)]·r^exponent`` (caller ensures |a| < 2)."""
    return (b - a * first) / (1.0 - 0.5 * a) * ((1.0 - 0.5 * a) / (1.0 + 0.5 * a)) ** exponent


@dataclass(frozen=True)
class GM11:
    """A fitted GM(1,1): development coefficient ``a``, grey input ``b``, the window's first sample and length."""

    a: float
    b: float
    first: float
    n: int

    @classmethod
    def fit(cls, seq: Sequence[float] | np.ndarray) -> GM11:
        """Least-squares fit (3.6a)/(3.6b) to ``seq`` = e0(1..n).

        Raises ValueError for fewer than 3 samples (n − 1 equations for 2 unknowns) or a
        non-finite sample, and `GreyModelError` when C(i) = 0 (the background values do not
        vary: e0(k) = 0 for k >= 2).  The thesis assumes positive, smooth data (Theorem 3.1);
        other data are fitted all the same.
        """
        x = finite_vector(seq, "GM11.fit")
        if x.size < 3:
            raise ValueError(f"GM11.fit: needs at least 3 samples (2 equations for a and b), got {x.size}")
        coefficients = gm11_coefficients(x.tolist())
        if coefficients is None:
            raise GreyModelError("GM11.fit: C(i) of (3.6b) is zero — the background values Z(k) do not vary")
        return cls(coefficients[0], coefficients[1], float(x[0]), int(x.size))

    @staticmethod
    def theorem34(seq: Sequence[float] | np.ndarray) -> tuple[float, float]:
        """(a, b) by the centred form of Theorem 3.4 (3.20a)-(3.20e) and (3.22): the cross-check of (3.6).

        ``a = A/C``, ``A = (e1(n) − e1(1))·Q``, ``Q = ΣZ − 0.5(n−1)(e1(n) + e1(1))``,
        ``C = (n−1)·Σ(Z − Z_ave)²``, ``b = B/C``, ``B = (e1(n) − e1(1))·Σ(Z − Z_ave)² + Z_ave·A``.
        """
        x = finite_vector(seq, "GM11.theorem34")
        if x.size < 3:
            raise ValueError(f"GM11.theorem34: needs at least 3 samples, got {x.size}")
        e1 = ago(x)
        z = background(e1)
        n1 = x.size - 1
        spread = float(np.sum((z - z.mean()) ** 2))
        if spread == 0.0:
            raise GreyModelError("GM11.theorem34: C(i) of (3.20d) is zero — the background values do not vary")
        rise = float(e1[-1] - e1[0])
        A = rise * (float(z.sum()) - 0.5 * n1 * float(e1[-1] + e1[0]))
        C = n1 * spread
        B = rise * spread + float(z.mean()) * A
        return A / C, B / C

    @property
    def r(self) -> float:
        """Ratio ``r = (1 − 0.5a)/(1 + 0.5a)`` of (3.7a); r > 1 for a rising sequence (Corollary 3.2)."""
        self._check_range()
        return (1.0 - 0.5 * self.a) / (1.0 + 0.5 * self.a)

    def predict(self, k: int | float | np.ndarray) -> float | np.ndarray:
        """ê0(k) by (3.7b) for k >= 2 (k <= n: estimate, k > n: prediction); ê0(1) = e0(1).

        Raises `GreyModelError` when |a| >= 2 (Remark 1: (3.7b) is not valid there).
        """
        self._check_range()
        k = np.asarray(k, dtype=float)
        value = np.where(k <= 1.0, self.first, gm11_value(self.a, self.b, self.first, k - 1.0))
        return float(value) if value.ndim == 0 else value

    def predict_ago(self, k: int | float | np.ndarray) -> float | np.ndarray:
        """ê1(k) by (3.7a), written ``e0(1) + (b − a·e0(1))·[(1 − r^(k−1))/a]`` so that a → 0 gives e0(1) + b·(k − 1)."""
        self._check_range()
        k = np.asarray(k, dtype=float)
        if self.a == 0.0:
            value = self.first + self.b * (k - 1.0)
        else:
            log_r = math.log1p(-self.a / (1.0 + 0.5 * self.a))
            value = self.first - (self.b - self.a * self.first) * np.expm1((k - 1.0) * log_r) / self.a
        return float(value) if np.ndim(value) == 0 else value

    def _check_range(self) -> None:
        if not abs(self.a) < 2.0:
            raise GreyModelError(f"GM(1,1): a = {self.a} outside |a| < 2, where (3.7a)/(3.7b) do not hold (Remark 1)")
