"""Practical predictive control for a second-order-plus-dead-time model (Cîrtoaje, Frâncu, Rădulescu).

Paper: *A practical predictive control algorithm for a large class of processes*
(``../shared/seeds/001_*``).  The process model is ``K e^{−τs} / ((T1 s + 1)(T2 s + 1))`` (1).

Off-line part (``sopdt_design``): sampling-time advice and horizon N, T1/T2 from ξ and X_t (2),
integer dead time m, coefficients (3), discrete model (4), unit step response (5), E (6).
On-line part (``SOPDTPredictive.step``): free response (9)-(10) from the measured outputs and
the applied past inputs, and one of the control laws (7), (12)-(14) or (15)-(17).

Two printed formulas disagree with the paper's own model and criterion; we follow the model:

- (5) prints ``h_{i+2} = b − a1·h_{i+1} + a2·h_i``; the step response of model (4) is
  ``h_{i+2} = b − a1·h_{i+1} − a2·h_i`` (only this one settles at the model gain X_k·K).
- (14) prints ``a = F / (E − g_N²)``; minimising criterion (11) over the two postulated
  values gives ``a = F1 / (E − g_N²)`` (F is the criterion itself, F1 is defined next to it).
"""

from __future__ import annotations

import logging
import math
import warnings
from collections import deque
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from greyfmu.control.limits import OutputLimits

logger = logging.getLogger(__name__)

N_MIN, N_MAX = 15, 20
"""Recommended range of the prediction horizon N = [(τ + 3·T0)/Ts] (paper §2 and §4)."""
N_LIMIT = 40
"""Largest horizon accepted: beyond it the sampling period is far too short for the paper's method."""


class HorizonWarning(UserWarning):
    """The horizon N exceeds the paper's limit of 20 (abstract, §2, §4); the design is still made."""
_U_HISTORY = N_LIMIT + 1
"""Past applied inputs kept: u_{t−1} … u_{t−m−1} for any admissible m < N ≤ 40."""


class ControlLaw(IntEnum):
    """The three on-line laws, numbered by their equation in the paper."""

    ONE_MOVE = 7
    """(7): one postulated input value over the whole horizon."""
    TWO_MOVES = 12
    """(12)-(14): one value on [t, t+1], a second one on [t+1, t+N]."""
    TWO_MOVES_HELD = 15
    """(15)-(17): one value on [t, t+2], a second one on [t+2, t+N]."""


def horizon_length(T0: float, tau: float, Ts: float) -> int:
    """Prediction horizon N = integer part of (τ + 3·T0)/Ts (paper §2; 17 for the starting data)."""
    return math.floor((tau + 3.0 * T0) / Ts + 1e-9)


def dominant_time_constant(T_r: float, tau: float) -> float:
    """T0 ≈ (T_r − τ)/3 from the process transient time T_r (step response, ±5 % band) and dead time τ (paper §2).

    The paper's other estimate is the sum of the process time constants.
    """
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f"SOPDTPredictive: dead time tau must be a finite number >= 0 s, got {tau}")
    if not (math.isfinite(T_r) and T_r > tau):
        raise ValueError(f"SOPDTPredictive: transient time T_r must be a finite number > tau = {tau} s, got {T_r}")
    return (T_r - tau) / 3.0


def sampling_time_range(T0: float, tau: float) -> tuple[float, float]:
    """Sampling periods Ts for which N = [(τ + 3·T0)/Ts] lies in 15..20: the interval (L/21, L/15], L = τ + 3·T0.

    For the starting data (T0 = 200 s, τ = 90 s) this is (32.86 s, 46 s]; the paper's T = 40 s lies in it.
    """
    _check_process(1.0, T0, tau)
    span = tau + 3.0 * T0
    return span / (N_MAX + 1), span / N_MIN


def _check_process(K: float, T0: float, tau: float) -> None:
    if not (math.isfinite(K) and K > 0.0):
        raise ValueError(f"SOPDTPredictive: process gain K must be a finite number > 0, got {K}")
    if not (math.isfinite(T0) and T0 > 0.0):
        raise ValueError(f"SOPDTPredictive: dominant time constant T0 must be a finite number > 0 s, got {T0}")
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f"SOPDTPredictive: dead time tau must be a finite number >= 0 s, got {tau}")


@dataclass(frozen=True)
class SOPDTDesign:
    """Result of the off-line computation: model (4) and its unit step response g (5), E (6)."""

    K: float
    T0: float
    tau: float
    xi: float
    Ts: float
    X_k: float
    X_t: float
    X_d: float
    T1: float
    """(2): (1 − 0.5ξ)·X_t·T0."""
    T2: float
    """(2): 0.5ξ·X_t·T0."""
    m: int
    """Integer dead time [X_d·τ/Ts]."""
    N: int
    """Prediction horizon [(τ + 3·T0)/Ts]."""
    a1: float
    a2: float
    b: float
    g: np.ndarray
    """Unit step response g_0 … g_N of model (4): g_i = 0 for i < m, g_{i+m} = h_i (5)."""
    E: float
    """(6): g_m² + … + g_N²."""


