"""Continuous LTI plant in innovation form with input delays, integrated exactly: Zhou et al. (2006) (1)-(2).

``dx/dt = A x + B u(t − τ) + V η(t)``, ``y = C x + η + d``.  η is a white sequence of covariance
Q_η held over the noise period (sample k on [t0 + k·Tη, t0 + (k+1)·Tη)), so at Tη = T the
sampled plant is exactly the discrete model (4) with Γ of (8).  d are step disturbances added
to the outputs.  τ is a number or one delay per entry of B.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from greyfmu.control.digital_pi.discretize import delay_groups, integral_expm
from greyfmu.plants.delay import DelayLine
from greyfmu.signals.clock import SampleClock


class StochasticLTI:
    """``advance(t, h, u, d)`` integrates [t, t + h] exactly with u held from t (zero-order hold), returns ``output(d)``.

    The step is split where any delayed input switches and where a new noise sample starts; each
    piece is solved with ``e^{Aδ}`` and ``∫_0^δ e^{As} ds`` (exact for singular A), so the result
    does not depend on the caller's step.  The plant starts at x = x0 with u = 0 before the start.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, V: np.ndarray, tau: float | np.ndarray = 0.0,
                 Q_eta: np.ndarray | None = None, noise_period: float = 1.0, seed: int = 0, t0: float = 0.0,
                 x0: np.ndarray | None = None) -> None:
        self.A, self.B, self.C, self.V = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (A, B, C, V))
        n, p = self.A.shape[0], self.C.shape[0]
        if self.A.shape != (n, n) or self.B.shape[0] != n or self.C.shape[1] != n or self.V.shape != (n, p):
            raise ValueError(f"StochasticLTI: shapes do not fit: A {self.A.shape}, B {self.B.shape}, "
                             f"C {self.C.shape}, V {self.V.shape}")
        tau_array = np.asarray(tau, dtype=float)
        if not np.all(np.isfinite(tau_array)) or np.any(tau_array < 0.0):
            raise ValueError(f"StochasticLTI: input delays must be finite and >= 0, got {tau_array.tolist()}")
        self.groups = delay_groups(self.B, tau)
        Q_eta = np.zeros((p, p)) if Q_eta is None else np.atleast_2d(np.asarray(Q_eta, dtype=float))
        if Q_eta.shape != (p, p) or not np.allclose(Q_eta, Q_eta.T) or np.linalg.eigvalsh(Q_eta).min() < -1e-12:
            raise ValueError(f"StochasticLTI: Q_eta must be a symmetric positive semi-definite {p}x{p} matrix")
        w, U = np.linalg.eigh(Q_eta)
        self._noise_factor = U * np.sqrt(np.clip(w, 0.0, None))
        self.noise_clock = SampleClock(noise_period, t0)
        self.seed = seed
        self.x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float)
        self._exponentials = self._exponential_cache()
        self.reset()

    def _exponential_cache(self):
        """``integral_expm(A, δ)`` per step piece δ, cached (the pieces repeat from step to step)."""
        return lru_cache(maxsize=256)(lambda delta: integral_expm(self.A, delta))

    def __getstate__(self) -> dict:
        """The state without the cache, which holds a closure (a copied or restored FMU state:
        fmus/_slave.py); `__setstate__` starts an empty one."""
        state = self.__dict__.copy()
        del state["_exponentials"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._exponentials = self._exponential_cache()

    def reset(self) -> None:
        """Back to x0 at t0 with empty input histories and the noise sequence from its start."""
        self.x = self.x0.copy()
        self._inputs = [DelayLine(0.0) for _ in range(self.B.shape[1])]
        self._rng = np.random.default_rng(self.seed)
        self._noise_index = -1
        self._noise = np.zeros(self.C.shape[0])
        self.time = self.noise_clock.t0

    def noise(self, t: float) -> np.ndarray:
        """η on the noise sample holding at t (samples are drawn in order; t never goes back)."""
        index = max(0, self.noise_clock.index_at(t))
        while self._noise_index < index:
            self._noise = self._noise_factor @ self._rng.standard_normal(self.C.shape[0])
            self._noise_index += 1
        return self._noise

    def output(self, d: np.ndarray | float = 0.0) -> np.ndarray:
        """Output at the current time with the output disturbance d: C x + η + d."""
        return self.C @ self.x + self.noise(self.time) + d

    @staticmethod
    def _value(line: DelayLine, s: float) -> float:
        """Value at time s of the held signal recorded in ``line``."""
        return next(line.segments(s, 0.0, 0.0))[1]

    def advance(self, t: float, h: float, u: np.ndarray, d: np.ndarray | float = 0.0) -> np.ndarray:
        """Integrate over [t, t + h] with the input u held from t; returns the output ``output(d)`` at t + h."""
        if h < 0.0:
            raise ValueError(f"StochasticLTI: step h must be >= 0, got {h}")
        u = np.asarray(u, dtype=float)
        for line, value in zip(self._inputs, u):
            line.push(t, float(value))
        cuts = {t, t + h}
        for delay, _ in self.groups:
            for line in self._inputs:
                start = t
                for duration, _ in line.segments(t, h, delay):
                    start += duration
                    cuts.add(min(start, t + h))
        cuts.update(self.noise_clock.time(k) for k in self.noise_clock.samples_in(t, h))
        edges = sorted(cuts)
        for a, b in zip(edges[:-1], edges[1:]):
            if b - a <= 1e-12 * max(1.0, abs(b)):
                continue
            middle = 0.5 * (a + b)
            drive = self.V @ self.noise(middle)
            for delay, B_delay in self.groups:
                drive = drive + B_delay @ np.array([self._value(line, middle - delay) for line in self._inputs])
            E, Phi = self._exponentials(round(b - a, 12))
            self.x = E @ self.x + Phi @ drive
        longest = max(delay for delay, _ in self.groups)
        for line in self._inputs:
            line.prune(t + h, longest)
        self.time = t + h
        return self.output(d)
