"""The paper's route to the Kalman gain: identify the ARMAX model (14) by extended least squares
from input/output data and read the gain off it, K_oi = D_i − G_oi — "no prior knowledge of noise
properties", no Riccati equation (Zhou et al. 2006, (12)-(14); Shieh, Wang & Tsay 1983).

Extended least squares (ELS, also called pseudo-linear regression; Ljung & Söderström 1983): recursive
least squares on the regressor

    φ(k) = [−y(k−1) … −y(k−na), u(k−1) … u(k−nb), ε(k−1) … ε(k−nc)]

in which the unmeasured innovations η(k−i) are replaced by the a-posteriori residuals
ε(k) = y(k) − θ(k)ᵀφ(k).  All outputs share φ, so one covariance P serves the p columns of θ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.companion import companion_matrix
from greyfmu.control.digital_pi.errors import DesignError


@dataclass(frozen=True)
class ARMAX:
    """(14): ``y(k) + Σ_{i≤na} A_i y(k−i) = Σ_{j≤nb} B_j u(k−j) + η(k) + Σ_{i≤nc} D_i η(k−i)``.

    Shapes: A (na, p, p) — the G_oi of (13); B (nb, p, m); D (nc, p, p).
    """

    A: np.ndarray
    B: np.ndarray
    D: np.ndarray

    def kalman_gain(self) -> np.ndarray:
        """K_o = [K_o1; …; K_or] with K_oi = D_i − G_oi (the paper, after (14)); needs na = nc = r."""
        if self.A.shape[0] != self.D.shape[0]:
            raise DesignError(f"K_oi = D_i - G_oi needs as many D_i as G_oi, got na = {self.A.shape[0]}, "
                              f"nc = {self.D.shape[0]}")
        return (self.D - self.A).reshape(-1, self.A.shape[1])

    def innovation_model(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(G_o, H_o, K_o, C_o)`` of ``x(k+1) = G_o x + H_o u + K_o η``, ``y = C_o x + η``: the block
        companion realisation (13) of order s·p, s = max(na, nb, nc), missing blocks zero.  With
        nb > na (input delay) the extra blocks carry the delayed inputs."""
        p, m = self.B.shape[1], self.B.shape[2]
        s = max(self.A.shape[0], self.B.shape[0], self.D.shape[0])
        A, B, D = (np.concatenate([X, np.zeros((s - X.shape[0],) + X.shape[1:])]) for X in (self.A, self.B, self.D))
        Go = companion_matrix(A)
        Co = np.hstack([np.eye(p), np.zeros((p, (s - 1) * p))])
        return Go, B.reshape(s * p, m), (D - A).reshape(s * p, p), Co


@dataclass(frozen=True)
class ELSResult:
    """The identified model and the a-posteriori residuals ε(k) (the innovation estimates)."""

    model: ARMAX
    residuals: np.ndarray


