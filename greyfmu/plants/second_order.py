"""Second-order plant with dead time, integrated exactly for piecewise-constant input."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from greyfmu.plants.delay import DelayLine


@lru_cache(maxsize=64)
def _zoh(wn: float, zeta: float, K: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH transition Φ and input vector Γ of x = [y, ẏ] over a step h (augmented matrix exponential)."""
    augmented = np.zeros((3, 3))
    augmented[0, 1] = 1.0
    augmented[1, 0] = -wn * wn
    augmented[1, 1] = -2.0 * zeta * wn
    augmented[1, 2] = K * wn * wn
    transition = expm(augmented * h)
    return transition[:2, :2], transition[:2, 2]


class SecondOrder:
    """``ÿ/ω_n² + 2ζ·ẏ/ω_n + y = K·(u + d)(t − τ)``: the process (1) of Jukić & Božičević (seeds 002_*).

    Also the thesis's second-order processes K/(c2·s² + c1·s + 1) with ω_n = 1/√c2,
    ζ = c1/(2√c2): Simulation 3.4 (1/((1+40s)(1+20s)), 1/(1400s² + 30s + 1)) and (3.27a)
    (1/((1+30s)(1+5s))).  ``advance(t, h, u, d)`` splits the step where the delayed input
    switches and applies the exact zero-order-hold solution to each piece, so the output
    equals the analytic response at every communication point for any step.  The plant
    starts at rest at y0 (input y0/K before the start).
    """

    def __init__(self, K: float, wn: float, zeta: float, tau: float = 0.0, y0: float = 0.0) -> None:
        if not (math.isfinite(K) and K != 0.0):
            raise ValueError(f"SecondOrder: gain K must be a finite nonzero number, got {K}")
        if not (math.isfinite(wn) and wn > 0.0):
            raise ValueError(f"SecondOrder: natural frequency wn must be a finite number > 0, got {wn}")
        if not (math.isfinite(zeta) and zeta > 0.0):
            raise ValueError(f"SecondOrder: damping ratio zeta must be a finite number > 0, got {zeta}")
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ValueError(f"SecondOrder: dead time tau must be a finite number >= 0, got {tau}")
        if not math.isfinite(y0):
            raise ValueError(f"SecondOrder: initial output y0 must be finite, got {y0}")
        self.K, self.wn, self.zeta, self.tau, self.y0 = K, wn, zeta, tau, y0
        self._inputs = DelayLine(y0 / K)
        self._state = np.array([y0, 0.0])

    @property
    def y(self) -> float:
        """Plant output at the end of the last step."""
        return float(self._state[0])

    def advance(self, t: float, h: float, u: float, d: float = 0.0) -> float:
        """Integrate over ``[t, t + h]`` with input ``u`` and load ``d`` held from ``t``; return ``y(t + h)``."""
        if h < 0.0:
            raise ValueError(f"SecondOrder: step h must be >= 0, got {h}")
        self._inputs.push(t, u + d)
        for duration, delayed_u in self._inputs.segments(t, h, self.tau):
            if duration > 0.0:
                transition, gain = _zoh(self.wn, self.zeta, self.K, duration)
                self._state = transition @ self._state + gain * delayed_u
        self._inputs.prune(t + h, self.tau)
        return self.y

    def reset(self) -> None:
        """Back to rest at y0 (input y0/K on all of the past)."""
        self._inputs.reset()
        self._state = np.array([self.y0, 0.0])
