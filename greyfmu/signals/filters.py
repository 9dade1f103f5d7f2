"""First-order lag integrated exactly for piecewise-constant input."""

from __future__ import annotations

import math


class FirstOrderFilter:
    """``T dy/dt + y = K u`` with the input held constant over each step (exact ZOH solution).

    ``advance(h, u)`` returns ``y(t + h) = K u + (y(t) − K u)·exp(−h/T)``, exact for any h.
    """

    def __init__(self, T: float, K: float = 1.0, y0: float = 0.0) -> None:
        if not (math.isfinite(T) and T > 0.0):
            raise ValueError(f"FirstOrderFilter: time constant T must be a finite number > 0, got {T}")
        if not math.isfinite(K):
            raise ValueError(f"FirstOrderFilter: gain K must be finite, got {K}")
        if not math.isfinite(y0):
            raise ValueError(f"FirstOrderFilter: initial output y0 must be finite, got {y0}")
        self.T = T
        self.K = K
        self.y0 = y0
        self.y = y0

    def advance(self, h: float, u: float) -> float:
        """Integrate over a step of length ``h >= 0`` with input ``u`` held; return the new output."""
        if h < 0.0:
            raise ValueError(f"FirstOrderFilter: step h must be >= 0, got {h}")
        target = self.K * u
        self.y = target + (self.y - target) * math.exp(-h / self.T)
        return self.y

    def reset(self) -> None:
        self.y = self.y0
