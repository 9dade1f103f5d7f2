"""Takagi–Sugeno fuzzy models: Gaussian antecedents, clustering, batch WLS and fuzzy RLS.

Pan, Shen & Luh (2012), J. Dyn. Sys. Meas. Control 134:041006 (seed 003), §3, and
``recovered-models.md`` §6.  A multi-input single-output TS model has R rules

    R_i: if z is Ω_i then y = x_eᵀ π_i,   x_e = [x, 1]  (affine term last, as in Table 1),

and output ``y = Σ λ_i(z) x_eᵀ π_i`` with normalised firing degrees λ_i = τ_i / Σ τ_j and
Gaussian firing ``τ_i = exp(−½ (z − c_i)ᵀ S_i (z − c_i))`` (S_i diagonal from widths, or the
inverse of a Gustafson–Kessel cluster covariance).

Antecedents: given centres/widths, or identified offline by fuzzy c-means or
Gustafson–Kessel clustering.  Consequents: batch weighted least squares (global or local
objective), or on-line by :class:`FuzzyRLS` with the global FRLS, the local FRLS
(Angelov & Filev 2004) or the mixed FRLS (MFRLS).

The MFRLS is OUR RECONSTRUCTION: the paper's equations (10)–(18), which define its mixed cost,
were lost.  What survives, (19)–(25), is the recursion of an information matrix
``C_m⁻¹(k) = C_m⁻¹(k−1) + μ̄_m Ψ_k Ψ_kᵀ + μ_m Σ_i μ_i x_{i,k} x_{i,k}ᵀ`` (21) and of the
parameters (25) with the global error weighted by μ̄_m and the local errors by μ_m, μ_m being
the "maximal firing level among all the subspaces" of the new sample (§3, after (25)).  That is
exactly weighted RLS on the stacked θ = [π_1; …; π_R] with, per sample, one global rank-one
update (regressor Ψ_k = λ ⊗ x_e, weight μ̄_m = 1 − μ_m) and R local ones (regressor e_i ⊗ x_e,
weight μ_m λ_i), which is how it is implemented here (recovered-models.md §6).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

logger = logging.getLogger(__name__)

FIRING_FLOOR = 1e-12
"""Below this largest firing degree a sample counts as outside every cluster (a warning is logged)."""

Method = Literal["global", "local", "mixed"]


def _as_matrix(values: ArrayLike, name: str) -> NDArray[np.float64]:
    array = np.atleast_2d(np.asarray(values, dtype=float))
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite")
    return array


@dataclass
class Antecedent:
    """Gaussian fuzzy sets Ω_i: centres (R × p) and precision matrices S_i (R × p × p)."""

    centres: NDArray[np.float64]
    precisions: NDArray[np.float64]

    @classmethod
    def from_widths(cls, centres: ArrayLike, widths: ArrayLike) -> Antecedent:
        """Product of one-dimensional Gaussians exp(−½((z_j − c_ij)/σ_ij)²); widths σ (R × p) > 0."""
        c = _as_matrix(centres, "centres")
        sigma = np.broadcast_to(_as_matrix(widths, "widths"), c.shape)
        if np.any(sigma <= 0.0):
            raise ValueError("Antecedent: every width must be > 0")
        precisions = np.stack([np.diag(1.0 / s**2) for s in sigma])
        return cls(c, precisions)

    @classmethod
    def from_covariances(cls, centres: ArrayLike, covariances: ArrayLike) -> Antecedent:
        """Multivariate Gaussians with the given (positive definite) covariance matrices (R × p × p)."""
        c = _as_matrix(centres, "centres")
        covariances = np.asarray(covariances, dtype=float).reshape(c.shape[0], c.shape[1], c.shape[1])
        return cls(c, np.linalg.inv(covariances))

    @property
    def rules(self) -> int:
        return self.centres.shape[0]

    def log_firing(self, z: ArrayLike) -> NDArray[np.float64]:
        """log τ_i(z) for one sample z (p,) or many (N × p) → (R,) or (N × R)."""
        z = np.asarray(z, dtype=float)
        d = z[..., None, :] - self.centres
        return -0.5 * np.einsum("...ri,rij,...rj->...r", d, self.precisions, d)

    def firing(self, z: ArrayLike) -> NDArray[np.float64]:
        """Firing degrees τ_i(z) ∈ (0, 1]."""
        return np.exp(self.log_firing(z))

    def memberships(self, z: ArrayLike) -> tuple[NDArray[np.float64], float]:
        """Normalised firing degrees λ (Σλ = 1) and the largest firing degree μ_m of one sample.

        Normalisation works on log τ (λ = softmax(log τ)), so a sample far outside every
        cluster, where all τ_i underflow, still gets finite memberships that favour the
        nearest rule; if μ_m < ``FIRING_FLOOR`` a warning is logged (documented fallback).
        """
        log_tau = self.log_firing(z)
        top = float(log_tau.max())
        weights = np.exp(log_tau - top)
        mu_max = math.exp(top)
        if mu_max < FIRING_FLOOR:
            logger.warning("TS memberships vanish at z = %s (max firing %.3g); nearest rule dominates", z, mu_max)
        return weights / weights.sum(), mu_max


@dataclass
class TSModel:
    """MISO Takagi–Sugeno model: antecedent on z, affine consequents π_i on x (R × (n_x + 1))."""

    antecedent: Antecedent
    consequents: NDArray[np.float64]

    def __post_init__(self) -> None:
        self.consequents = _as_matrix(self.consequents, "consequents")
        if self.consequents.shape[0] != self.antecedent.rules:
            raise ValueError(
                f"TSModel: {self.consequents.shape[0]} consequent rows for {self.antecedent.rules} rules"
            )

    def output(self, z: ArrayLike, x: ArrayLike) -> float:
        """y = Σ λ_i(z) [x, 1]ᵀ π_i."""
        lam, _ = self.antecedent.memberships(z)
        return float(lam @ (self.consequents @ np.append(np.asarray(x, dtype=float), 1.0)))

    def local_model(self, z: ArrayLike, lam: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Fuzzily weighted consequent Σ λ_i π_i at z: the active linear model of (33) (λ may be given)."""
        if lam is None:
            lam, _ = self.antecedent.memberships(z)
        return lam @ self.consequents


