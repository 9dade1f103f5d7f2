"""Observable block companion form of Shieh, Wang & Tsay (1983), Zhou et al. (2006) (12)-(14).

A block-observable ``x(k+1) = G x + … + Γ η``, ``y = C x + η`` (n states, p outputs, r = n/p an
integer, rank Q(G, C) = n (12)) becomes, with ``x = T_o x_o``,

    x_o(k+1) = G_o x_o + … + K_o η,   y = C_o x_o + η,   C_o = [I_p, 0, …, 0]                    (13)

    G_o = [[−G_o1, I, 0, …], [−G_o2, 0, I, …], …, [−G_or, 0, …, 0]],   K_o = T_o⁻¹ Γ = [K_o1; …; K_or]

whose input–output form is the multivariable ARMAX model (14)

    y(k) + Σ G_oi y(k−i) = Σ B_i u(k−i) + η(k) + Σ D_i η(k−i),   D_i = G_oi + K_oi.

Sign convention (ours; the extracted paper lost the matrices): G_oi are the coefficients of the
ARMAX autoregressive polynomial, so the paper's ``D_i = G_oi + K_oi`` holds as printed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.errors import DesignError


@dataclass(frozen=True)
class BlockCompanion:
    """``T_o`` (x = T_o x_o) and the autoregressive blocks ``G_oi`` (shape (r, p, p)) of (13)."""

    T_o: np.ndarray
    Go_blocks: np.ndarray

    @property
    def Go(self) -> np.ndarray:
        """G_o of (13)."""
        return companion_matrix(self.Go_blocks)

    def to_companion(self, M: np.ndarray) -> np.ndarray:
        """T_o⁻¹ M: an input or noise matrix (H_0, H_1, Γ) in the companion coordinates."""
        return np.linalg.solve(self.T_o, M)


def companion_matrix(Go_blocks: np.ndarray) -> np.ndarray:
    """G_o of (13) from its first block column's blocks G_o1 … G_or (signs as in the module note)."""
    r, p, _ = Go_blocks.shape
    Go = np.zeros((r * p, r * p))
    Go[:, :p] = -Go_blocks.reshape(r * p, p)
    Go[: (r - 1) * p, p:] = np.eye((r - 1) * p)
    return Go


def block_companion(G: np.ndarray, C: np.ndarray) -> BlockCompanion:
    """Transformation of (G, C) to the observable block companion form (13).

    ``T_o⁻¹ = L·O`` with ``O = [C; CG; …; CG^{r−1}]`` and L block lower-triangular Toeplitz with
    identities on the diagonal and G_o1 … G_o(r−1) below; ``[G_or … G_o1] O = −C G^r``.
    Raises `DesignError` when n/p is not an integer or (12) fails (not block observable).
    """
    G, C = np.atleast_2d(np.asarray(G, dtype=float)), np.atleast_2d(np.asarray(C, dtype=float))
    n, p = G.shape[0], C.shape[0]
    if n % p:
        raise DesignError(f"block companion form (13) needs r = n/p to be an integer, got n = {n}, p = {p} "
                          "(Shieh et al. 1989 treat the general case)")
    r = n // p
    powers = [C]
    for _ in range(r):
        powers.append(powers[-1] @ G)
    O = np.vstack(powers[:r])
    if np.linalg.matrix_rank(O, tol=1e-10 * max(1.0, np.abs(O).max())) < n:
        raise DesignError(f"(G, C) is not block observable: rank Q(G, C) < n = {n} (condition (12))")
    stacked = -np.linalg.solve(O.T, powers[r].T).T                   # [G_or … G_o1]
    Go_blocks = np.stack([stacked[:, (r - i) * p : (r - i + 1) * p] for i in range(1, r + 1)])
    L = np.eye(n)
    for i in range(1, r):
        for j in range(i):
            L[i * p : (i + 1) * p, j * p : (j + 1) * p] = Go_blocks[i - j - 1]
    return BlockCompanion(np.linalg.inv(L @ O), Go_blocks)
