"""The identified Kalman gain against the DARE one as the data length grows (issue 15; Zhou et al.
(2006) (12)-(14)): the experiment behind docs/digital_pi.md's identification table.

Data: the stochastic plant (1)-(2) sampled at T — the augmented discrete model (9)/(10), which the
StochasticLTI plant reproduces exactly (tests/test_digital_pi.py) — driven by innovations of
covariance Q_η and run under an LQ state feedback (unit disc, Q = I, R = I: any stabilising
controller would do; CH-47 is open-loop unstable) plus a white dither on every input.  ELS sees
only y and u.  The ARMAX orders follow the plant: na = nc = r = n/p, nb = r + D (D delay samples).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.augment import augment_delay
from greyfmu.control.digital_pi.companion import block_companion
from greyfmu.control.digital_pi.design import design_digital_pi, stationary_variances, with_observer_gain
from greyfmu.control.digital_pi.disc_lqr import dlqr_disc
from greyfmu.control.digital_pi.discretize import c2d
from greyfmu.control.digital_pi.examples import Example
from greyfmu.control.digital_pi.identification import armax_observer, extended_least_squares, one_step_predictions


@dataclass(frozen=True)
class GainComparison:
    """One row of the table: data length N, ‖K̂_o − K_o‖_F/‖K_o‖_F, one-step prediction-error
    variances on fresh data (identified observer, exact Kalman predictor) and the digital PI's
    stationary E{y_i²} with the identified gain in its observer and with the DARE gain."""

    N: int
    gain_error: float
    prediction_identified: np.ndarray
    prediction_kalman: np.ndarray
    regulation_identified: np.ndarray
    regulation_kalman: np.ndarray


def closed_loop_records(example: Example, N: int, seed: int, dither: float) -> tuple[np.ndarray, np.ndarray]:
    """(y, u) records of N samples of the plant under the data-collection loop described above."""
    aug = augment_delay(c2d(example.plant, example.T, example.tau))
    feedback = dlqr_disc(aug.Gp, aug.Hp, np.eye(aug.order), np.eye(aug.Hp.shape[1])).K
    rng = np.random.default_rng(seed)
    p, m = aug.Cp.shape[0], aug.Hp.shape[1]
    eta = rng.standard_normal((N, p)) @ np.linalg.cholesky(example.Q_eta).T
    excitation = dither * rng.standard_normal((N, m))
    X = np.zeros(aug.order)
    y, u = np.empty((N, p)), np.empty((N, m))
    for k in range(N):
        y[k] = aug.Cp @ X + eta[k]
        u[k] = -feedback @ X + excitation[k]
        X = aug.Gp @ X + aug.Hp @ u[k] + aug.Gammap @ eta[k]
    return y, u


def compare_gains(example: Example, N: int, seed: int, dither: float, validation: int = 4000) -> GainComparison:
    """Identify from N samples (seed), validate on ``validation`` fresh samples (seed + 1)."""
    discrete = c2d(example.plant, example.T, example.tau)
    companion = block_companion(discrete.G, discrete.C)
    r = companion.Go_blocks.shape[0]
    lags = augment_delay(discrete).lags
    y, u = closed_loop_records(example, N, seed, dither)
    model = extended_least_squares(y, u, na=r, nb=r + lags, nc=r).model
    K_hat = model.kalman_gain()
    K_true = companion.to_companion(discrete.Gamma)
    y_val, u_val = closed_loop_records(example, validation, seed + 1, dither)
    keep = slice(validation // 10, None)
    identified = y_val - one_step_predictions(armax_observer(model), y_val, u_val)
    kalman = y_val - np.vstack([np.zeros(y_val.shape[1]),
                                _kalman_predictions(discrete, y_val, u_val)[:-1]])
    design = design_digital_pi(example.plant, example.T, example.tau, example.alpha, example.beta, example.q, example.r)
    with_identified = with_observer_gain(design, companion.T_o @ K_hat)
    var_identified, _ = stationary_variances(with_identified, example.Q_eta, design.augmented.Gammap)
    var_kalman, _ = stationary_variances(design, example.Q_eta)
    return GainComparison(N, float(np.linalg.norm(K_hat - K_true) / np.linalg.norm(K_true)),
                          np.mean(identified[keep] ** 2, axis=0), np.mean(kalman[keep] ** 2, axis=0),
                          var_identified, var_kalman)


def _kalman_predictions(discrete, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """ŷ(k+1|k) of the true innovation model (the DARE gain Γ) on the augmented plant, from x̂(0) = 0."""
    aug = augment_delay(discrete)
    Gk = aug.Gp - aug.Gammap @ aug.Cp
    x = np.zeros(aug.order)
    out = np.empty_like(y)
    for k in range(len(y)):
        x = Gk @ x + aug.Hp @ u[k] + aug.Gammap @ y[k]
        out[k] = aug.Cp @ x
    return out
