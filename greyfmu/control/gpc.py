"""Multivariable generalized predictive control (GPC) on CARIMA models, with constraints.

Pan, Shen & Luh (2012) (seed 003), §4.2, equations (34)–(39); Clarke, Mohtadi & Tuffs (1987);
``recovered-models.md`` §7.  Each output j has the MISO CARIMA model (28)

    A_j(q⁻¹) y_j(k) = Σ_l B_jl(q⁻¹) u_l(k−1) + c_j + e_j(k)/Δ,   Δ = 1 − q⁻¹,

A_j monic (a diagonal polynomial matrix A), B_jl's coefficient s multiplying u_l(k−1−s)
(a dead time is leading zeros).  The affine term c_j disappears in the incremental form.
The j-step predictions (37) come from the Diophantine identity 1 = E_j Ã + q⁻ʲ F_j (39),
Ã = ΔA, solved by recursion, and E_j B = G_j + q⁻ʲ H_j (38).

The cost (34) weights the output error by λ(j) and the moves by Q(j); the reference is
smoothed by (36); the moves are bounded by (35): Δu_min ≤ Δu ≤ Δu_max and
u_min ≤ u ≤ u_max over the control horizon.  The constrained problem is a QP solved by DAQP
(``daqp`` on PyPI, a dual active-set solver: see ``benchmarks/bench_qp.py`` for the
measured comparison); the unconstrained law Δu = −H⁻¹g is the fast path, used when it
satisfies every bound (then it is the QP's solution).

Reference smoothing: (36) as printed, w(k) = Y_r(k), w(k+j) = a w(k+j−1) + (1−a) w(k), makes
w constant; we use Clarke's form it garbles, w(k) = y(k), w(k+j) = a w(k+j−1) + (1−a) Y_r(k).
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

logger = logging.getLogger(__name__)


@dataclass
class CARIMA:
    """MIMO CARIMA model with diagonal A: ``A[j]`` = [1, a_1, …], ``B[j][l]`` = [b_0, b_1, …] (of u_l(k−1−s))."""

    A: list[NDArray[np.float64]]
    B: list[list[NDArray[np.float64]]]

    def __post_init__(self) -> None:
        self.A = [np.atleast_1d(np.asarray(a, dtype=float)) for a in self.A]
        self.B = [[np.atleast_1d(np.asarray(b, dtype=float)) for b in row] for row in self.B]
        if len(self.B) != len(self.A) or len({len(row) for row in self.B}) != 1:
            raise ValueError("CARIMA: B must have one row per output, each with one polynomial per input")
        for j, a in enumerate(self.A):
            if a[0] != 1.0:
                raise ValueError(f"CARIMA: A[{j}] must be monic (leading coefficient 1), got {a[0]}")
        if not all(np.all(np.isfinite(p)) for p in self.A + [b for row in self.B for b in row]):
            raise ValueError("CARIMA: coefficients must be finite")

    @property
    def outputs(self) -> int:
        return len(self.A)

    @property
    def inputs(self) -> int:
        return len(self.B[0])

    def steady_state_gain(self) -> NDArray[np.float64]:
        """K_jl = B_jl(1)/A_j(1) (q⁻¹ = 1); inf where A_j(1) = 0."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.array([[b.sum() / a.sum() for b in row] for a, row in zip(self.A, self.B)])


def diophantine(A_tilde: ArrayLike, horizon: int) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    """E_j (degree j−1) and F_j (degree deg Ã − 1) of 1 = E_j Ã + q⁻ʲ F_j, j = 1..horizon, by recursion.

    E_1 = 1, F_1 = q(1 − Ã); with r = F_j,0: E_{j+1} = E_j + r q⁻ʲ, F_{j+1,i} = F_{j,i+1} − r Ã_{i+1}.
    """
    a = np.asarray(A_tilde, dtype=float)
    n = len(a) - 1
    e = np.zeros(horizon)
    F = np.zeros((horizon, n))
    e[0] = 1.0
    F[0] = -a[1:]
    for j in range(1, horizon):
        r = F[j - 1, 0]
        e[j] = r
        F[j, :-1] = F[j - 1, 1:]
        F[j] -= r * a[1:]
    return [e[: j + 1] for j in range(horizon)], list(F)


def horizon_weights(value: float | ArrayLike | Sequence[ArrayLike], length: int, channels: int, name: str) -> NDArray[np.float64]:
    """A weight given as a scalar, per channel (channels,), or per horizon step (length × channels)."""
    w = np.asarray(value, dtype=float)
    if w.ndim == 0 or w.shape == (channels,):
        w = np.broadcast_to(w, (length, channels))
    elif w.shape == (length,):
        w = np.repeat(w[:, None], channels, axis=1)
    elif w.shape != (length, channels):
        raise ValueError(f"GPC: {name} must be a scalar, ({channels},), ({length},) or ({length}, {channels})")
    if np.any(w < 0.0) or not np.all(np.isfinite(w)):
        raise ValueError(f"GPC: {name} must be finite and >= 0")
    return np.array(w)


