"""Parallel-coursing utility units with a header (PUUH): 3 boilers, 2 turbines, 2 header segments.

Pan, Shen & Luh (2012) (seed 003), §2 and §5.2; the paper's simulator (its ref. [11]) is not
available, so this is OUR lumped model, ``recovered-models.md`` §8, with two changes said there
and here: (1) each boiler has its own load-dependent efficiency curve, so the marginal steam per
unit fuel differs between boilers and changes with load (what OSMM scheduling exploits);
(2) the boiler-outlet and tie-pipe flows are linear in the pressure drop (secant conductances
at rated flow) instead of square-root laws, which removes the non-smooth zero-flow point of
the tie pipe and its stiffness (§8's numerical note).  Units MPa, kg/s, s.

Boiler B1 feeds segment 1 (pressure P_m2, turbine T1), B3 segment 2 (P_m4, T2), and B2, in
the middle of the header as in the paper's Fig. 1 (B1–T1–B2–T2–B3), feeds both through two
outlets of half the conductance each; a tie pipe joins the segments.  (§8 put B1 and B2 on
the same segment, which makes the pair (1, 2) unable to set P_m2 and P_m4 independently.)  Per boiler i (firing demand u_i in p.u. of rated firing):

    τ_f dq_i/dt  = u_i − q_i                               firing lag
    τ_g dw_gi/dt = w_N q_i η_i(q_i)/η_ref − w_gi             steam generation
    C_b dP_bi/dt = w_gi − w_si,   w_si = G_s (P_bi − P_seg(i))   (B2: G_s/2 to each segment)
    η_i(q) = η_max,i − c_i (q − q*_i)²                      efficiency curve
    F_i = F_N q_i                                           fuel consumption [kg/s]

Header: C_h dP_s/dt = Σ_i→s w_si − w_ts ∓ w_link, w_link = G_l (P_1 − P_2); turbines
w_tj = K_tj v_j P_seg(j) (valve opening v_j as a fraction).  K_t1, K_t2 are set so that the
design point (all boilers at 0.75 p.u., both valves at 50 %, both segments at 8.75 MPa) has no
tie flow.  Fixed-step RK4 with sub-steps of at most ``max_substep`` (0.25 s; the fastest mode, a
header node, is about −6.3 s⁻¹) over each caller step; inputs held over the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq, minimize_scalar

from greyfmu.plants.integration import rk4


@dataclass(frozen=True)
class HeaderParameters:
    """Design values (RECONSTRUCTED, recovered-models.md §8 adapted: see the module docstring)."""

    w_N: float = 61.0  # rated steam flow per boiler [kg/s] (paper §5.2)
    F_N: float = 7.2  # fuel at rated firing [kg/s]; 3 boilers at 0.75 p.u. burn 16.2 kg/s (Table 3's scale)
    eta_ref: float = 0.9
    eta_max: tuple[float, float, float] = (0.92, 0.88, 0.90)
    q_star: tuple[float, float, float] = (0.95, 0.85, 0.75)
    curvature: tuple[float, float, float] = (0.05, 0.05, 0.3)
    tau_f: float = 15.0  # [s]
    tau_g: float = 60.0  # [s]
    C_b: float = 1400.0  # [kg/MPa]
    C_h: float = 100.0  # [kg/MPa]
    G_s: float = 244.0  # boiler outlet conductance [kg/s/MPa] (61 kg/s at 0.25 MPa)
    G_l: float = 120.0  # tie-pipe conductance [kg/s/MPa]
    P_set: float = 8.75  # design header pressure [MPa]
    q_design: float = 0.75
    v_design: float = 0.5

    def efficiency(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(self.eta_max) - np.asarray(self.curvature) * (q - np.asarray(self.q_star)) ** 2

    def steam(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Steady steam generation w_N q η(q)/η_ref of each boiler."""
        return self.w_N * q * self.efficiency(q) / self.eta_ref

    def marginal_steam(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """d(steam)/d(fuel) of each boiler [kg steam / kg fuel]: what regulating efficiency tracks."""
        qs, c = np.asarray(self.q_star), np.asarray(self.curvature)
        return self.w_N / (self.eta_ref * self.F_N) * (self.efficiency(q) - 2.0 * c * q * (q - qs))

    def turbine_constants(self) -> tuple[float, float]:
        """K_t1, K_t2 [kg/s/MPa per unit opening] balancing the design point without tie flow."""
        w = self.steam(np.full(3, self.q_design))
        return (w[0] + 0.5 * w[1]) / (self.v_design * self.P_set), (w[2] + 0.5 * w[1]) / (self.v_design * self.P_set)


@dataclass
class SteamHeader:
    """State x = [q_1..3, w_g1..3, P_b1..3, P_1, P_2]; starts at the equilibrium for ``u0``, ``v0``."""

    params: HeaderParameters = field(default_factory=HeaderParameters)
    u0: ArrayLike | None = None
    v0: ArrayLike = (0.5, 0.5)
    max_substep: float = 0.25

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_substep) and self.max_substep > 0.0):
            raise ValueError(f"SteamHeader: max_substep must be a finite number > 0, got {self.max_substep}")
        self.K_t = np.array(self.params.turbine_constants())
        u0 = np.full(3, self.params.q_design) if self.u0 is None else np.asarray(self.u0, dtype=float)
        self.x0 = self.equilibrium(u0, np.asarray(self.v0, dtype=float))
        self.reset()

    def reset(self) -> None:
        """Back to the equilibrium of ``u0``, ``v0``."""
        self.x = self.x0.copy()

    def equilibrium(self, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Steady state for firing u and valves v (linear in the pressures once the steam is known)."""
        p = self.params
        w = p.steam(u)
        k1, k2 = self.K_t * v
        # segment balances (derivative at rest): B2's flow G_s (P_b2 − (P1 + P2)/2) = w2 enters segment 1 as
        # 0.5 G_s (P_b2 − P1) = w2/2 + G_s (P2 − P1)/4 and segment 2 as w2/2 − G_s (P2 − P1)/4, so
        # w1 + w2/2 = k1 P1 + (G_l + G_s/4)(P1 − P2); w3 + w2/2 = k2 P2 − (G_l + G_s/4)(P1 − P2)
        tie = p.G_l + 0.25 * p.G_s
        M = np.array([[k1 + tie, -tie], [-tie, k2 + tie]])
        P1, P2 = np.linalg.solve(M, [w[0] + 0.5 * w[1], w[2] + 0.5 * w[1]])
        seg = np.array([P1, 0.5 * (P1 + P2), P2])
        return np.concatenate([u, w, seg + w / p.G_s, [P1, P2]])

    def derivative(self, x: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        p = self.params
        q, w_g, P_b, P1, P2 = x[0:3], x[3:6], x[6:9], x[9], x[10]
        w_s = p.G_s * (P_b - np.array([P1, 0.5 * (P1 + P2), P2]))
        half2_1 = 0.5 * p.G_s * (P_b[1] - P1)  # B2's flow into segment 1 (the rest goes to segment 2)
        link = p.G_l * (P1 - P2)
        w_t = self.K_t * v * np.array([P1, P2])
        return np.concatenate(
            [
                (u - q) / p.tau_f,
                (p.steam(np.maximum(q, 0.0)) - w_g) / p.tau_g,
                (w_g - w_s) / p.C_b,
                [(w_s[0] + half2_1 - w_t[0] - link) / p.C_h, (w_s[2] + w_s[1] - half2_1 - w_t[1] + link) / p.C_h],
            ]
        )

    def advance(self, t: float, h: float, u: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
        """Integrate [t, t + h] with firing demands u (p.u.) and valve openings v (fraction) held; returns
        the header pressures at t + h (time-invariant: t only follows the ``Plant`` contract)."""
        if h < 0.0:
            raise ValueError(f"SteamHeader: step h must be >= 0, got {h}")
        u, v = np.asarray(u, dtype=float), np.clip(np.asarray(v, dtype=float), 0.0, None)
        if h == 0.0:
            return self.pressures
        self.x = rk4(lambda _, x: self.derivative(x, u, v), self.x, h, self.max_substep)
        return self.pressures

    @property
    def pressures(self) -> NDArray[np.float64]:
        """Header pressures [P_m2, P_m4] in MPa."""
        return self.x[9:11].copy()

    @property
    def fuel(self) -> NDArray[np.float64]:
        """Fuel consumption of each boiler [kg/s]."""
        return self.params.F_N * self.x[0:3]


def excitation_run(
    plant: SteamHeader, boilers: tuple[int, ...], duration: float, Ts: float, hold: float = 120.0, low: float = 0.6,
    high: float = 1.0, seed: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Open-loop identification experiment: random firing levels in [low, high] held ``hold`` s on
    ``boilers`` (the others at their design firing), valves at their design opening.

    Returns the header pressures Y (N × 2) and firing demands M (N × 3) sampled every ``Ts``:
    Y[k] is measured at t_k, M[k] applied over [t_k, t_k + Ts).
    """
    rng = np.random.default_rng(seed)
    samples = int(round(duration / Ts))
    per_hold = max(1, int(round(hold / Ts)))
    M = np.tile(plant.x0[0:3], (samples, 1))
    for boiler in boilers:
        levels = rng.uniform(low, high, size=samples // per_hold + 1)
        M[:, boiler] = np.repeat(levels, per_hold)[:samples]
    Y = np.empty((samples, 2))
    plant.reset()
    v = np.asarray(plant.v0, dtype=float)
    for k in range(samples):
        Y[k] = plant.pressures
        plant.advance(k * Ts, Ts, M[k], v)
    return Y, M


def segment_demands(params: HeaderParameters, valves: ArrayLike) -> NDArray[np.float64]:
    """Steam each header segment's turbine takes at P_set [kg/s]: D_j = K_tj v_j P_set."""
    return np.asarray(params.turbine_constants()) * np.asarray(valves, dtype=float) * params.P_set


def firing_for_steam(params: HeaderParameters, boiler: int, steam: float, q_max: float = 1.5) -> float:
    """The steady firing q in [0, q_max] at which ``boiler`` generates ``steam`` kg/s, on the rising part of its
    steam curve; NaN if the steam at q_max is below it (or at 0 above it)."""
    def excess(q: float) -> float:
        return float(params.steam(np.full(3, q))[boiler]) - steam

    if not excess(0.0) <= 0.0 <= excess(q_max):
        return math.nan
    return float(brentq(excess, 0.0, q_max, xtol=1e-12))


def steady_firing(
    params: HeaderParameters, boilers: tuple[int, int], valves: ArrayLike, held: float, q_max: float = 1.5
) -> NDArray[np.float64]:
    """Steady firing of the three boilers when the pair ``boilers`` holds both segments at P_set
    (no tie flow) and the third boiler fires ``held``: the segment balances
    w_1 + w_2/2 = D_1, w_3 + w_2/2 = D_2 fix the pair's steam.  NaN where no firing in [0, q_max] gives it."""
    D1, D2 = segment_demands(params, valves)
    other = ({0, 1, 2} - set(boilers)).pop()
    w = np.zeros(3)
    w[other] = params.steam(np.full(3, held))[other]
    if other == 0:
        w[1] = 2.0 * (D1 - w[0])
        w[2] = D2 - w[1] / 2.0
    elif other == 1:
        w[0], w[2] = D1 - w[1] / 2.0, D2 - w[1] / 2.0
    else:
        w[1] = 2.0 * (D2 - w[2])
        w[0] = D1 - w[1] / 2.0
    q = np.array([firing_for_steam(params, i, w[i], q_max) for i in range(3)])
    q[other] = held
    return q


def least_fuel_firing(params: HeaderParameters, valves: ArrayLike, q_min: float, q_max: float) -> NDArray[np.float64]:
    """The steady firing in [q_min, q_max] of least fuel that holds both segments at P_set: the
    minimum over the one-parameter family w_2 (w_1 = D_1 − w_2/2, w_3 = D_2 − w_2/2)."""
    D1, D2 = segment_demands(params, valves)

    def firing(w2: float) -> NDArray[np.float64]:
        return np.array([firing_for_steam(params, i, w) for i, w in enumerate((D1 - w2 / 2.0, w2, D2 - w2 / 2.0))])

    def fuel(w2: float) -> float:
        q = firing(w2)
        return float(np.sum(q)) if np.all(np.isfinite(q)) and np.all((q >= q_min) & (q <= q_max)) else math.inf

    grid = np.linspace(0.0, 2.0 * min(D1, D2), 401)
    fuels = [fuel(w2) for w2 in grid]
    best = int(np.argmin(fuels))
    if not math.isfinite(fuels[best]):
        raise ValueError(f"least_fuel_firing: no firing in [{q_min}, {q_max}] holds both segments at P_set for valves {valves}")
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    if math.isfinite(fuel(low)) and math.isfinite(fuel(high)):
        refined = float(minimize_scalar(fuel, bounds=(low, high), method="bounded", options={"xatol": 1e-9}).x)
        if fuel(refined) <= fuels[best]:
            return firing(refined)
    return firing(float(grid[best]))