def sopdt_design(
    K: float,
    T0: float,
    tau: float,
    Ts: float,
    *,
    xi: float = 0.6,
    X_k: float = 1.5,
    X_t: float = 1.0,
    X_d: float = 1.0,
    N: int | None = None,
) -> SOPDTDesign:
    """Off-line computation of the paper's §2 from the process data K, T0, τ, ξ, Ts and the tuning X_k, X_t, X_d.

    ``N`` overrides the paper's horizon rule N = [(τ + 3·T0)/Ts] (None: the rule); it changes the
    horizon only, not the model (used to study the rule "the prediction horizon should completely
    overlap the transient time", §4).  Refuses K ≤ 0, T0 ≤ 0, τ < 0, ξ outside (0, 1], X_k/X_t ≤ 0,
    X_d < 0, N < 1, N > 40 and m ≥ N, each with a message giving the allowed range.  Warns
    (``HorizonWarning``) for 20 < N ≤ 40: the paper limits N to 20 ("at maximum 20").
    """
    _check_process(K, T0, tau)
    if not (math.isfinite(xi) and 0.0 < xi <= 1.0):
        raise ValueError(f"SOPDTPredictive: time-constant allocation xi must lie in (0, 1], got {xi}")
    if not (math.isfinite(Ts) and Ts > 0.0):
        raise ValueError(f"SOPDTPredictive: sampling period Ts must be a finite number > 0 s, got {Ts}")
    for name, value in (("X_k", X_k), ("X_t", X_t)):
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"SOPDTPredictive: adjustment coefficient {name} must be a finite number > 0, got {value}")
    if not (math.isfinite(X_d) and X_d >= 0.0):
        raise ValueError(f"SOPDTPredictive: adjustment coefficient X_d must be a finite number >= 0, got {X_d}")
    if N is None:
        N = horizon_length(T0, tau, Ts)
    elif not (isinstance(N, int) and N >= 1):
        raise ValueError(f"SOPDTPredictive: horizon N must be an integer >= 1 (None = [(tau + 3 T0)/Ts]), got {N!r}")
    if N > N_LIMIT:
        low, high = sampling_time_range(T0, tau)
        raise ValueError(
            f"SOPDTPredictive: horizon N = [(tau + 3 T0)/Ts] = {N} exceeds {N_LIMIT}; allowed N <= {N_LIMIT}, "
            f"i.e. Ts >= {(tau + 3 * T0) / (N_LIMIT + 1):.4g} s (recommended: N in {N_MIN}..{N_MAX}, "
            f"Ts in ({low:.4g}, {high:.4g}] s)"
        )
    if N > N_MAX:
        low, high = sampling_time_range(T0, tau)
        warnings.warn(
            f"SOPDTPredictive: horizon N = [(tau + 3 T0)/Ts] = {N} exceeds the paper's limit of {N_MAX} "
            f"(N in {N_MIN}..{N_MAX}); for T0 = {T0:g} s, tau = {tau:g} s choose Ts in ({low:.4g}, {high:.4g}] s "
            f"instead of Ts = {Ts:g} s",
            HorizonWarning,
            stacklevel=2,
        )
    m = math.floor(X_d * tau / Ts + 1e-9)
    if m >= N:
        raise ValueError(
            f"SOPDTPredictive: integer dead time m = [X_d tau/Ts] = {m} must be less than the horizon N = {N} "
            f"(allowed 0 <= m <= {N - 1}); reduce X_d or tau"
        )
    T1 = (1.0 - 0.5 * xi) * X_t * T0
    T2 = 0.5 * xi * X_t * T0
    c1, c2 = math.exp(-Ts / T1), math.exp(-Ts / T2)
    a1, a2 = -(c1 + c2), c1 * c2
    b = X_k * K * (1.0 + a1 + a2)
    g = np.zeros(N + 1)
    h_prev2 = h_prev1 = 0.0
    for i in range(N + 1 - m):
        h = b - a1 * h_prev1 - a2 * h_prev2  # (5) with the sign of model (4); see the module docstring
        g[i + m] = h
        h_prev2, h_prev1 = h_prev1, h
    E = float(np.sum(g[m:] ** 2))
    return SOPDTDesign(K, T0, tau, xi, Ts, X_k, X_t, X_d, T1, T2, m, N, a1, a2, b, g, E)


