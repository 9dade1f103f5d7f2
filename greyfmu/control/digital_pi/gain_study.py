"""The identified Kalman gain against the DARE one as the data length grows (issue 15; Zhou et al.
(2006) (12)-(14)): the experiment behind docs/digital_pi.md's identification table.

Data: the stochastic plant (1)-(2) sampled at Ts — the augmented discrete model (9)/(10), which the
StochasticLTI plant reproduces exactly (tests/greyfmu/test_digital_pi.py) — driven by innovations of
covariance Q_η and run under an LQ state feedback (unit disc, Q = I, R = I: any stabilising
controller would do; CH-47 is open-loop unstable) plus a white dither on every input.  ELS sees
only y and u.  The ARMAX orders follow the plant: na = nc = r = n/p, nb = r + D (D delay samples).

Two routes, both ELS and K_oi = D_i − G_oi: "unknown" identifies the whole ARMAX (14) (the paper's
route for an unknown plant); "known model" takes G, H, C as given (the paper's Example 2) and
identifies only the moving average D(q) of w = A(q) y − B(q) u (`noise_model_gain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from greyfmu.control.digital_pi.augment import AugmentedPlant, augment_delay
from greyfmu.control.digital_pi.companion import block_companion
from greyfmu.control.digital_pi.design import design_digital_pi, stationary_variances, with_observer_gain
from greyfmu.control.digital_pi.disc_lqr import dlqr_disc
from greyfmu.control.digital_pi.discretize import c2d
from greyfmu.control.digital_pi.examples import Example
from greyfmu.control.digital_pi.errors import DesignError
from greyfmu.control.digital_pi.identification import (
    armax_observer,
    extended_least_squares,
    noise_model_gain,
    one_step_predictions,
)


@dataclass(frozen=True)
class Route:
    """One route's result: ‖K̂_o − K_o‖_F/‖K_o‖_F, the one-step prediction-error variances of its
    observer on fresh data, and the digital PI's stationary E{y_i²} with its gain in the observer.
    ``prediction`` and ``regulation`` are None with ``refused`` naming why when the identified
    observer is unstable; ``regulation`` is None for the unknown-ARMAX route, whose model is in its
    own coordinates, not the controller's."""

    gain_error: float
    prediction: np.ndarray | None
    regulation: np.ndarray | None
    refused: str = ""


@dataclass(frozen=True)
class GainComparison:
    """A row of the table: data length N, the two ELS routes and the DARE (true) Kalman gain."""

    N: int
    unknown: Route
    known: Route
    kalman: Route


def closed_loop_records(example: Example, N: int, seed: int, dither: float) -> tuple[np.ndarray, np.ndarray]:
    """(y, u) records of N samples of the plant under the data-collection loop described above."""
    aug = augment_delay(c2d(example.plant, example.Ts, example.tau))
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


