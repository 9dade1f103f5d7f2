"""``design_digital_pi``: the whole procedure of Zhou et al. (2006), "Controller design" section.

Sign convention (a documented deviation).  The extracted (18)/(19) read
``u = −F x_a − K2 z − K1 e``; with K1 = G_p(0)^{-1} that feeds ``−G_p(0)^{-1} r`` forward, i.e.
the first move after a set-point step goes the wrong way.  The PI (15)/(16) and Fig. 1 add the
PI's ``K1 e`` to the state feedback, so here

    u(k) = −F x̂_a(k) − K2 z(k) + K1 e(k),   z(k+1) = z(k) + Hc e(k),   e = r − y        (18)/(36)

and with the LQ law ``u* = −K̄1 x_a − K̄2 z`` (20) the split (21) becomes ``F = K̄1 − K1 Cp``,
``K2 = K̄2``.  The closed-loop poles are those of ``Ḡ − H̄K̄`` either way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import solve_discrete_lyapunov

from greyfmu.control.digital_pi.augment import AugmentedPlant, augment_delay, cascade_pi
from greyfmu.control.digital_pi.decoupling import static_decoupling
from greyfmu.control.digital_pi.discretize import ContinuousPlant, DiscretePlant, c2d
from greyfmu.control.digital_pi.disc_lqr import dlqr_disc
from greyfmu.control.digital_pi.errors import DesignError
from greyfmu.control.digital_pi.observer import innovation_observer


@dataclass(frozen=True)
class DigitalPIDesign:
    """Everything the design produces; the controller needs Gp, Hp, Gammap, Cp (observer), F, K1, K2, Hc.

    ``riccati_backward_error`` is the relative residual of (26) (`DiscLQR.backward_error`), reported.
    """

    Ts: float
    alpha: float
    beta: float
    discrete: DiscretePlant
    augmented: AugmentedPlant
    Gbar: np.ndarray
    Hbar: np.ndarray
    Kbar: np.ndarray
    P: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    F: np.ndarray
    Hc: np.ndarray
    closed_loop_poles: np.ndarray
    observer_poles: np.ndarray
    riccati_backward_error: float

    @property
    def KP(self) -> np.ndarray:
        """Proportional gain of K(z) = K_I z/(z − 1) + K_P (15): K_P = K1 − K_I."""
        return self.K1 - self.KI

    @property
    def KI(self) -> np.ndarray:
        """Integral gain of (15) for the law u = … − K2 z + K1 e with z(k+1) = z + Hc e: K_I = −K2 Hc."""
        return -self.K2 @ self.Hc


def _weight(value: float | np.ndarray, size: int) -> np.ndarray:
    matrix = np.asarray(value, dtype=float)
    return matrix * np.eye(size) if matrix.ndim == 0 else matrix


def design_digital_pi(plant: ContinuousPlant, Ts: float, tau: float | np.ndarray, alpha: float, beta: float,
                      Q: float | np.ndarray, R: float | np.ndarray, Hc: np.ndarray | None = None) -> DigitalPIDesign:
    """Design the centralised digital PI: discretise (5)-(8), augment (9)/(10), cascade with the PI
    (16)-(17), LQR in the disc |z − β| < α (25)-(27), K1 = G_p(0)^{-1}, split (21), observer.

    ``Q``/``R`` may be numbers (times the identity of the cascaded order n + D·m + p, resp. m)
    or matrices; ``Hc`` defaults to the identity (the paper's Example 2).  Raises `DesignError`.
    """
    K1 = static_decoupling(plant)
    discrete = c2d(plant, Ts, tau)
    aug = augment_delay(discrete)
    Hc = np.eye(plant.p) if Hc is None else np.atleast_2d(np.asarray(Hc, dtype=float))
    if Hc.shape != (plant.p, plant.p) or np.linalg.matrix_rank(Hc) < plant.p:
        raise DesignError(f"Hc must be a nonsingular {plant.p}x{plant.p} matrix, got {Hc.tolist()}")
    Gbar, Hbar = cascade_pi(aug, Hc)
    size = Gbar.shape[0]
    lqr = dlqr_disc(Gbar, Hbar, _weight(Q, size), _weight(R, plant.m), alpha, beta)
    Kbar = lqr.K
    Go = innovation_observer(aug)
    na = aug.order
    F = Kbar[:, :na] - K1 @ aug.Cp                                    # (21), sign of K1 as in the module note
    K2 = Kbar[:, na:]                                                 # (21)
    return DigitalPIDesign(Ts, alpha, beta, discrete, aug, Gbar, Hbar, Kbar, lqr.P, K1, K2, F, Hc,
                           np.linalg.eigvals(Gbar - Hbar @ Kbar), np.linalg.eigvals(Go), lqr.backward_error)


def with_observer_gain(design: DigitalPIDesign, Gamma: np.ndarray) -> DigitalPIDesign:
    """The same design with the observer's Kalman gain replaced by ``Gamma`` (n×p, the plant's states;
    the delay states get none), e.g. the gain identified by `extended_least_squares`.  Refused
    (`innovation_observer`) when G − ΓC is not stable."""
    a = design.augmented
    Gammap = np.zeros_like(a.Gammap)
    Gammap[: Gamma.shape[0]] = Gamma
    augmented = replace(a, Gammap=Gammap)
    return replace(design, augmented=augmented, observer_poles=np.linalg.eigvals(innovation_observer(augmented)))


def closed_loop(design: DigitalPIDesign, plant_Gammap: np.ndarray | None = None,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The loop of plant (9)/(10), PI and observer, state ξ = [X_a; z; x̂_a], inputs (r, η):
    returns ``(A, B_r, B_eta, C_y, C_u)`` with ``y = C_y ξ + η`` and ``u = C_u ξ + K1 (r − η)``.
    ``plant_Gammap`` is the plant's noise gain when it differs from the observer's (default: equal)."""
    a = design.augmented
    na, p = a.order, a.Cp.shape[0]
    Gp, Hp, Gm, Cp = a.Gp, a.Hp, a.Gammap, a.Cp
    Gn = Gm if plant_Gammap is None else plant_Gammap
    F, K1, K2, Hc = design.F, design.K1, design.K2, design.Hc
    C_u = np.hstack([-K1 @ Cp, -K2, -F])
    C_y = np.hstack([Cp, np.zeros((p, p + na))])
    A = np.vstack([
        np.hstack([Gp, np.zeros((na, p + na))]) + Hp @ C_u,
        np.hstack([-Hc @ Cp, np.eye(p), np.zeros((p, na))]),
        np.hstack([Gm @ Cp, np.zeros((na, p)), Gp - Gm @ Cp]) + Hp @ C_u,
    ])
    B_r = np.vstack([Hp @ K1, Hc, Hp @ K1])
    B_eta = np.vstack([Gn - Hp @ K1, -Hc, Gm - Hp @ K1])
    return A, B_r, B_eta, C_y, C_u


def stationary_variances(design: DigitalPIDesign, Q_eta: np.ndarray,
                         plant_Gammap: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """E{y_i²} and E{u_i²} of the regulation loop (r = 0) driven by innovations η of covariance Q_eta,
    from the discrete Lyapunov equation — the exact values the simulated variances (42) estimate.
    ``plant_Gammap`` as in `closed_loop` (an observer gain that is not the plant's)."""
    A, _, B_eta, C_y, C_u = closed_loop(design, plant_Gammap)
    Q_eta = np.atleast_2d(np.asarray(Q_eta, dtype=float))
    S = solve_discrete_lyapunov(A, B_eta @ Q_eta @ B_eta.T)
    var_y = np.diag(C_y @ S @ C_y.T + Q_eta)
    D_u = -design.K1
    var_u = np.diag(C_u @ S @ C_u.T + D_u @ Q_eta @ D_u.T)
    return var_y, var_u


def reference_dc_gain(design: DigitalPIDesign) -> np.ndarray:
    """Static gain from r to y of the closed loop: the identity when the PI decouples statically."""
    A, B_r, _, C_y, _ = closed_loop(design)
    return C_y @ np.linalg.solve(np.eye(A.shape[0]) - A, B_r)