def law_weights(design: SOPDTDesign, law: ControlLaw | int) -> np.ndarray:
    """Weights q_m … q_N such that Δu_t = X_p·Σ q_i·e_{t+i} for law (7), (12) or (15).

    - (7):  q_i = g_i / E
    - (12): q_i = (g_i − a·g_{i−1}) / E1,  E1 = E − a·F1,  F1 = Σ_{m}^{N−1} g_i g_{i+1},  a = F1/(E − g_N²)
    - (15): q_i = (g_i − a·g_{i−2}) / E2,  E2 = E − a·F2,  F2 = Σ_{m}^{N−2} g_i g_{i+2},  a = F2/(E − g_{N−1}² − g_N²)

    With X_p = 1 each is the first postulated move of the unconstrained least-squares
    minimum of criterion (11).  For (15) with m = N − 1 the second move cannot act on the
    horizon (F2 = 0), so a = 0 and (15) is (7).
    """
    law = ControlLaw(law)
    m, N, g, E = design.m, design.N, design.g, design.E
    shifted = np.concatenate([np.zeros(2), g])  # shifted[i + 2 − s] = g_{i−s}, zero before g_0
    g_h = g[m:]
    if law is ControlLaw.ONE_MOVE:
        return g_h / E
    shift = 1 if law is ControlLaw.TWO_MOVES else 2
    g_lag = shifted[m + 2 - shift : N + 3 - shift]
    cross = float(np.dot(g_h, g_lag))  # F1 or F2: g_{i−s} = 0 for i − s < m
    lag_energy = float(np.dot(g_lag, g_lag))  # E − g_N² or E − g_{N−1}² − g_N²
    a = cross / lag_energy if lag_energy > 0.0 else 0.0
    return (g_h - a * g_lag) / (E - a * cross)


def free_response(design: SOPDTDesign, Y: tuple[float, float, float], u_past: np.ndarray) -> np.ndarray:
    """Free response y_t … y_{t+N} by (9)-(10).

    ``Y = (Y_{t−2}, Y_{t−1}, Y_t)`` are the measured outputs, ``u_past[j] = u_{t−1−j}`` the
    applied past inputs (at least m of them).  The input is postulated constant from t on,
    so only the moves u_{t+k−m} − u_{t+k−m−1} already made (k < m) still act on y.
    """
    a1, a2, b, m, N = design.a1, design.a2, design.b, design.m, design.N
    y = np.empty(N + 3)
    y[0:3] = Y
    for k in range(1, N + 1):
        z = u_past[m - k - 1] - u_past[m - k] if k < m else 0.0  # (10)
        y[k + 2] = y[k + 1] - a1 * (y[k + 1] - y[k]) - a2 * (y[k] - y[k - 1]) + b * z  # (9)
    return y[2:]


