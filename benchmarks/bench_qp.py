"""Measured solve time of the QP solvers considered for the constrained GPC (34)–(35), and of one OSMM-GPC step.

Problem size of the header controller: 2 outputs, 2 moving boilers, N2 = 20, Nu = 5, so 10
decision variables, 10 simple bounds (Δu) and 10 two-sided general constraints (u).  The QPs
are taken from the GPC of a random stable 2×2 CARIMA model at set-point errors large enough
that bounds are active (the analytic fast path would otherwise answer).  Every solver must
return the same solution (checked against DAQP to 1e-5).

    python benchmarks/bench_qp.py
"""

from __future__ import annotations

import logging
import time

import numpy as np

from greyfmu.control.gpc import CARIMA, _cumulative, prediction


def problems(count: int = 200, seed: int = 0) -> list[tuple]:
    rng = np.random.default_rng(seed)
    out = []
    Nu, n = 5, 2
    for _ in range(count):
        A = [np.array([1.0, -1.6 + 0.1 * rng.random(), 0.64]) for _ in range(2)]
        B = [[rng.uniform(0.05, 0.3, 2) * (1.0 if j == l else 0.3) for l in range(2)] for j in range(2)]
        pred = prediction(CARIMA(A, B), 1, 20, Nu)
        G = pred.G
        H = 2.0 * (G.T @ G + 0.1 * np.eye(Nu * n))
        g = 2.0 * G.T @ (-np.tile(rng.uniform(-3, 3, 2), 20))
        lower, upper = -0.2 * np.ones(Nu * n), 0.2 * np.ones(Nu * n)
        u_lo, u_hi = -0.5 * np.ones(Nu * n), 0.5 * np.ones(Nu * n)
        out.append((H, g, _cumulative(n, Nu), lower, upper, u_lo, u_hi))
    return out


def solve_daqp(H, g, T, lower, upper, u_lo, u_hi):
    import daqp

    x, _, flag, _ = daqp.solve(H, g, T, np.concatenate([upper, u_hi]), np.concatenate([lower, u_lo]), np.zeros(2 * len(g), dtype=np.intc))
    return x


def solve_quadprog(H, g, T, lower, upper, u_lo, u_hi):
    import quadprog

    I = np.eye(len(g))
    C = np.vstack([I, -I, T, -T]).T
    b = np.concatenate([lower, -upper, u_lo, -u_hi])
    return quadprog.solve_qp(H, -g, C, b)[0]


def solve_osqp(H, g, T, lower, upper, u_lo, u_hi):
    import osqp
    from scipy import sparse

    solver = osqp.OSQP()
    solver.setup(sparse.csc_matrix(H), g, sparse.csc_matrix(np.vstack([np.eye(len(g)), T])), np.concatenate([lower, u_lo]),
                 np.concatenate([upper, u_hi]), verbose=False, eps_abs=1e-9, eps_rel=1e-9, polishing=True)
    return solver.solve().x


def solve_proxsuite(H, g, T, lower, upper, u_lo, u_hi):
    import proxsuite

    n = len(g)
    qp = proxsuite.proxqp.dense.QP(n, 0, n, True)
    qp.settings.eps_abs = 1e-9
    qp.init(H, g, None, None, T, u_lo, u_hi, lower, upper)
    qp.solve()
    return qp.results.x


def solve_scipy(H, g, T, lower, upper, u_lo, u_hi):
    from scipy.optimize import LinearConstraint, minimize

    return minimize(lambda x: 0.5 * x @ H @ x + g @ x, np.zeros_like(g), jac=lambda x: H @ x + g, method="SLSQP",
                    bounds=list(zip(lower, upper)), constraints=[LinearConstraint(T, u_lo, u_hi)],
                    options={"ftol": 1e-12, "maxiter": 500}).x


SOLVERS = {"daqp 0.11.0": solve_daqp, "quadprog 0.1.14": solve_quadprog, "osqp 1.1.3": solve_osqp,
           "proxsuite 0.8.0": solve_proxsuite, "scipy SLSQP": solve_scipy}


def bench_solvers() -> dict[str, float]:
    qps = problems()
    reference = [solve_daqp(*qp) for qp in qps]
    times = {}
    for name, solve in SOLVERS.items():
        try:
            start = time.perf_counter()
            xs = [solve(*qp) for qp in qps]
            elapsed = (time.perf_counter() - start) / len(qps)
        except ImportError:
            print(f"{name:18s} not installed")
            continue
        error = max(np.max(np.abs(x - r)) for x, r in zip(xs, reference))
        times[name] = elapsed
        print(f"{name:18s} {elapsed * 1e6:9.1f} µs per QP   max |x - x_daqp| = {error:.1e}")
    return times


def bench_osmm_step(samples: int = 300) -> float:
    """Mean time of one OSMM-GPC step (MFRLS on 3 groups × 2 outputs, scheduling, QP; N2 = 20, Nu = 5)."""
    from greyfmu.control import ARXStructure, Bounds, OSMMGPC, boiler_groups, identify_group_models
    from greyfmu.plants import SteamHeader, excitation_run

    logging.disable(logging.WARNING)
    structure, groups = ARXStructure(2, 2), boiler_groups(3, 2)
    models = []
    for g, boilers in enumerate(groups):
        Y, M = excitation_run(SteamHeader(), boilers, 3000.0, 10.0, seed=g)
        models.append(identify_group_models(Y, M, boilers, structure))
    controller = OSMMGPC(groups, models, structure, [0.75] * 3, N2=20, Nu=5, bounds=Bounds(0.3, 1.2, -0.01, 0.01), omega=0.01)
    rng = np.random.default_rng(1)
    measurements = 8.75 + 0.3 * rng.standard_normal((samples, 2))
    start = time.perf_counter()
    for y in measurements:
        controller.step([8.75, 8.75], y)
    elapsed = (time.perf_counter() - start) / samples
    print(f"OSMM-GPC step      {elapsed * 1e3:9.3f} ms (3 groups x 2 TS models by MFRLS, scheduling, QP N2=20 Nu=5)")
    return elapsed


if __name__ == "__main__":
    bench_solvers()
    bench_osmm_step()
