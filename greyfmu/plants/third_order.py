"""Third-order plant with a zero and dead time, integrated exactly for piecewise-constant input."""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from greyfmu.plants.delay import DelayLine

_CACHE_SIZE = 64
"""Discretisations kept per plant (the step lengths of a run are few: h and the delay's splits)."""


class ThirdOrderPlant:
    """``H(s) = K (1 − T4 s) e^{−τ s} / ((T1 s + 1)(T2 s + 1)(T3 s + 1))``, input ``u + d``.

    The test process of Cîrtoaje et al. (paper §3) with K = 1.2, T1 = 90 s, T2 = 60 s,
    T3 = 50 s, τ = 90 s; T4 = 0 is the minimum-phase case of Figs. 3-10, T4 = 60 s the
    non-minimum-phase one of Fig. 11.  ``d`` is a load disturbance entering with the input.

    Realisation: three first-order lags in series, ``T1 ẋ1 = v − x1``, ``T2 ẋ2 = x1 − x2``,
    ``T3 ẋ3 = x2 − x3`` with ``v(t) = (u + d)(t − τ)``, and ``y = K (x3 − T4 ẋ3)``.  The output
    depends on the state only (strictly proper), so it has no direct feedthrough.
    ``advance(t, h, u, d)`` holds u + d from t on, splits ``[t, t + h]`` where the delayed
    input switches (``DelayLine``) and solves each piece exactly with the zero-order-hold
    transition ``[[Φ, Γ], [0, 1]] = expm([[A, B], [0, 0]]·Δ)``: for piecewise-constant input
    the result at every communication point is the analytic response, whatever the step.
    Before the start the input is the equilibrium ``y0/K``.
    """

    def __init__(
        self,
        K: float = 1.2,
        T1: float = 90.0,
        T2: float = 60.0,
        T3: float = 50.0,
        T4: float = 0.0,
        tau: float = 90.0,
        y0: float = 0.0,
    ) -> None:
        if not (math.isfinite(K) and K != 0.0):
            raise ValueError(f"ThirdOrderPlant: gain K must be a finite nonzero number, got {K}")
        for name, value in (("T1", T1), ("T2", T2), ("T3", T3)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ThirdOrderPlant: time constant {name} must be a finite number > 0 s, got {value}")
        if not math.isfinite(T4):
            raise ValueError(f"ThirdOrderPlant: zero time constant T4 must be finite, got {T4}")
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ValueError(f"ThirdOrderPlant: dead time tau must be a finite number >= 0 s, got {tau}")
        if not math.isfinite(y0):
            raise ValueError(f"ThirdOrderPlant: initial output y0 must be finite, got {y0}")
        self.K, self.T1, self.T2, self.T3, self.T4, self.tau, self.y0 = K, T1, T2, T3, T4, tau, y0
        self.A = np.array([[-1 / T1, 0.0, 0.0], [1 / T2, -1 / T2, 0.0], [0.0, 1 / T3, -1 / T3]])
        self.B = np.array([1 / T1, 0.0, 0.0])
        self.C = K * (np.array([0.0, 0.0, 1.0]) - T4 * self.A[2])
        self._transitions: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._inputs = DelayLine(y0 / K)
        self.reset()

    @property
    def y(self) -> float:
        """Plant output at the end of the last step."""
        return float(self.C @ self.x)

    def transition(self, duration: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact ZOH pair (Φ, Γ) over ``duration``: x(t + Δ) = Φ x(t) + Γ v for v held."""
        pair = self._transitions.get(duration)
        if pair is None:
            M = np.zeros((4, 4))
            M[:3, :3] = self.A
            M[:3, 3] = self.B
            E = expm(M * duration)
            pair = (E[:3, :3], E[:3, 3])
            if len(self._transitions) >= _CACHE_SIZE:
                self._transitions.clear()
            self._transitions[duration] = pair
        return pair

    def advance(self, t: float, h: float, u: float, d: float = 0.0) -> float:
        """Integrate over ``[t, t + h]`` with input ``u`` and load ``d`` held from ``t``; return ``y(t + h)``."""
        if h < 0.0:
            raise ValueError(f"ThirdOrderPlant: step h must be >= 0, got {h}")
        self._inputs.push(t, u + d)
        for duration, delayed in self._inputs.segments(t, h, self.tau):
            if duration > 0.0:
                Phi, Gamma = self.transition(duration)
                self.x = Phi @ self.x + Gamma * delayed
        self._inputs.prune(t + h, self.tau)
        return self.y

    def reset(self) -> None:
        """Back to the equilibrium at y0 (input y0/K on all of the past)."""
        self.x = np.full(3, self.y0 / self.K)
        self._inputs.reset()
