"""The augmented plant (9)/(10) that absorbs the input delay, and its cascade with the PI state (16)-(17).

Augmented state ``X_a(k) = [x(k); u(k−1); u(k−2); …; u(k−D)]`` where D is the oldest input
sample any delay term needs (D = d when H1 ≠ 0, else d − 1).  For one delay with d = 1
this is (9) (``X_a = [x; u(k−1)]``), for d > 1 it is (10); with no delay (τ = 0) D = 0 and
the model is (11) unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.discretize import DiscretePlant


@dataclass(frozen=True)
class AugmentedPlant:
    """``X_a(k+1) = Gp X_a + Hp u + Γp η``, ``y = Cp X_a + η`` (9)/(10); ``lags`` = D input samples held."""

    Gp: np.ndarray
    Hp: np.ndarray
    Gammap: np.ndarray
    Cp: np.ndarray
    lags: int

    @property
    def order(self) -> int:
        return self.Gp.shape[0]


def oldest_lag(plant: DiscretePlant) -> int:
    """D: the oldest past input u(k − D) the delay terms use."""
    return max(term.d if np.any(term.H1) else term.d - 1 for term in plant.terms)


def augment_delay(plant: DiscretePlant) -> AugmentedPlant:
    """Build (9) (d = 1) or (10) (d > 1) from the discrete model (4); per-entry delays stack their terms."""
    n, m = plant.G.shape[0], plant.m
    D = oldest_lag(plant)
    lag_matrices = [np.zeros((n, m)) for _ in range(D + 1)]  # coefficient of u(k − j) in x(k + 1)
    for term in plant.terms:
        lag_matrices[term.d - 1] += term.H0
        if term.d <= D:
            lag_matrices[term.d] += term.H1
    size = n + D * m
    Gp = np.zeros((size, size))
    Gp[:n, :n] = plant.G
    for j in range(1, D + 1):
        Gp[:n, n + (j - 1) * m : n + j * m] = lag_matrices[j]
    for j in range(2, D + 1):  # u(k − j) at k + 1 is u(k − j + 1) at k
        Gp[n + (j - 1) * m : n + j * m, n + (j - 2) * m : n + (j - 1) * m] = np.eye(m)
    Hp = np.zeros((size, m))
    Hp[:n] = lag_matrices[0]
    if D:
        Hp[n : n + m] = np.eye(m)
    Gammap = np.zeros((size, plant.Gamma.shape[1]))
    Gammap[:n] = plant.Gamma
    Cp = np.hstack([plant.C, np.zeros((plant.C.shape[0], D * m))])
    return AugmentedPlant(Gp, Hp, Gammap, Cp, D)


def cascade_pi(aug: AugmentedPlant, Hc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(17): ``x̄ = [X_a; z]``, ``x̄(k+1) = Ḡ x̄ + H̄ u`` with the PI state ``z(k+1) = z + Hc e`` (16), Gc = I,
    and e = −Cp X_a (set-point response design, r = 0, no noise).  Returns (Ḡ, H̄)."""
    na, m = aug.Hp.shape
    q = Hc.shape[0]
    Gbar = np.block([[aug.Gp, np.zeros((na, q))], [-Hc @ aug.Cp, np.eye(q)]])
    Hbar = np.vstack([aug.Hp, np.zeros((q, m))])
    return Gbar, Hbar
