"""Two-input four-tank benchmark of Pan, Shen & Luh (2012) (seed 003), §5.1, (40)–(42).

The paper writes the plant both as the ODE (40) and as the discrete maps (41)–(42) with unit
coefficient on h_i(k−1), i.e. the forward-Euler map of (40) at one-second steps:

    h_1(k) = h_1(k−1) − 2.82 √h_1(k−1) + c(k) (2.256 √h_3(k−d) + 0.564 √h_4(k−d))
    h_2(k) = h_2(k−1) − 2.82 √h_2(k−1) + c(k) (0.564 √h_3(k−d) + 2.256 √h_4(k−d))
    h_3(k) = h_3(k−1) − 2.82 √h_3(k−1) + 15.12 u_1(k−1)
    h_4(k) = h_4(k−1) − 2.82 √h_4(k−1) + 15.12 u_2(k−1)

with c = 1, d = 1 up to step ``k_change`` = 500 and then the ramp c(k) = 1 − 0.0005 (k − 500)
and the delay d = 450 ((41)–(42); the paper's ``1 − 0.0005·k`` read as starting at step 500,
where it says both changes start, so c is continuous).  The literal (41), c(k) = 1 − 0.0005·k
from step 500 on (a jump from 1 to 0.75 at the change), is ``ramp_origin = 0``.  Table 1's local poles 0.41–0.74 are
those of this map at levels 6–29 (1 − 1.41/√h), which is why we integrate the map the paper
prints rather than the ODE.  Levels are clamped at 0 under the square roots.  The delayed
√h_3, √h_4 are held in :class:`~greyfmu.plants.delay.DelayLine` s (they are piecewise constant
between steps of the map).  recovered-models.md §5 (the coefficients fit Johansson's quadruple
tank with k = 2.82 and γ = 0.8).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from greyfmu.plants.delay import DelayLine

OUTFLOW = 2.82
DIRECT = 2.256
CROSS = 0.564
PUMP = 15.12


def equilibrium_levels(u1: float, u2: float) -> NDArray[np.float64]:
    """Steady levels of (40) for constant inputs (c = 1): √h_3 = 15.12 u_1 / 2.82, …"""
    s3, s4 = PUMP * u1 / OUTFLOW, PUMP * u2 / OUTFLOW
    s1 = (DIRECT * s3 + CROSS * s4) / OUTFLOW
    s2 = (CROSS * s3 + DIRECT * s4) / OUTFLOW
    return np.array([s1, s2, s3, s4]) ** 2


class FourTank:
    """Discrete four-tank plant (41)–(42) with sample period ``Ts`` (1 s in the paper).

    ``step(u1, u2)`` advances one sample and returns the levels h(k).  ``k_change`` is the
    step where the ramp and the delay change start, ``ramp`` the coefficient slope (0.0005 per
    step), ``ramp_origin`` the step at which the ramp line passes through c = 1 (default
    ``k_change``: c continuous; 0: the literal 1 − 0.0005·k of (41)), ``delay`` the input delay
    after the change (450 steps).
    """

    def __init__(
        self,
        h0: ArrayLike | None = None,
        Ts: float = 1.0,
        k_change: int = 500,
        ramp: float = 0.0005,
        delay: int = 450,
        time_varying: bool = True,
        ramp_origin: int | None = None,
    ) -> None:
        if not (math.isfinite(Ts) and Ts > 0.0):
            raise ValueError(f"FourTank: sample period Ts must be a finite number > 0, got {Ts}")
        if delay < 1:
            raise ValueError(f"FourTank: delay must be >= 1 step, got {delay}")
        self.h0 = equilibrium_levels(0.7, 0.7) if h0 is None else np.asarray(h0, dtype=float)
        if self.h0.shape != (4,) or np.any(self.h0 < 0.0):
            raise ValueError(f"FourTank: h0 must be four levels >= 0, got {h0}")
        self.Ts = Ts
        self.k_change = k_change
        self.ramp = ramp
        self.ramp_origin = k_change if ramp_origin is None else ramp_origin
        self.delay = delay
        self.time_varying = time_varying
        self.reset()

    def reset(self) -> None:
        """Back to the levels h0 at k = 0."""
        self.h = self.h0.copy()
        self.k = 0
        self._root3 = DelayLine(math.sqrt(self.h0[2]))
        self._root4 = DelayLine(math.sqrt(self.h0[3]))

    def coefficient(self, k: int) -> float:
        """c(k) of (41)–(42)."""
        if not self.time_varying or k <= self.k_change:
            return 1.0
        return 1.0 - self.ramp * (k - self.ramp_origin)

    def input_delay(self, k: int) -> int:
        """d(k): 1 step, then ``delay`` steps after ``k_change``."""
        return self.delay if self.time_varying and k > self.k_change else 1

    def step(self, u1: float, u2: float) -> NDArray[np.float64]:
        """h(k+1) from h(k) and u(k); returns the new levels."""
        k = self.k + 1
        roots = np.sqrt(np.maximum(self.h, 0.0))
        self._root3.push(self.k, roots[2])
        self._root4.push(self.k, roots[3])
        d = self.input_delay(k)
        s3 = next(self._root3.segments(k, 0.0, d))[1]
        s4 = next(self._root4.segments(k, 0.0, d))[1]
        c = self.coefficient(k)
        h = self.h.copy()
        h[0] += -OUTFLOW * roots[0] + c * (DIRECT * s3 + CROSS * s4)
        h[1] += -OUTFLOW * roots[1] + c * (CROSS * s3 + DIRECT * s4)
        h[2] += -OUTFLOW * roots[2] + PUMP * u1
        h[3] += -OUTFLOW * roots[3] + PUMP * u2
        self.h = np.maximum(h, 0.0)
        self.k = k
        self._root3.prune(k + 1, max(self.delay, 1))
        self._root4.prune(k + 1, max(self.delay, 1))
        return self.h.copy()