def extended_least_squares(y: np.ndarray, u: np.ndarray, na: int, nb: int, nc: int,
                           initial_covariance: float = 1e4) -> ELSResult:
    """Recursive ELS on the records ``y`` (N×p) and ``u`` (N×m), θ(0) = 0, P(0) = ``initial_covariance``·I,
    no forgetting.  na = nb = 0 identifies a moving average ``y = D(q) η`` (`noise_model_gain`).
    Raises `DesignError` for non-finite data, orders out of range or too few samples."""
    y, u = np.atleast_2d(np.asarray(y, dtype=float)), np.atleast_2d(np.asarray(u, dtype=float))
    N, p = y.shape
    m = u.shape[1]
    if u.shape[0] != N:
        raise DesignError(f"ELS: y has {N} samples, u has {u.shape[0]}")
    if min(na, nb) < 0 or nc < 1:
        raise DesignError(f"ELS: orders must be na, nb >= 0 and nc >= 1, got na = {na}, nb = {nb}, nc = {nc}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(u))):
        raise DesignError("ELS: the input/output records contain non-finite samples")
    size = p * na + m * nb + p * nc
    start = max(na, nb, nc)
    if N - start < 2 * size:
        raise DesignError(f"ELS: {N} samples are too few for {size} parameters per output (need > {2 * size + start})")
    theta = np.zeros((size, p))
    P = initial_covariance * np.eye(size)
    eps = np.zeros((N, p))
    for k in range(start, N):
        phi = np.concatenate([-y[k - na : k][::-1].ravel() if na else [], u[k - nb : k][::-1].ravel() if nb else [],
                              eps[k - nc : k][::-1].ravel()])
        Pphi = P @ phi
        gain = Pphi / (1.0 + phi @ Pphi)
        theta += np.outer(gain, y[k] - phi @ theta)
        P -= np.outer(gain, Pphi)
        eps[k] = y[k] - phi @ theta                                       # a-posteriori residual
    blocks = np.split(theta.T, [p * na, p * na + m * nb], axis=1)         # (p, ·) per polynomial
    A = blocks[0].reshape(p, na, p).transpose(1, 0, 2)
    B = blocks[1].reshape(p, nb, m).transpose(1, 0, 2)
    D = blocks[2].reshape(p, nc, p).transpose(1, 0, 2)
    return ELSResult(ARMAX(A, B, D), eps)


def els_convergence_margin(D: np.ndarray, points: int = 2001) -> float:
    """min over ω ∈ [0, π] of the smallest eigenvalue of Herm(C(e^{iω})⁻¹) − 1/2, C(z) = I + Σ D_i z^{−i}.

    Positive: C⁻¹ − I/2 is strictly positive real, the sufficient condition for ELS to converge
    (Ljung, IEEE TAC 22, 1977, "On positive real transfer functions and the convergence of some
    recursive schemes").  Negative: convergence is not guaranteed.
    """
    p = D.shape[1]
    worst = np.inf
    for omega in np.linspace(0.0, np.pi, points):
        z = np.exp(-1j * omega)
        inverse = np.linalg.inv(np.eye(p) + sum(Di * z ** (i + 1) for i, Di in enumerate(D)))
        worst = min(worst, float(np.linalg.eigvalsh((inverse + inverse.conj().T) / 2).min()) - 0.5)
    return worst


def noise_model_gain(Go_blocks: np.ndarray, markov: np.ndarray, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """K_o when the deterministic part is known and only the noise is not (the paper's Example 2: G, H, C
    given, "no noise knowledge"): w = A(q) y − B(q) u is the moving average D(q) η of (14); ELS gives
    the D_i and K_oi = D_i − G_oi.

    ``Go_blocks`` (r, p, p) are the known G_oi; ``markov`` (L, p, m) the plant's Markov parameters
    M_1 … M_L (y = Σ M_l u(k−l) without noise), from which B_l = Σ_{i=0}^{min(l−1, r)} G_oi M_{l−i}
    (G_o0 = I) for l = 1 … L, L ≥ r + delay samples.
    """
    r, p, _ = Go_blocks.shape
    L = markov.shape[0]
    A = np.concatenate([np.eye(p)[None], Go_blocks])                       # A_0 = I, A_1 … A_r
    B = np.stack([sum(A[i] @ markov[l - i - 1] for i in range(min(l, r + 1))) for l in range(1, L + 1)])
    y, u = np.asarray(y, dtype=float), np.asarray(u, dtype=float)
    w = np.zeros_like(y)
    for i in range(r + 1):
        w[i:] += y[: len(y) - i] @ A[i].T
    for l in range(1, L + 1):
        w[l:] -= u[: len(u) - l] @ B[l - 1].T
    start = max(r, L)
    D = extended_least_squares(w[start:], np.zeros((len(w) - start, 0)), na=0, nb=0, nc=r).model.D
    return (D - Go_blocks).reshape(-1, p)


def armax_observer(model: ARMAX) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The observer (47) of the identified model: ``x̂(k+1) = (G_o − K_o C_o) x̂ + H_o u + K_o y``,
    ``ŷ = C_o x̂``; returns ``(G_o − K_o C_o, H_o, K_o, C_o)``.  Refused when G_o − K_o C_o (the
    companion matrix of D(q)) is not stable: the predictor would diverge."""
    Go, Ho, Ko, Co = model.innovation_model()
    Gk = Go - Ko @ Co
    radius = np.abs(np.linalg.eigvals(Gk)).max()
    if radius >= 1.0:
        raise DesignError(f"identified G_o - K_o C_o has spectral radius {radius:.6g} >= 1: D(q) of the ARMAX model "
                          "is not stable and the observer would diverge")
    return Gk, Ho, Ko, Co


def one_step_predictions(observer: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], y: np.ndarray,
                         u: np.ndarray) -> np.ndarray:
    """ŷ(k|k−1) of ``armax_observer`` over the records y (N×p), u (N×m), from x̂(0) = 0."""
    Gk, Ho, Ko, Co = observer
    x = np.zeros(Gk.shape[0])
    predictions = np.empty_like(np.asarray(y, dtype=float))
    for k in range(len(y)):
        predictions[k] = Co @ x
        x = Gk @ x + Ho @ u[k] + Ko @ y[k]
    return predictions