@dataclass
class Prediction:
    """Stacked predictions ŷ = G ΔU + Fy·y_past + Hu·Δu_past over j = N1..N2 (rows: step, then output).

    ΔU = [Δu(k); …; Δu(k+Nu−1)]; ``y_past[j, s]`` = y_j(k−s); ``du_past[l, p]`` = Δu_l(k−1−p).
    """

    G: NDArray[np.float64]
    Fy: NDArray[np.float64]
    Hu: NDArray[np.float64]
    y_depth: int
    u_depth: int

    def free_response(self, y_past: NDArray[np.float64], du_past: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.Fy @ y_past[:, : self.y_depth].ravel() + self.Hu @ du_past[:, : self.u_depth].ravel()


def prediction(model: CARIMA, N1: int, N2: int, Nu: int) -> Prediction:
    """Prediction matrices (37)–(39) of ``model`` for horizons N1..N2 and control horizon Nu.

    E_j is the first j coefficients of E_N2, so the future part G_j of E_j B (38) is the first
    j step-response coefficients g_0..g_{j−1} of E_N2 B; the past part H_j is E_j B beyond q⁻ʲ⁺¹.
    """
    m, n = model.outputs, model.inputs
    y_depth = max(len(a) for a in model.A)
    u_depth = max(1, max(len(b) for row in model.B for b in row) - 1)
    steps = np.arange(N1, N2 + 1)
    rows = len(steps) * m
    G = np.zeros((rows, Nu * n))
    Fy = np.zeros((rows, m * y_depth))
    Hu = np.zeros((rows, n * u_depth))
    lag = steps[:, None] - 1 - np.arange(Nu)[None, :]
    valid = lag >= 0
    for j in range(m):
        E, F = diophantine(np.convolve(model.A[j], [1.0, -1.0]), N2)
        Fy[j::m, j * y_depth : j * y_depth + len(model.A[j])] = np.array(F[N1 - 1 : N2])
        for l in range(n):
            b = model.B[j][l]
            g = np.convolve(E[-1], b)[:N2]
            G[j::m, l::n] = np.where(valid, g[np.maximum(lag, 0)], 0.0)
            e = E[-1]
            for p in range(len(b) - 1):  # H_j,p = Σ_{q>p} b_q e_{j+p−q}  (e_t = 0 for t < 0)
                index = steps[:, None] + p - np.arange(p + 1, len(b))[None, :]
                Hu[j::m, l * u_depth + p] = (np.where(index >= 0, e[np.maximum(index, 0)], 0.0) * b[p + 1 :]).sum(axis=1)
    return Prediction(G, Fy, Hu, y_depth, u_depth)


def smoothed_reference(y: ArrayLike, r: ArrayLike, alpha: float, N1: int, N2: int) -> NDArray[np.float64]:
    """Reference trajectory (36): w(k) = y(k), w(k+j) = α w(k+j−1) + (1−α) r, stacked for j = N1..N2."""
    y, r = np.asarray(y, dtype=float), np.asarray(r, dtype=float)
    steps = np.arange(N1, N2 + 1)[:, None]
    return (r + alpha**steps * (y - r)).ravel()


def cost_weights(
    output_weight: float | ArrayLike, move_weight: float | ArrayLike, costed: int, Nu: int, outputs: int, inputs: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Λ = diag λ(j) over the ``costed`` = N2 − N1 + 1 predicted outputs and Q = diag Q(j) over the Nu moves of (34)."""
    Lambda = np.diag(horizon_weights(output_weight, costed, outputs, "output_weight").ravel())
    Q = np.diag(horizon_weights(move_weight, Nu, inputs, "move_weight").ravel())
    return Lambda, Q


def qp_terms(
    G: NDArray[np.float64], Lambda: NDArray[np.float64], Q: NDArray[np.float64], f: NDArray[np.float64], w: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cost (34) as ½ ΔUᵀ H ΔU + gᵀ ΔU: with the predictions ŷ = G ΔU + f (37) and the reference w (36),
    J = (ŷ − w)ᵀ Λ (ŷ − w) + ΔUᵀ Q ΔU gives H = 2 (Gᵀ Λ G + Q), g = 2 Gᵀ Λ (f − w)."""
    return 2.0 * (G.T @ Lambda @ G + Q), 2.0 * G.T @ Lambda @ (f - w)


@dataclass
class Bounds:
    """Constraints (35) on the manipulated variables, per input (scalars broadcast)."""

    u_min: ArrayLike = -math.inf
    u_max: ArrayLike = math.inf
    du_min: ArrayLike = -math.inf
    du_max: ArrayLike = math.inf


@dataclass
class QPResult:
    """First move, whole plan, and how it was found: ``analytic``, ``qp`` or ``fallback``."""

    du: NDArray[np.float64]
    plan: NDArray[np.float64]
    path: str


def solve_moves(
    H: NDArray[np.float64],
    g: NDArray[np.float64],
    u_prev: NDArray[np.float64],
    bounds: Bounds,
    Nu: int,
    previous_plan: NDArray[np.float64] | None = None,
    solver: str = "daqp",
) -> QPResult:
    """min ½ xᵀHx + gᵀx s.t. (35), x = ΔU; analytic law if it is feasible, else the QP.

    Infeasible QP (e.g. u(k−1) already outside [u_min, u_max] by more than one move can
    correct): the previous feasible plan's next move, clipped to the Δu bounds and as far as
    possible towards [u_min, u_max], is used, with a logged warning (documented fallback).
    """
    n = len(u_prev)
    lower, upper = _box(bounds, n, Nu)
    T = _cumulative(n, Nu)
    u_lo = np.tile(np.broadcast_to(np.asarray(bounds.u_min, dtype=float), (n,)) - u_prev, Nu)
    u_hi = np.tile(np.broadcast_to(np.asarray(bounds.u_max, dtype=float), (n,)) - u_prev, Nu)
    x = -np.linalg.solve(H, g)
    tol = 1e-9
    if np.all(x >= lower - tol) and np.all(x <= upper + tol) and np.all(T @ x >= u_lo - tol) and np.all(T @ x <= u_hi + tol):
        return QPResult(x[:n], x, "analytic")
    x, ok = _qp(H, g, T, lower, upper, u_lo, u_hi, solver)
    if ok:
        return QPResult(x[:n], x, "qp")
    if previous_plan is not None and len(previous_plan) >= 2 * n:
        du = previous_plan[n : 2 * n].copy()
    else:
        du = np.zeros(n)
    target = np.clip(u_prev + du, np.broadcast_to(bounds.u_min, (n,)), np.broadcast_to(bounds.u_max, (n,))) - u_prev
    du = np.clip(target, lower[:n], upper[:n])
    du = np.where(np.isfinite(du), du, 0.0)
    logger.warning("GPC: infeasible QP at u(k-1) = %s; previous feasible move %s used", u_prev, du)
    return QPResult(du, np.concatenate([du, np.zeros(n * (Nu - 1))]), "fallback")


@functools.lru_cache(maxsize=32)
def _cumulative(n: int, Nu: int) -> NDArray[np.float64]:
    """T (shared, do not modify) with T ΔU = [u(k) − u(k−1); …; u(k+Nu−1) − u(k−1)]: block lower triangle of identities."""
    T = np.kron(np.tril(np.ones((Nu, Nu))), np.eye(n))
    return T


def _box(bounds: Bounds, n: int, Nu: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lower = np.tile(np.broadcast_to(np.asarray(bounds.du_min, dtype=float), (n,)), Nu)
    upper = np.tile(np.broadcast_to(np.asarray(bounds.du_max, dtype=float), (n,)), Nu)
    return lower, upper


_INF = 1e20


def _qp(
    H: NDArray[np.float64],
    g: NDArray[np.float64],
    T: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    u_lo: NDArray[np.float64],
    u_hi: NDArray[np.float64],
    solver: str,
) -> tuple[NDArray[np.float64], bool]:
    """Solve the constrained QP; returns (x, feasible-and-optimal)."""
    if np.any(lower > upper) or np.any(u_lo > u_hi):
        return np.zeros_like(g), False
    clip = lambda v: np.clip(v, -_INF, _INF)  # noqa: E731 - solvers want finite bounds
    if solver == "daqp":
        import daqp

        x, _, flag, _ = daqp.solve(
            np.ascontiguousarray(H), np.ascontiguousarray(g), np.ascontiguousarray(T),
            np.concatenate([clip(upper), clip(u_hi)]), np.concatenate([clip(lower), clip(u_lo)]),
            np.zeros(2 * len(g), dtype=np.intc),
        )
        return np.asarray(x), flag == 1 and bool(np.all(np.isfinite(x)))
    if solver == "scipy":
        from scipy.optimize import LinearConstraint, minimize

        result = minimize(
            lambda x: 0.5 * x @ H @ x + g @ x, np.zeros_like(g), jac=lambda x: H @ x + g, method="trust-constr",
            constraints=[LinearConstraint(np.vstack([np.eye(len(g)), T]), np.concatenate([lower, u_lo]), np.concatenate([upper, u_hi]))],
            options={"gtol": 1e-10, "xtol": 1e-12, "maxiter": 5000},
        )
        return result.x, bool(result.success)
    raise ValueError(f"GPC: unknown QP solver {solver!r} (use 'daqp' or 'scipy')")


@dataclass
class GPC:
    """Constrained MIMO GPC: ``step(r, y)`` once per sample returns the new input u(k).

    ``N1, N2`` costing horizons, ``Nu`` control horizon, ``output_weight`` λ(j) and
    ``move_weight`` Q(j) of (34) (scalar, per channel, per step, or per step and channel),
    ``alpha`` the reference smoothing a of (36), ``bounds`` the constraints (35), ``u0`` the
    initial input.  ``set_model`` replaces the prediction model (adaptive use).
    """

    model: CARIMA
    N1: int = 1
    N2: int = 20
    Nu: int = 5
    output_weight: float | ArrayLike = 1.0
    move_weight: float | ArrayLike = 1.0
    alpha: float = 0.0
    bounds: Bounds = field(default_factory=Bounds)
    u0: ArrayLike = 0.0
    solver: str = "daqp"

    def __post_init__(self) -> None:
        if not (1 <= self.N1 <= self.N2 and 1 <= self.Nu):
            raise ValueError(f"GPC: need 1 <= N1 <= N2 and Nu >= 1, got N1={self.N1}, N2={self.N2}, Nu={self.Nu}")
        if not 0.0 <= self.alpha < 1.0:
            raise ValueError(f"GPC: reference smoothing alpha must be in [0, 1), got {self.alpha}")
        self.Lambda, self.Q = cost_weights(
            self.output_weight, self.move_weight, self.N2 - self.N1 + 1, self.Nu, self.model.outputs, self.model.inputs
        )
        self._initial_model = self.model
        self.reset()

    def reset(self) -> None:
        """Return to the state right after construction (initial model, input u0, no history)."""
        m, n = self.model.outputs, self.model.inputs
        self.u = np.broadcast_to(np.asarray(self.u0, dtype=float), (n,)).copy()
        self.y_past = np.zeros((m, 0))
        self.du_past = np.zeros((n, 64))
        self.plan: NDArray[np.float64] | None = None
        self.last_path = ""
        self.set_model(self._initial_model)

    def set_model(self, model: CARIMA) -> None:
        if (model.outputs, model.inputs) != (self.model.outputs, self.model.inputs):
            raise ValueError("GPC: a new model must have the same numbers of inputs and outputs")
        self.model = model
        self.pred = prediction(model, self.N1, self.N2, self.Nu)
        if self.du_past.shape[1] < self.pred.u_depth:
            self.du_past = np.hstack([self.du_past, np.zeros((self.du_past.shape[0], self.pred.u_depth))])

    def moves(self, r: ArrayLike, y: ArrayLike) -> QPResult:
        """Solve (34)–(35) for the current measurement y(k) (after ``observe``) and set-point r."""
        y = np.asarray(y, dtype=float)
        f = self.pred.free_response(self.y_past, self.du_past)
        w = smoothed_reference(y, r, self.alpha, self.N1, self.N2)
        H, g = qp_terms(self.pred.G, self.Lambda, self.Q, f, w)
        return solve_moves(H, g, self.u, self.bounds, self.Nu, self.plan, self.solver)

    def observe(self, y: ArrayLike) -> None:
        """Shift the output history with the new measurement y(k)."""
        y = np.asarray(y, dtype=float)[:, None]
        depth = max(self.pred.y_depth, 1)
        self.y_past = np.hstack([y, self.y_past])[:, :depth]
        if self.y_past.shape[1] < depth:
            self.y_past = np.hstack([self.y_past, np.repeat(self.y_past[:, -1:], depth - self.y_past.shape[1], axis=1)])

    def apply(self, result: QPResult) -> NDArray[np.float64]:
        """Apply the first move: u(k) = u(k−1) + Δu(k); shift the move history."""
        self.u = self.u + result.du
        self.du_past = np.hstack([result.du[:, None], self.du_past[:, :-1]])
        self.plan = result.plan
        self.last_path = result.path
        return self.u.copy()

    def step(self, r: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """One sample: measure y(k), solve, apply; returns u(k)."""
        if not np.all(np.isfinite(np.asarray(y, dtype=float))):
            logger.warning("GPC: non-finite measurement %s; input held", y)
            return self.u.copy()
        self.observe(y)
        return self.apply(self.moves(r, y))