class SOPDTPredictive:
    """Predictive controller of Cîrtoaje et al. on model (1), sampled every Ts (the paper's T; one ``step`` per sample).

    ``step(r, y)``: measured output Y_t = y, setpoint r; returns u_t =
    ``u_{t−1} + X_p·Σ_{i=m}^{N} q_i·e_{t+i}`` (law (7), (12) or (15); ``law_weights``), then
    limited to ``u_{t−1} ± du_max·Ts`` (rate limit in units per second, 0 = none) and to
    ``[u_min, u_max]``.  The predicted errors are ``e_{t+i} = w_{t+i} − y_{t+i}`` (8) with the
    free response (9)-(10) computed from the *applied* (limited) past inputs, so the limits
    cause no windup.

    Reference trajectory (paper Fig. 5): with ``T_ref > 0`` the setpoint is approached along
    ``w_{t+i} = r − α^i (r − Y_t)``, ``α = exp(−Ts/T_ref)``; ``T_ref = 0`` gives w = r.

    Bumpless start: before the first sample the past outputs equal the first measurement
    and the past inputs equal ``u0``.  A NaN measurement holds the output (Δu = 0), is
    logged, and is replaced in the output history by the model's one-step prediction
    (counted in ``missing_measurements``).

    ``retune(...)`` re-runs the off-line part with new K, T0, τ, ξ, X_k, X_t or X_d (an
    operator change during the run, paper §2) and/or changes X_p, the law or T_ref; it acts
    from the next sample on and keeps the input and output history.
    """

    def __init__(
        self,
        K: float,
        T0: float,
        tau: float,
        Ts: float,
        *,
        xi: float = 0.6,
        X_k: float = 1.5,
        X_t: float = 1.0,
        X_d: float = 1.0,
        X_p: float = 0.6,
        law: ControlLaw | int = ControlLaw.ONE_MOVE,
        T_ref: float = 0.0,
        u_min: float = -math.inf,
        u_max: float = math.inf,
        du_max: float = 0.0,
        u0: float = 0.0,
        N: int | None = None,
    ) -> None:
        self.limits = OutputLimits("SOPDTPredictive", Ts, u_min, u_max, du_max)
        self.limits.check_start(u0)
        self.Ts = Ts
        self.u0 = u0
        self._settings = dict(K=K, T0=T0, tau=tau, xi=xi, X_k=X_k, X_t=X_t, X_d=X_d, X_p=X_p, law=law, T_ref=T_ref, N=N)
        self._initial_settings = dict(self._settings)
        self._apply(self._settings)
        self.reset()

    def retune(self, **changes: float) -> None:
        """Re-run the off-line part with the changed K, T0, tau, xi, X_k, X_t, X_d, X_p, law, T_ref or N.

        An invalid change is refused (ValueError) and the controller keeps its previous design.
        """
        unknown = set(changes) - set(self._settings)
        if unknown:
            raise ValueError(f"SOPDTPredictive: cannot retune {sorted(unknown)}; allowed: {sorted(self._settings)}")
        settings = {**self._settings, **changes}
        self._apply(settings)
        self._settings = settings

    def _apply(self, s: dict) -> None:
        if not (math.isfinite(s["X_p"]) and 0.0 < s["X_p"] <= 1.0):
            raise ValueError(f"SOPDTPredictive: control weighting X_p must lie in (0, 1], got {s['X_p']}")
        if not (math.isfinite(s["T_ref"]) and s["T_ref"] >= 0.0):
            raise ValueError(f"SOPDTPredictive: reference-trajectory time constant T_ref must be >= 0 s (0 = none), got {s['T_ref']}")
        try:
            law = ControlLaw(s["law"])
        except ValueError:
            raise ValueError(f"SOPDTPredictive: law must be 7, 12 or 15 (the paper's equation numbers), got {s['law']}") from None
        design = sopdt_design(s["K"], s["T0"], s["tau"], self.Ts, xi=s["xi"], X_k=s["X_k"], X_t=s["X_t"], X_d=s["X_d"],
                              N=s["N"])
        self.design = design
        self.law = law
        self.X_p = float(s["X_p"])
        self.T_ref = float(s["T_ref"])
        self.weights = law_weights(design, law)
        """q_m … q_N of the selected law (``law_weights``)."""
        alpha = math.exp(-self.Ts / self.T_ref) if self.T_ref > 0.0 else 0.0
        self.approach = alpha ** np.arange(design.m, design.N + 1) if self.T_ref > 0.0 else np.zeros(design.N + 1 - design.m)
        """α^i for i = m … N: w_{t+i} = r − α^i (r − Y_t) (zeros without a reference trajectory)."""

    def reset(self) -> None:
        """Return to the state right after construction (initial design, output u0, no history)."""
        self._settings = dict(self._initial_settings)
        self._apply(self._settings)
        self.u = self.u0
        self.e = 0.0
        self.missing_measurements = 0
        self.free = np.zeros(self.design.N + 1)
        self._u_past: deque[float] = deque([self.u0] * _U_HISTORY, maxlen=_U_HISTORY)
        self._Y_past: deque[float] | None = None  # Y_{t−1}, Y_{t−2}, Y_{t−3}

    def step(self, r: float, y: float) -> float:
        """One sample: setpoint r, measured output y = Y_t; returns the applied input u_t."""
        d = self.design
        u_past = np.asarray(self._u_past)
        if self._Y_past is None:
            if math.isnan(y):
                raise ValueError("SOPDTPredictive: the first measurement is NaN; no history to predict it from")
            self._Y_past = deque([y, y, y], maxlen=3)
        Y1, Y2, Y3 = self._Y_past
        measured = not math.isnan(y)
        if not measured:
            z = u_past[d.m - 1] - u_past[d.m] if d.m >= 1 else 0.0  # Δu_{t−m}; for m = 0 it is Δu_t = 0 (held)
            y = Y1 - d.a1 * (Y1 - Y2) - d.a2 * (Y2 - Y3) + d.b * z  # (9) one step ahead
            self.missing_measurements += 1
            logger.warning("SOPDTPredictive: NaN measurement; output held at u = %g, Y replaced by the prediction %g", self.u, y)
        self.free = free_response(d, (Y2, Y1, y), u_past)
        w = r - self.approach * (r - y)
        errors = w - self.free[d.m :]
        self.e = r - y
        u_prev = self.u
        if measured:
            self.u = self.limits.apply(u_prev + self.X_p * float(np.dot(self.weights, errors)), u_prev)
        self._u_past.appendleft(self.u)
        self._Y_past.appendleft(y)
        return self.u
