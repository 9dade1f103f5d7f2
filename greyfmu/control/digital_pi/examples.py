"""The plants of Zhou et al. (2006)'s examples, with the noise models we had to reconstruct.

- Example 1 is Westerlund's (1981) cement kiln; its matrices were not recoverable
  (recovered-models.md §3), so `cement_kiln` refuses and `wood_berry` is the clearly labelled
  2×2 substitute (Wood & Berry 1973, Ts = 1 min).
- Example 2 is the CH-47 helicopter (Doyle & Stein 1981, recovered-models.md §2): A verified
  against the paper's open-loop poles, B and C recalled from memory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.discretize import ContinuousPlant, c2d
from greyfmu.control.digital_pi.observer import continuous_noise_gain, kalman_innovation


@dataclass(frozen=True)
class Example:
    """A plant (1) with its input delay, innovation covariance Q_η and the design settings used."""

    name: str
    plant: ContinuousPlant
    tau: float | np.ndarray
    Q_eta: np.ndarray
    Ts: float
    alpha: float
    beta: float
    q: float
    r: float


UNIT_DISC = (1.0, 0.0)
"""(α, β) of the paper's Example 2: the ordinary LQR, every pole in the unit circle."""


def cement_kiln() -> Example:
    """Example 1 slot: (28)-(29) of the paper.  Drop Westerlund's A, B, C, V (Ts = 5, τ = Ts/2) in here."""
    raise LookupError("the cement kiln matrices of Zhou et al. (2006) (28)-(29) were lost in extraction and are not "
                      "in any public source we could reach (recovered-models.md §3); use wood_berry()")


def _with_innovations(name: str, A: np.ndarray, B: np.ndarray, C: np.ndarray, tau: float | np.ndarray, Ts: float,
                      W: np.ndarray, Rv: np.ndarray, alpha: float, beta: float) -> Example:
    """Give the plant the innovation form of state noise W and measurement noise Rv (RECONSTRUCTED)."""
    zero_V = np.zeros((A.shape[0], C.shape[0]))
    G = c2d(ContinuousPlant(A, B, C, zero_V), Ts, tau).G
    Gamma, Q_eta = kalman_innovation(G, C, W, Rv)
    V = continuous_noise_gain(A, Ts, Gamma)
    return Example(name, ContinuousPlant(A, B, C, V), tau, Q_eta, Ts, alpha, beta, q=10.0, r=1.0)


def wood_berry() -> Example:
    """Wood–Berry column (recovered-models.md §3) as a diagonal realisation with per-entry delays.

    States x11, x12, x21, x22, one per transfer element; y = (x11 + x12, x21 + x22) + η; time in
    minutes.  Each element's dead time (1, 3, 7, 3 min) gets the Ts/2 input delay of the zero-order
    hold that both paper examples add (Example 1: "an input delay of τ = Ts/2 will be introduced"),
    so τ = 1.5, 3.5, 7.5, 3.5 min.  Noise (RECONSTRUCTED): white noise of 0.05 lb/min RMS on both
    inputs, held over Ts and entering without delay, and measurement noise 0.02 mol %.  §3's
    separate feed-disturbance states are left out: their poles 0.935 and 0.927 are uncontrollable
    and outside the paper's disc |z − 0.7| < 0.2, so (G_αβ, H_α) would not be stabilisable (Lemma 1
    refuses it).  Design: Q = 10 I, R = I and the disc α = 0.2, β = 0.7 of the paper's Example 1.
    The 16 delay states start at z = 0 and must all be pushed into the disc: every pole is in it
    (max |z − β|/α = 0.878) but a unit step peaks at |y| ≈ 540 (docs/digital_pi.md); the unit disc
    (α = 1, β = 0) of Example 2 is `UNIT_DISC`.
    """
    gains = np.array([12.8, -18.9, 6.6, -19.4])
    lags = np.array([16.7, 21.0, 10.9, 14.4])
    delays = np.array([1.0, 3.0, 7.0, 3.0])
    inputs = [0, 1, 0, 1]
    A = np.diag(-1.0 / lags)
    B = np.zeros((4, 2))
    tau = np.zeros((4, 2))
    Ts = 1.0
    for state, (K, lag, delay, j) in enumerate(zip(gains, lags, delays, inputs)):
        B[state, j] = K / lag
        tau[state, j] = delay + Ts / 2
    C = np.array([[1.0, 1, 0, 0], [0, 0, 1, 1]])
    H = c2d(ContinuousPlant(A, B, C, np.zeros((4, 2))), Ts).H
    W = 0.05**2 * H @ H.T
    return _with_innovations("Wood-Berry column (substitute for the cement kiln)", A, B, C, tau, Ts, W,
                             0.02**2 * np.eye(2), alpha=0.2, beta=0.7)


def ch47() -> Example:
    """CH-47 at 40 kn (Doyle & Stein 1981; recovered-models.md §2), Ts = 0.01, τ = Ts/2, α = 1, β = 0.

    Noise (RECONSTRUCTED; (44) was lost): white disturbances on both rotor commands, 0.1 RMS held
    over Ts, and measurement noise 0.01 (ft/s, deg) on both outputs.
    """
    A = np.array([[-0.02, 0.005, 2.4, -32], [-0.14, 0.44, -1.3, -30], [0, 0.018, -1.6, 1.2], [0, 0, 1, 0]])
    B = np.array([[0.14, -0.12], [0.36, -8.6], [0.35, 0.009], [0, 0]])
    C = np.array([[0, 1.0, 0, 0], [0, 0, 0, 57.3]])
    Ts = 0.01
    H = c2d(ContinuousPlant(A, B, C, np.zeros((4, 2))), Ts).H
    W = 0.1**2 * H @ H.T + 1e-12 * np.eye(4)
    return _with_innovations("CH-47 tandem-rotor helicopter", A, B, C, Ts / 2, Ts, W, 0.01**2 * np.eye(2),
                             alpha=1.0, beta=0.0)
