"""The Kalman innovation-form observer of Zhou et al. (2006) Example 1 / (47), and the innovation
model a plant's noise covariances give (Shieh et al., 1983).

In innovation form ``x(k+1) = G x + H u + Γ η``, ``y = C x + η`` the Kalman gain is Γ itself, so
the one-step predictor is ``x̂(k+1) = (G − ΓC) x̂ + H u + Γ y`` — no Riccati equation, no noise
covariances; it converges when G − ΓC is stable.  On the augmented plant (9)/(10) the delay
states are past inputs and are reproduced exactly.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

from greyfmu.control.digital_pi.augment import AugmentedPlant
from greyfmu.control.digital_pi.discretize import integral_expm
from greyfmu.control.digital_pi.errors import DesignError


def innovation_observer(aug: AugmentedPlant) -> np.ndarray:
    """Observer matrix ``Gp − Γp Cp``; refused when it is not stable (the predictor would diverge)."""
    Go = aug.Gp - aug.Gammap @ aug.Cp
    radius = np.abs(np.linalg.eigvals(Go)).max()
    if radius >= 1.0:
        raise DesignError(f"G - Gamma C has spectral radius {radius:.6g} >= 1: the innovation model is not "
                          "invertible and the Kalman innovation observer would diverge")
    return Go


def kalman_innovation(G: np.ndarray, C: np.ndarray, W: np.ndarray, Rv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Innovation form of ``x(k+1) = G x + w``, ``y = C x + v`` (cov w = W, cov v = Rv): the steady
    Kalman predictor gain Γ and the innovation covariance Q_η = C P Cᵀ + Rv."""
    P = solve_discrete_are(G.T, C.T, W, Rv)
    Q_eta = C @ P @ C.T + Rv
    Gamma = G @ P @ C.T @ np.linalg.inv(Q_eta)
    return Gamma, Q_eta


def continuous_noise_gain(A: np.ndarray, Ts: float, Gamma: np.ndarray) -> np.ndarray:
    """V of (1) whose discretisation (8) ``Γ = (G − I) A^{-1} V`` is the given Γ (η held over Ts)."""
    _, Phi = integral_expm(A, Ts)
    return np.linalg.solve(Phi, Gamma)
