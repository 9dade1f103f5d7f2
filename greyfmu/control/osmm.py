"""Optimally scheduled multiple-model GPC (OSMM-GPC): Pan, Shen & Luh (2012) (seed 003), §4.

n boilers, m controlled outputs (header pressures), n > m.  For every one of the C(n, m)
boiler groups (27) and every output j there is a MISO Takagi–Sugeno ARX model (28)

    y_j(k) = Σ_i λ_i(z) [a_i,1 y_j(k−1) + … + Σ_l (b_i,l,0 M_l(k−1) + …) + c_i],

z = the group's firing rates at k−1.  Each sample (:meth:`OSMMGPC.step`): update every TS model
by MFRLS (§3; :class:`greyfmu.control.ts_fuzzy.FuzzyRLS`), form each group's active model
(33) by fuzzily weighting its rules at the current z, compute the regulating efficiencies
(31) and choose the best group (32), solve the m × m constrained GPC (34)–(39) for that
group, add ΔM to the chosen boilers and hold the others.

Regulating efficiency.  (31) as printed, Σ_j ω_j A_j(1)/Σ_l B_jl(1), has units (kg/s)/MPa: its
maximum is the group that needs the most firing per MPa of pressure.  It is the default: run
through the header scenario it reproduces Fig. 5(d) (one switch, (1,3) → (1,2) after the valve-2
step, boiler 1 in the group throughout; docs/osmm_gpc.md).  ``efficiency_form="gain"`` uses the
unit-consistent η = Σ_j ω_j Σ_l B_jl(1)/A_j(1), the steady-state pressure gain per unit firing
(the default until issue 31: it switches 16 times there after the first sample).  A group with a singular denominator
(A_j(1) ≈ 0 or Σ_l B_jl(1) ≈ 0, either form's) or a non-finite η is excluded with a logged
warning; if every group is excluded the previous group is kept.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from greyfmu.control.gpc import (
    CARIMA, Bounds, Prediction, QPResult, cost_weights, prediction, qp_terms, smoothed_reference, solve_moves,
)
from greyfmu.control.ts_fuzzy import FuzzyRLS, Method, TSModel, antecedent_from_partition, batch_wls, gustafson_kessel

logger = logging.getLogger(__name__)

SINGULAR = 1e-9
"""|A_j(1)| or |Σ_l B_jl(1)| below this counts as a singular regulating-efficiency denominator."""


def boiler_groups(n: int, m: int) -> list[tuple[int, ...]]:
    """The C(n, m) control groups (27), as 0-based boiler indices in lexicographic order."""
    return list(itertools.combinations(range(n), m))


@dataclass(frozen=True)
class ARXStructure:
    """Regressor layout x = [y(k−1..k−na), M_1(k−1..k−nb), …, M_m(k−1..k−nb)] of a consequent [π_x, c]."""

    na: int = 1
    nb: int = 1

    def size(self, inputs: int) -> int:
        return self.na + inputs * self.nb

    def regressor(self, y_past: NDArray[np.float64], M_past: NDArray[np.float64]) -> NDArray[np.float64]:
        """x from ``y_past[s]`` = y(k−1−s) and ``M_past[l, s]`` = M_l(k−1−s) (l over the group's boilers)."""
        return np.concatenate([y_past[: self.na], M_past[:, : self.nb].ravel()])

    def polynomials(self, consequent: NDArray[np.float64], inputs: int) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
        """A(q⁻¹) = 1 − Σ a_s q⁻ˢ and B_l (coefficients of M_l(k−1−s)) of one consequent."""
        A = np.concatenate([[1.0], -consequent[: self.na]])
        B = [consequent[self.na + l * self.nb : self.na + (l + 1) * self.nb] for l in range(inputs)]
        return A, B


def regulating_efficiency(model: CARIMA, weights: ArrayLike | None = None, form: str = "printed") -> float:
    """η = Σ_j ω_j A_j(1) / Σ_l B_jl(1), (31) as printed (default, the paper's rule);
    ``form="gain"``: the unit-consistent Σ_j ω_j Σ_l B_jl(1) / A_j(1) (see the module docstring).

    Returns NaN for a singular denominator (A_j(1) ≈ 0 or Σ_l B_jl(1) ≈ 0).
    """
    if form not in ("gain", "printed"):
        raise ValueError(f"regulating efficiency form must be 'gain' or 'printed', got {form!r}")
    w = np.ones(model.outputs) if weights is None else np.asarray(weights, dtype=float)
    total = 0.0
    for j in range(model.outputs):
        a1 = float(model.A[j].sum())
        b1 = float(sum(b.sum() for b in model.B[j]))
        if abs(a1) < SINGULAR or abs(b1) < SINGULAR:
            return math.nan
        total += w[j] * (b1 / a1 if form == "gain" else a1 / b1)
    return total


def choose_group(efficiencies: Sequence[float], previous: int) -> int:
    """Problem (32): the group of largest η; NaN/inf groups excluded (warning); none left → previous."""
    eta = np.asarray(efficiencies, dtype=float)
    finite = np.isfinite(eta)
    for index in np.flatnonzero(~finite):
        logger.warning("OSMM: group %d excluded, singular regulating efficiency", index)
    if not finite.any():
        logger.warning("OSMM: every group excluded; group %d kept", previous)
        return previous
    return int(np.argmax(np.where(finite, eta, -np.inf)))


@dataclass
class OSMMGPC:
    """OSMM-GPC controller (§4).  ``step(r, y)`` once per sample returns all n firing rates M(k).

    ``models[g][j]``: TS model of output j for group ``groups[g]`` on ``structure``; ``M0`` the
    initial firing rates; ``bounds`` (35) per boiler (M and ΔM); ``fixed_group`` (index into
    ``groups``) disables scheduling: a plain GPC on that boiler pair, with the same adaptive
    models.  ``adapt`` switches the on-line estimation (``method``: global/local/mixed FRLS).
    """

    groups: list[tuple[int, ...]]
    models: list[list[TSModel]]
    structure: ARXStructure
    M0: ArrayLike
    N1: int = 1
    N2: int = 20
    Nu: int = 5
    output_weight: float | ArrayLike = 1.0
    move_weight: float | ArrayLike = 1.0
    alpha: float = 0.0
    bounds: Bounds = field(default_factory=Bounds)
    efficiency_weights: ArrayLike | None = None
    efficiency_form: str = "printed"
    """(31) as "printed" (default, the paper's rule) or in the unit-consistent "gain" form (`regulating_efficiency`)."""
    fixed_group: int | None = None
    adapt: bool = True
    method: Method = "mixed"
    forgetting: float = 1.0
    omega: float = 1.0
    solver: str = "daqp"

    def __post_init__(self) -> None:
        self.n = len(np.asarray(self.M0, dtype=float))
        self.m = len(self.models[0])
        self.Lambda, self.Q = cost_weights(self.output_weight, self.move_weight, self.N2 - self.N1 + 1, self.Nu, self.m, self.m)
        self._initial_consequents = [[model.consequents.copy() for model in row] for row in self.models]
        self.reset()

    def reset(self) -> None:
        """Return to the state right after construction: firing M0, the initial TS models (the
        estimators update them in place), fresh estimators, no history, the first group."""
        for row, initial in zip(self.models, self._initial_consequents):
            for model, consequents in zip(row, initial):
                model.consequents = consequents.copy()
        self.M = np.asarray(self.M0, dtype=float).copy()
        depth = max(self.structure.na, self.structure.nb) + 1
        self.y_past: NDArray[np.float64] | None = None
        self.M_past = np.repeat(self.M[:, None], depth, axis=1)  # M_past[:, s] = M(k−1−s)
        self.estimators = [[FuzzyRLS(model, self.method, self.forgetting, self.omega) for model in row] for row in self.models]
        self.group = 0 if self.fixed_group is None else self.fixed_group
        self.efficiencies = np.zeros(len(self.groups))
        self.last_path = ""
        self.plan: NDArray[np.float64] | None = None
        self.plan_group = -1

    def antecedent(self, group: int, M_past: NDArray[np.float64]) -> NDArray[np.float64]:
        """z of a group: its boilers' firing rates at the latest past instant of ``M_past``."""
        return M_past[list(self.groups[group]), 0]

    def active_model(self, group: int) -> CARIMA:
        """The active prediction model (33): each output's rules weighted at the current z."""
        z = self.antecedent(group, self.M[:, None])
        lam, _ = self.models[group][0].antecedent.memberships(z)
        A, B = [], []
        for model in self.models[group]:
            a, b = self.structure.polynomials(model.local_model(z, lam if model.antecedent is self.models[group][0].antecedent else None), self.m)
            A.append(a)
            B.append(b)
        return CARIMA(A, B)

    def _update_models(self, y: NDArray[np.float64]) -> None:
        """MFRLS (or the chosen FRLS) on the sample y(k) with regressors from k−1, k−2, …"""
        for g, boilers in enumerate(self.groups):
            M_group = self.M_past[list(boilers)]
            z = self.antecedent(g, self.M_past)
            shared = self.models[g][0].antecedent
            memberships = shared.memberships(z)
            for j, estimator in enumerate(self.estimators[g]):
                x = self.structure.regressor(self.y_past[j], M_group)
                estimator.update(z, x, y[j], memberships if estimator.model.antecedent is shared else None)

    def step(self, r: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """One sample: estimate, schedule, solve, apply; returns the firing rates M(k) of all boilers."""
        y = np.asarray(y, dtype=float)
        if not np.all(np.isfinite(y)):
            logger.warning("OSMM-GPC: non-finite measurement %s; firing rates held", y)
            return self.M.copy()
        depth = max(self.structure.na, 1) + 1
        self.M_past = np.hstack([self.M[:, None], self.M_past[:, :-1]])  # M_past[:, s] = M(k−1−s)
        if self.y_past is None:
            self.y_past = np.repeat(y[:, None], depth, axis=1)
        elif self.adapt:
            self._update_models(y)  # y_past[:, s] = y(k−1−s) here
        self.y_past = np.hstack([y[:, None], self.y_past[:, :-1]])  # y_past[:, s] = y(k−s) from here on
        models = [self.active_model(g) for g in range(len(self.groups))]
        self.efficiencies = np.array([regulating_efficiency(model, self.efficiency_weights, self.efficiency_form) for model in models])
        if self.fixed_group is None:
            self.group = choose_group(self.efficiencies, self.group)
        result = self._solve(models[self.group], np.asarray(r, dtype=float), y)
        boilers = list(self.groups[self.group])
        self.M[boilers] += result.du
        self.plan, self.plan_group = result.plan, self.group
        self.last_path = result.path
        return self.M.copy()

    def _solve(self, model: CARIMA, r: NDArray[np.float64], y: NDArray[np.float64]) -> QPResult:
        boilers = list(self.groups[self.group])
        pred: Prediction = prediction(model, self.N1, self.N2, self.Nu)
        dM_past = -np.diff(self.M_past[boilers], axis=1)  # ΔM(k−1−p) = M(k−1−p) − M(k−2−p)
        u_depth = pred.u_depth
        if dM_past.shape[1] < u_depth:
            dM_past = np.hstack([dM_past, np.zeros((len(boilers), u_depth - dM_past.shape[1]))])
        f = pred.free_response(self.y_past, dM_past)
        w = smoothed_reference(y, r, self.alpha, self.N1, self.N2)
        H, g = qp_terms(pred.G, self.Lambda, self.Q, f, w)
        selected = Bounds(
            *(np.broadcast_to(np.asarray(v, dtype=float), (self.n,))[boilers] for v in
              (self.bounds.u_min, self.bounds.u_max, self.bounds.du_min, self.bounds.du_max))
        )
        plan = self.plan if self.plan_group == self.group else None
        return solve_moves(H, g, self.M[boilers], selected, self.Nu, plan, self.solver)


def identify_group_models(
    Y: ArrayLike, M: ArrayLike, boilers: tuple[int, ...], structure: ARXStructure, rules: int = 3, seed: int = 0
) -> list[TSModel]:
    """Initial TS models (28) of one group from sampled data (Y[k] outputs, M[k] firing applied after
    Y[k]): Gustafson–Kessel clustering of z = M_group(k−1) for the antecedents and local batch
    weighted least squares for the consequents (paper §3 and §5.2: "initial groups of
    prediction models by TS modeling")."""
    Y, M = np.asarray(Y, dtype=float), np.asarray(M, dtype=float)[:, list(boilers)]
    start = max(structure.na, structure.nb)
    Z = M[start - 1 : -1]
    _, U, _ = gustafson_kessel(Z, rules, seed=seed)
    antecedent = antecedent_from_partition(Z, U)
    models = []
    for j in range(Y.shape[1]):
        X = np.array(
            [structure.regressor(Y[k - 1 :: -1, j], M[k - 1 :: -1].T) for k in range(start, len(Y))]
        )
        models.append(batch_wls(antecedent, Z, X, Y[start:, j], method="local"))
    return models
