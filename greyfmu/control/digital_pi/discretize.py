"""Exact discretisation of the continuous plant (1) with input delay, Zhou et al. (2006) (3)-(8).

Plant (1): ``dx/dt = A x + B u(t − τ) + V η``, ``y = C x + η``.  The input delay may be one
number (the paper) or one delay per entry of B (``tau[i, j]`` delays ``u_j`` in row i), which
a transfer matrix with different dead times per element (Wood–Berry) needs.  Entries with
the same delay form one *delay term*; each term τ = (d − 1)Ts + τ', 0 < τ' ≤ Ts, γ = τ'/Ts (3)
contributes ``H0 u(k − d + 1) + H1 u(k − d)`` to x(k + 1) with (6)-(7).  τ = 0 is the limit
τ' = 0 (d = 1, γ = 0): H0 = H, H1 = 0, the delay-free model (11).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from greyfmu.control.digital_pi.errors import DesignError

DELAY_TOLERANCE = 1e-9
"""Fraction of a sample period within which a delay counts as a whole number of periods."""


@dataclass(frozen=True)
class ContinuousPlant:
    """The continuous innovation-form plant (1): matrices A (n×n), B (n×m), C (p×n), V (n×p)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    V: np.ndarray

    def __post_init__(self) -> None:
        A, B, C, V = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (self.A, self.B, self.C, self.V))
        n = A.shape[0]
        if A.shape != (n, n):
            raise DesignError(f"A must be square, got shape {A.shape}")
        if B.shape[0] != n or C.shape[1] != n or V.shape[0] != n:
            raise DesignError(f"shapes do not fit n = {n}: B {B.shape}, C {C.shape}, V {V.shape}")
        if V.shape[1] != C.shape[0]:
            raise DesignError(f"V must have one column per output (p = {C.shape[0]}), got shape {V.shape}")
        for name, M in zip("ABCV", (A, B, C, V)):
            if not np.all(np.isfinite(M)):
                raise DesignError(f"{name} has non-finite entries")
            object.__setattr__(self, name, M)

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @property
    def p(self) -> int:
        return self.C.shape[0]


@dataclass(frozen=True)
class DelayTerm:
    """One input-delay term of (4): ``x(k+1) += H0 u(k − d + 1) + H1 u(k − d)`` for a delay (d − 1)Ts + γTs."""

    d: int
    gamma: float
    H0: np.ndarray
    H1: np.ndarray


@dataclass(frozen=True)
class DiscretePlant:
    """The discrete model (4): ``x(k+1) = G x(k) + Σ_terms [H0 u(k−d+1) + H1 u(k−d)] + Γ η(k)``, ``y = C x + η``."""

    G: np.ndarray
    Gamma: np.ndarray
    C: np.ndarray
    terms: tuple[DelayTerm, ...]
    Ts: float

    @property
    def H(self) -> np.ndarray:
        """H = H0 + H1 summed over the terms: the delay-free input matrix of (11)."""
        return sum((term.H0 + term.H1 for term in self.terms), np.zeros((self.G.shape[0], self.m)))

    @property
    def m(self) -> int:
        return self.terms[0].H0.shape[1]

    def single_term(self) -> DelayTerm:
        """The one delay term of the paper's scalar-delay case (refused when delays differ per entry)."""
        if len(self.terms) != 1:
            raise DesignError(f"the plant has {len(self.terms)} different input delays, not one")
        return self.terms[0]


def split_delay(tau: float, Ts: float) -> tuple[int, float]:
    """(3): ``τ = (d − 1)Ts + τ'`` with 0 < τ' ≤ Ts; returns (d, γ = τ'/Ts).  τ = 0 gives (1, 0.0)."""
    if not (math.isfinite(Ts) and Ts > 0.0):
        raise DesignError(f"sample time Ts must be a finite number > 0, got {Ts}")
    if not (math.isfinite(tau) and tau >= 0.0):
        raise DesignError(f"input delay tau must be a finite number >= 0, got {tau}")
    periods = tau / Ts
    if periods <= DELAY_TOLERANCE:
        return 1, 0.0
    d = math.ceil(periods - DELAY_TOLERANCE * max(1.0, periods))
    return d, min(1.0, periods - (d - 1))


def integral_expm(A: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """``(e^{At}, ∫_0^t e^{As} ds)``: the second is ``(e^{At} − I)A^{-1}`` (5)-(8), and the series
    ``Σ_{i≥1} t^i/i! A^{i−1}`` the paper prescribes when A is singular.  Both come exactly from
    one exponential of the block matrix ``[[A, I], [0, 0]]·t``, singular A or not."""
    n = A.shape[0]
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = A
    block[:n, n:] = np.eye(n)
    E = expm(block * t)
    return E[:n, :n], E[:n, n:]


def delay_groups(B: np.ndarray, tau: float | np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Split B into ``[(delay, B_delay)]``: entries of B sharing one delay; a scalar tau gives one group."""
    tau_array = np.asarray(tau, dtype=float)
    if tau_array.ndim == 0:
        return [(float(tau_array), B)]
    if tau_array.shape != B.shape:
        raise DesignError(f"tau must be a number or have the shape of B {B.shape}, got {tau_array.shape}")
    delays = sorted({float(v) for v, b in zip(tau_array.ravel(), B.ravel()) if b != 0.0}) or [0.0]
    return [(delay, np.where(tau_array == delay, B, 0.0)) for delay in delays]


def c2d(plant: ContinuousPlant, Ts: float, tau: float | np.ndarray = 0.0) -> DiscretePlant:
    """Discretise (1) at sample time Ts with zero-order hold: G (5), H0 (6), H1 (7), Γ (8) per delay term."""
    split_delay(0.0, Ts)                           # validates Ts
    G, Phi_T = integral_expm(plant.A, Ts)
    terms = []
    for delay, B_delay in delay_groups(plant.B, tau):
        d, gamma = split_delay(delay, Ts)
        _, Phi_early = integral_expm(plant.A, (1.0 - gamma) * Ts)
        H0 = Phi_early @ B_delay                  # (6): (G^{1−γ} − I) A^{-1} B
        H1 = (Phi_T - Phi_early) @ B_delay        # (7): (G − G^{1−γ}) A^{-1} B
        terms.append(DelayTerm(d, gamma, H0, H1))
    Gamma = Phi_T @ plant.V                       # (8): (G − I) A^{-1} V
    return DiscretePlant(G, Gamma, plant.C, tuple(terms), Ts)
