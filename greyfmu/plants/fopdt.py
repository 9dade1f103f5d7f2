"""First-order plus dead-time plant, integrated exactly for piecewise-constant input."""

from __future__ import annotations

import math

from greyfmu.plants.delay import DelayLine
from greyfmu.signals.filters import FirstOrderFilter


class FOPDT:
    """``T dx/dt + x = K·(u + d)(t − τ)``, ``y = x`` (Simulation 2.1's plant; with d, thesis (2.13a)).

    ``d`` is a load disturbance entering with the input.  ``advance(t, h, u, d)``
    integrates ``[t, t + h]`` with ``u`` and ``d`` applied (held) from ``t`` on.  The
    interval is split where the delayed input switches and each piece is solved exactly
    (zero-order hold), so for piecewise-constant input the result equals the analytic
    response at every communication point, whatever the step (h need not divide τ).
    Before the start the input u + d is taken as the equilibrium ``y0/K``.
    """

    def __init__(self, K: float, T: float, tau: float, y0: float = 0.0) -> None:
        if not (math.isfinite(K) and K != 0.0):
            raise ValueError(f"FOPDT: gain K must be a finite nonzero number, got {K}")
        if not (math.isfinite(T) and T > 0.0):
            raise ValueError(f"FOPDT: time constant T must be a finite number > 0, got {T}")
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ValueError(f"FOPDT: dead time tau must be a finite number >= 0, got {tau}")
        self.K = K
        self.T = T
        self.tau = tau
        self._lag = FirstOrderFilter(T, K, y0)
        self._inputs = DelayLine(y0 / K)

    @property
    def y(self) -> float:
        """Plant output at the end of the last step."""
        return self._lag.y

    def advance(self, t: float, h: float, u: float, d: float = 0.0) -> float:
        """Integrate over ``[t, t + h]`` with input ``u`` and load ``d`` held from ``t``; return ``y(t + h)``."""
        if h < 0.0:
            raise ValueError(f"FOPDT: step h must be >= 0, got {h}")
        self._inputs.push(t, u + d)
        for duration, delayed_u in self._inputs.segments(t, h, self.tau):
            self._lag.advance(duration, delayed_u)
        self._inputs.prune(t + h, self.tau)
        return self._lag.y

    def reset(self) -> None:
        """Back to the equilibrium at y0 (input y0/K on all of the past)."""
        self._lag.reset()
        self._inputs.reset()
