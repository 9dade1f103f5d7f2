"""Discrete LQ regulator with every closed-loop eigenvalue inside a disc: Lee & Lee (1986),
Zhou et al. (2006) Lemma 1 (23)-(27), recovered-models.md §4.

With ``G_αβ = (G − βI)/α`` and ``H_α = H/α`` the LQ gain of the fictitious system
``(G_αβ, H_α)`` makes ``ρ(G_αβ − H_α K) < 1``, and ``G − HK = βI + α(G_αβ − H_α K)``, so every
eigenvalue of ``G − HK`` lies in the open disc ``|z − β| < α``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, solve_discrete_are

from greyfmu.control.digital_pi.errors import DesignError

def check_disc(alpha: float, beta: float) -> None:
    """The disc |z − β| < α must lie in the unit circle: α > 0 and α + |β| ≤ 1.

    The paper writes the strict α + |β| < 1 but uses α = 1, β = 0 (the ordinary LQR) in its
    Example 2; the open disc stays inside the open unit circle at equality, so equality is allowed.
    """
    if not (math.isfinite(alpha) and alpha > 0.0):
        raise DesignError(f"disc radius alpha must be a finite number > 0, got {alpha}")
    if not math.isfinite(beta) or alpha + abs(beta) > 1.0 + 1e-12:
        raise DesignError(f"alpha + |beta| must be <= 1 for the disc |z - beta| < alpha to lie in the unit "
                          f"circle, got alpha = {alpha}, beta = {beta}")


def check_weights(Q: np.ndarray, R: np.ndarray, n: int, m: int) -> None:
    """Q = Qᵀ ≥ 0 (n×n) and R = Rᵀ > 0 (m×m), as Lemma 1 (25) requires."""
    if Q.shape != (n, n):
        raise DesignError(f"Q must be {n}x{n} (the order of the cascaded system (17)), got {Q.shape}")
    if R.shape != (m, m):
        raise DesignError(f"R must be {m}x{m}, got {R.shape}")
    if not (np.allclose(Q, Q.T) and np.linalg.eigvalsh((Q + Q.T) / 2).min() >= -1e-10 * max(1.0, np.abs(Q).max())):
        raise DesignError("Q must be symmetric positive semi-definite")
    if not (np.allclose(R, R.T) and np.linalg.eigvalsh((R + R.T) / 2).min() > 0.0):
        raise DesignError("R must be symmetric positive definite")


def uncontrollable_modes(G: np.ndarray, H: np.ndarray, outside: float = 1.0) -> list[complex]:
    """Eigenvalues λ of G with |λ| ≥ ``outside`` that the input cannot move (PBH: rank [λI − G, H] < n)."""
    n = G.shape[0]
    modes = []
    for lam in np.linalg.eigvals(G):
        if abs(lam) >= outside - 1e-9:
            pbh = np.hstack([lam * np.eye(n) - G, H.astype(complex)])
            if np.linalg.matrix_rank(pbh, tol=1e-9 * max(1.0, np.abs(pbh).max())) < n:
                modes.append(complex(lam))
    return modes


@dataclass(frozen=True)
class DiscLQR:
    """Lemma 1's solution: gain K (27), Riccati solution P (26), and how well both are known.

    ``backward_error`` = ‖residual of (26)‖₂ / (‖G_αβ‖₂²‖P‖₂ + ‖P‖₂ + ‖Q‖₂), reported, not a
    refusal criterion: with long delays and a small disc P is ill-conditioned (cond 1e14 for the
    CH-47 at α = 0.2, β = 0.7, backward error 1.5e-4 for Wood–Berry) while the gain still puts
    every pole in the disc, which is what the Lemma promises and what is checked.
    ``disc_radius`` = max |z − β|/α over the closed-loop poles (< 1: all in the disc).
    """

    K: np.ndarray
    P: np.ndarray
    backward_error: float
    disc_radius: float


def dlqr_disc(G: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray,
              alpha: float = 1.0, beta: float = 0.0) -> DiscLQR:
    """Gain K of ``u = −K x`` minimising (25) with every eigenvalue of ``G − HK`` in ``|z − β| < α``.

    Accepts the gain when every closed-loop pole lies in the disc and reports the Riccati
    residual with it (`DiscLQR`).  Refuses, naming the condition: a disc outside the unit circle,
    Q not ≥ 0, R not > 0, (G_αβ, H_α) not stabilisable, (Q^{1/2}, G_αβ) not detectable, a DARE
    the solver cannot solve or solves with non-finite entries, or a gain that leaves a pole on
    or outside the disc (with the pole radius and the residual in the message).
    """
    G, H, Q, R = (np.atleast_2d(np.asarray(M, dtype=float)) for M in (G, H, Q, R))
    n, m = H.shape
    check_disc(alpha, beta)
    check_weights(Q, R, n, m)
    G_ab = (G - beta * np.eye(n)) / alpha
    H_a = H / alpha
    stuck = uncontrollable_modes(G_ab, H_a)
    if stuck:
        outside = [beta + alpha * lam for lam in stuck]
        raise DesignError(f"(G_ab, H_a) is not stabilisable: modes {np.round(outside, 6).tolist()} of G cannot be "
                          f"moved into the disc |z - {beta}| < {alpha}")
    w, U = np.linalg.eigh((Q + Q.T) / 2)
    Q_half = (U * np.sqrt(np.clip(w, 0.0, None))) @ U.T
    hidden = uncontrollable_modes(G_ab.T, Q_half.T)
    if hidden:
        raise DesignError(f"(Q^1/2, G_ab) is not detectable: modes {np.round(hidden, 6).tolist()} of G_ab on or "
                          "outside the unit circle are not weighted by Q")
    try:
        P = solve_discrete_are(G_ab, H_a, Q, R)
    except (LinAlgError, ValueError) as error:
        raise DesignError(f"the discrete Riccati equation (26) did not converge: {error}") from error
    if not np.all(np.isfinite(P)):
        raise DesignError("the discrete Riccati equation (26) did not converge: non-finite solution")
    S = R + H_a.T @ P @ H_a
    K = np.linalg.solve(S, H_a.T @ P @ G_ab)                          # (27)
    residual = G_ab.T @ P @ G_ab - G_ab.T @ P @ H_a @ K - P + Q       # (26)
    norm_P = np.linalg.norm(P, 2)
    backward_error = float(np.linalg.norm(residual, 2) / (np.linalg.norm(G_ab, 2) ** 2 * norm_P + norm_P
                                                           + np.linalg.norm(Q, 2)))
    radius = float(np.abs(np.linalg.eigvals(G_ab - H_a @ K)).max())   # = max |z − β|/α of G − HK
    if not radius < 1.0:
        raise DesignError(f"the Riccati solution leaves a closed-loop pole outside the disc |z - {beta}| < {alpha}: "
                          f"max |z - beta|/alpha = {radius:.6g} (Riccati backward error {backward_error:.3g})")
    return DiscLQR(K, P, backward_error, radius)