def fuzzy_c_means(
    Z: ArrayLike, rules: int, m: float = 2.0, iterations: int = 200, tol: float = 1e-7, seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fuzzy c-means (Bezdek): centres (R × p) and partition matrix U (R × N)."""
    return _cluster(Z, rules, m, iterations, tol, seed, gustafson_kessel=False)[:2]


def gustafson_kessel(
    Z: ArrayLike, rules: int, m: float = 2.0, iterations: int = 200, tol: float = 1e-7, seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gustafson–Kessel clustering (unit cluster volumes): centres, U (R × N), fuzzy covariances (R × p × p)."""
    return _cluster(Z, rules, m, iterations, tol, seed, gustafson_kessel=True)


def _cluster(
    Z: ArrayLike, rules: int, m: float, iterations: int, tol: float, seed: int, gustafson_kessel: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    data = _as_matrix(Z, "Z")
    n, p = data.shape
    if not 1 <= rules <= n:
        raise ValueError(f"clustering: need 1 <= rules <= samples, got {rules} rules for {n} samples")
    U = np.random.default_rng(seed).random((rules, n))
    U /= U.sum(axis=0)
    covariances = np.stack([np.eye(p)] * rules)
    for _ in range(iterations):
        W = U**m
        centres = (W @ data) / W.sum(axis=1, keepdims=True)
        diff = data[None, :, :] - centres[:, None, :]
        if gustafson_kessel:
            covariances = np.einsum("rn,rni,rnj->rij", W, diff, diff) / W.sum(axis=1)[:, None, None]
            covariances += 1e-9 * np.trace(covariances, axis1=1, axis2=2)[:, None, None] * np.eye(p)
            norms = np.linalg.det(covariances) ** (1.0 / p)
            A = norms[:, None, None] * np.linalg.inv(covariances)
            d2 = np.einsum("rni,rij,rnj->rn", diff, A, diff)
        else:
            d2 = np.einsum("rni,rni->rn", diff, diff)
        d2 = np.maximum(d2, 1e-300)
        inv = d2 ** (-1.0 / (m - 1.0))
        U_new = inv / inv.sum(axis=0)
        change = np.max(np.abs(U_new - U))
        U = U_new
        if change < tol:
            break
    return centres, U, covariances


def antecedent_from_partition(Z: ArrayLike, U: ArrayLike, m: float = 2.0, full: bool = False) -> Antecedent:
    """Gaussian antecedents projected from a fuzzy partition: weighted means and (co)variances."""
    data = _as_matrix(Z, "Z")
    W = np.asarray(U, dtype=float) ** m
    centres = (W @ data) / W.sum(axis=1, keepdims=True)
    diff = data[None, :, :] - centres[:, None, :]
    cov = np.einsum("rn,rni,rnj->rij", W, diff, diff) / W.sum(axis=1)[:, None, None]
    scale = np.maximum(np.diagonal(cov, axis1=1, axis2=2), 1e-12)
    if full:
        return Antecedent.from_covariances(centres, cov + 1e-9 * np.eye(data.shape[1]) * scale.max())
    return Antecedent.from_widths(centres, np.sqrt(scale))


def regressors(antecedent: Antecedent, Z: ArrayLike, X: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Memberships Λ (N × R) and extended regressors X_e = [X, 1] (N × (n_x + 1))."""
    data = _as_matrix(Z, "Z")
    log_tau = antecedent.log_firing(data)
    weights = np.exp(log_tau - log_tau.max(axis=1, keepdims=True))
    lam = weights / weights.sum(axis=1, keepdims=True)
    Xe = np.hstack([_as_matrix(X, "X"), np.ones((data.shape[0], 1))])
    return lam, Xe


def batch_wls(antecedent: Antecedent, Z: ArrayLike, X: ArrayLike, y: ArrayLike, method: Literal["global", "local"] = "local") -> TSModel:
    """Consequents by batch least squares: ``local`` solves R weighted LS problems (weights λ_i),
    ``global`` one LS problem on the stacked regressor Ψ = λ ⊗ x_e (Yen & Wang 1998)."""
    lam, Xe = regressors(antecedent, Z, X)
    target = np.asarray(y, dtype=float).ravel()
    R, q = antecedent.rules, Xe.shape[1]
    if method == "global":
        Psi = (lam[:, :, None] * Xe[:, None, :]).reshape(len(target), R * q)
        theta = np.linalg.lstsq(Psi, target, rcond=None)[0]
        return TSModel(antecedent, theta.reshape(R, q))
    if method != "local":
        raise ValueError(f"batch_wls: method must be 'global' or 'local', got {method!r}")
    rows = []
    for i in range(R):
        w = np.sqrt(lam[:, i])
        rows.append(np.linalg.lstsq(w[:, None] * Xe, w * target, rcond=None)[0])
    return TSModel(antecedent, np.array(rows))


@dataclass
class FuzzyRLS:
    """On-line consequent estimation of a :class:`TSModel` (updates ``model.consequents`` in place).

    ``method``: ``"global"`` (one RLS on Ψ = λ ⊗ x_e, cost J_G), ``"local"`` (R RLS weighted by
    λ_i, cost J_L), ``"mixed"`` (MFRLS, our reconstruction, see the module docstring: per
    sample a global update weighted μ̄_m and local updates weighted μ_m λ_i, (21) and (25)).
    ``forgetting`` ρ ∈ (0, 1] divides the covariance C by ρ once per sample.  ``omega`` sets the
    initial covariance C(0) = ω I.  ``dominance`` defines μ_m: ``"firing"`` the largest raw
    firing degree max τ_i (recovered-models.md §6) or ``"normalised"`` (R max λ_i − 1)/(R − 1),
    which is 1 in one rule's core and 0 where all rules fire evenly (the paper's §3 wording).
    """

    model: TSModel
    method: Method = "mixed"
    forgetting: float = 1.0
    omega: float = 1e3
    dominance: Literal["firing", "normalised"] = "normalised"
    covariance: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        if self.method not in ("global", "local", "mixed"):
            raise ValueError(f"FuzzyRLS: method must be global, local or mixed, got {self.method!r}")
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"FuzzyRLS: forgetting factor must be in (0, 1], got {self.forgetting}")
        if not (math.isfinite(self.omega) and self.omega > 0.0):
            raise ValueError(f"FuzzyRLS: omega must be a finite number > 0, got {self.omega}")
        self.covariance = self.omega * np.eye(self.model.consequents.size)

    def mixing_weight(self, lam: NDArray[np.float64], mu_max: float) -> float:
        """μ_m of the sample: the weight of the local objective (μ̄_m = 1 − μ_m weights the global one)."""
        if self.method == "global":
            return 0.0
        if self.method == "local":
            return 1.0
        if self.dominance == "firing":
            return mu_max
        R = len(lam)
        return 1.0 if R == 1 else float((R * lam.max() - 1.0) / (R - 1.0))

    def update(
        self, z: ArrayLike, x: ArrayLike, y: float, memberships: tuple[NDArray[np.float64], float] | None = None
    ) -> float:
        """Take one sample (antecedent z, regressor x, measured y); return the a-priori error y − ŷ.

        ``memberships`` = (λ, μ_m) of z if already computed (models sharing an antecedent)."""
        lam, mu_max = self.model.antecedent.memberships(z) if memberships is None else memberships
        xe = np.concatenate([np.asarray(x, dtype=float), [1.0]])
        theta = self.model.consequents.ravel().copy()
        R, q = self.model.consequents.shape
        prior_error = float(y - lam @ (self.model.consequents @ xe))
        if not (math.isfinite(y) and np.all(np.isfinite(xe))):
            logger.warning("FuzzyRLS: non-finite sample (y = %s, x = %s) skipped", y, x)
            return prior_error
        C = self.covariance / self.forgetting
        mu = self.mixing_weight(lam, mu_max)
        if mu < 1.0:
            C, theta = _weighted_rls(C, theta, (lam[:, None] * xe).ravel(), y, 1.0 - mu, slice(None))
        if mu > 0.0:
            for i in range(R):
                if lam[i] > 0.0:
                    block = slice(i * q, (i + 1) * q)
                    C, theta = _weighted_rls(C, theta, xe, y, mu * lam[i], block)
        self.covariance = 0.5 * (C + C.T)
        self.model.consequents = theta.reshape(R, q)
        return prior_error


def _weighted_rls(
    C: NDArray[np.float64], theta: NDArray[np.float64], phi: NDArray[np.float64], y: float, weight: float, block: slice
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One rank-one weighted RLS update; ``phi`` is nonzero only on ``block`` of the stacked θ.

    K = C φ / (1/w + φᵀ C φ),  θ += K (y − φᵀ θ),  C −= K φᵀ C   (recovered-models.md §6),
    with K computed as w C φ / (1 + w φᵀ C φ): the same gain without 1/w overflowing for a
    vanishing weight (a raw firing level μ_m far from every rule centre).
    """
    Cphi = C[:, block] @ phi
    gain = weight * Cphi / (1.0 + weight * (phi @ Cphi[block]))
    theta += gain * (y - phi @ theta[block])
    C -= np.outer(gain, Cphi)
    return C, theta