def innovation_predictions(aug: AugmentedPlant, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """ŷ(k|k−1) of the observer ``x̂(k+1) = (Gp − Γp Cp) x̂ + Hp u + Γp y`` over the records, x̂(0) = 0."""
    return one_step_predictions((aug.Gp - aug.Gammap @ aug.Cp, aug.Hp, aug.Gammap, aug.Cp), y, u)


def markov_parameters(aug: AugmentedPlant, count: int) -> np.ndarray:
    """M_1 … M_count, M_l = Cp Gp^{l−1} Hp: y(k) = Σ M_l u(k − l) without noise."""
    out, GH = [], aug.Hp
    for _ in range(count):
        out.append(aug.Cp @ GH)
        GH = aug.Gp @ GH
    return np.stack(out)


def compare_gains(example: Example, N: int, seed: int, dither: float, validation: int = 4000) -> GainComparison:
    """Identify from N samples (seed) by both routes, validate on ``validation`` fresh samples (seed + 1)."""
    discrete = c2d(example.plant, example.Ts, example.tau)
    aug = augment_delay(discrete)
    companion = block_companion(discrete.G, discrete.C)
    r = companion.Go_blocks.shape[0]
    K_true = companion.to_companion(discrete.Gamma)
    y, u = closed_loop_records(example, N, seed, dither)
    y_val, u_val = closed_loop_records(example, validation, seed + 1, dither)
    keep = slice(validation // 10, None)
    design = design_digital_pi(example.plant, example.Ts, example.tau, example.alpha, example.beta, example.q, example.r)

    def error(K: np.ndarray) -> float:
        return float(np.linalg.norm(K - K_true) / np.linalg.norm(K_true))

    def variance(prediction: np.ndarray) -> np.ndarray:
        return np.mean((y_val - prediction)[keep] ** 2, axis=0)

    model = extended_least_squares(y, u, na=r, nb=r + aug.lags, nc=r).model
    try:
        unknown = Route(error(model.kalman_gain()), variance(one_step_predictions(armax_observer(model), y_val, u_val)),
                        None)
    except DesignError as refusal:
        unknown = Route(error(model.kalman_gain()), None, None, str(refusal))
    K_known = noise_model_gain(companion.Go_blocks, markov_parameters(aug, r + aug.lags), y, u)
    try:
        loop = with_observer_gain(design, companion.T_o @ K_known)
        known = Route(error(K_known), variance(innovation_predictions(loop.augmented, y_val, u_val)),
                      stationary_variances(loop, example.Q_eta, aug.Gammap)[0])
    except DesignError as refusal:
        known = Route(error(K_known), None, None, str(refusal))
    kalman = Route(0.0, variance(innovation_predictions(aug, y_val, u_val)), stationary_variances(design, example.Q_eta)[0])
    return GainComparison(N, unknown, known, kalman)


@dataclass(frozen=True)
class PredictionExcess:
    """Out-of-sample one-step prediction-error variance above the true (Kalman) predictor's, per output, relative:
    of the ELS ARMAX model and of a least-squares ARX model of the same orders without the noise model; and the
    excess an efficient estimator is expected to show, d/N (d parameters per output, Akaike's FPE)."""

    N: int
    els: np.ndarray
    arx: np.ndarray
    efficient: float


def prediction_excess(example: Example, N: int, seed: int, dither: float = 0.1, validation: int = 20000) -> PredictionExcess:
    """Identify the whole ARMAX (14) by ELS from N samples (seed) and, as a control, an ARX model by batch least
    squares; compare their one-step predictions with the true innovation predictor's on ``validation`` fresh samples
    (seed + 1000, the first 10 % dropped).  An estimator that reaches the prediction-error optimum has an excess near
    d/N that falls as 1/N; one held away from it (the ARX model's bias) keeps a floor."""
    discrete = c2d(example.plant, example.Ts, example.tau)
    aug = augment_delay(discrete)
    r = block_companion(discrete.G, discrete.C).Go_blocks.shape[0]
    na, nb = r, r + aug.lags
    y, u = closed_loop_records(example, N, seed, dither)
    y_val, u_val = closed_loop_records(example, validation, seed + 1000, dither)
    p, m = y.shape[1], u.shape[1]
    keep = slice(validation // 10, None)

    def variance(prediction: np.ndarray) -> np.ndarray:
        return np.mean((y_val - prediction)[keep] ** 2, axis=0)

    true = variance(innovation_predictions(aug, y_val, u_val))
    els = variance(one_step_predictions(armax_observer(extended_least_squares(y, u, na, nb, r).model), y_val, u_val))
    start = max(na, nb)
    regressors = lambda Y, U, k: np.concatenate([-Y[k - na : k][::-1].ravel(), U[k - nb : k][::-1].ravel()])  # noqa: E731
    theta = np.linalg.lstsq(np.array([regressors(y, u, k) for k in range(start, N)]), y[start:], rcond=None)[0]
    arx = np.zeros_like(y_val)
    for k in range(start, validation):
        arx[k] = regressors(y_val, u_val, k) @ theta
    return PredictionExcess(N, els / true - 1.0, variance(arx) / true - 1.0, (p * na + m * nb + p * r) / N)
