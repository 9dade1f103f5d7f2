"""MIMO GPC: Diophantine recursion (38)–(39), predictions, analytic law vs QP, constraints (34)–(35)."""

import logging

import numpy as np
import pytest
from scipy.signal import lfilter

from greyfmu.control.gpc import CARIMA, GPC, Bounds, diophantine, prediction, smoothed_reference, solve_moves

A2 = [np.array([1.0, -1.5, 0.56]), np.array([1.0, -0.8])]
B2 = [[np.array([0.0, 0.3, 0.1]), np.array([0.2])], [np.array([0.1, 0.05]), np.array([0.0, 0.0, 0.4])]]


def series_division(A_tilde, j):
    """E_j = first j terms of 1/Ã by long division; F_j from the remainder q^j (1 − E_j Ã)."""
    e = lfilter([1.0], A_tilde, np.r_[1.0, np.zeros(j - 1)])
    remainder = np.r_[1.0, np.zeros(len(A_tilde) + j)] - np.r_[np.convolve(e, A_tilde), np.zeros(j + 1)][: len(A_tilde) + j + 1]
    return e, remainder[j : j + len(A_tilde) - 1]


def test_diophantine_recursion_matches_polynomial_division():
    A_tilde = np.convolve([1.0, -1.4, 0.45], [1.0, -1.0])
    E, F = diophantine(A_tilde, 8)
    for j in range(1, 9):
        e, f = series_division(A_tilde, j)
        assert np.allclose(E[j - 1], e) and np.allclose(F[j - 1], f)


def test_dynamic_matrix_is_the_step_response():
    pred = prediction(CARIMA(A2, B2), 1, 20, 5)
    for j in range(2):
        for l in range(2):
            step = lfilter(np.r_[0.0, B2[j][l]], A2[j], np.ones(25))
            assert np.allclose(pred.G[j::2, l], step[1:21])


def test_predictions_match_simulation():
    """ŷ = G ΔU + free response equals the model's simulated output for a given input history."""
    model = CARIMA(A2, B2)
    pred = prediction(model, 1, 10, 3)
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.standard_normal((50, 2)) * 0.1, axis=0)
    u[33:] = u[32]  # after the plan's Nu = 3 moves (k = 30, 31, 32) the input holds
    y = np.column_stack([sum(lfilter(np.r_[0.0, B2[j][l]], A2[j], u[:, l]) for l in range(2)) for j in range(2)])
    k = 30
    du = np.diff(np.vstack([np.zeros(2), u]), axis=0)
    y_past = y[k::-1][: pred.y_depth].T
    du_past = du[k - 1 :: -1][: pred.u_depth].T
    dU = du[k : k + 3].ravel()
    predicted = pred.G @ dU + pred.free_response(y_past, du_past)
    assert np.allclose(predicted, y[k + 1 : k + 11].ravel())


def test_reference_smoothing():
    w = smoothed_reference([0.0], [1.0], 0.5, 1, 3)
    assert np.allclose(w, [0.5, 0.75, 0.875])


def qp_data(seed=0):
    rng = np.random.default_rng(seed)
    pred = prediction(CARIMA(A2, B2), 1, 20, 5)
    H = 2.0 * (pred.G.T @ pred.G + 0.5 * np.eye(10))
    g = 2.0 * pred.G.T @ -np.tile(rng.uniform(-1, 1, 2), 20)
    return H, g


def test_unconstrained_law_equals_qp_when_no_bound_is_active():
    H, g = qp_data()
    analytic = -np.linalg.solve(H, g)
    loose = Bounds(-1e3, 1e3, -1e3, 1e3)
    fast = solve_moves(H, g, np.zeros(2), loose, 5)
    assert fast.path == "analytic"
    from greyfmu.control.gpc import _cumulative, _qp

    x, ok = _qp(H, g, _cumulative(2, 5), -1e3 * np.ones(10), 1e3 * np.ones(10), -1e3 * np.ones(10), 1e3 * np.ones(10), "daqp")
    assert ok and np.allclose(x, analytic, atol=1e-8) and np.allclose(fast.plan, x, atol=1e-8)


def test_qp_respects_bounds_and_matches_reference_solver():
    H, g = qp_data(1)
    bounds = Bounds(-0.3, 0.3, -0.05, 0.05)
    result = solve_moves(H, g, np.array([0.1, -0.1]), bounds, 5)
    assert result.path == "qp"
    reference = solve_moves(H, g, np.array([0.1, -0.1]), bounds, 5, solver="scipy")
    assert np.allclose(result.plan, reference.plan, atol=1e-4)
    u = np.array([0.1, -0.1]) + np.cumsum(result.plan.reshape(5, 2), axis=0)
    assert np.all(np.abs(result.plan) <= 0.05 + 1e-9) and np.all(np.abs(u) <= 0.3 + 1e-9)


def test_infeasible_qp_falls_back_to_previous_move(caplog):
    H, g = qp_data()
    bounds = Bounds(-0.1, 0.1, -0.01, 0.01)
    with caplog.at_level(logging.WARNING):
        result = solve_moves(H, g, np.array([0.5, 0.0]), bounds, 5, previous_plan=np.full(10, 0.005))
    assert result.path == "fallback" and "infeasible" in caplog.text
    assert np.all(np.isfinite(result.du)) and np.all(np.abs(result.du) <= 0.01 + 1e-12)
    assert result.du[0] == pytest.approx(-0.01)  # moves towards the feasible range as far as allowed


def test_closed_loop_tracks_and_never_violates_constraints():
    model = CARIMA(A2, B2)
    bounds = Bounds(-2.0, 2.0, -0.1, 0.1)
    controller = GPC(model, N2=20, Nu=5, move_weight=0.1, bounds=bounds)
    y_hist = np.zeros((200, 2))
    u_hist = np.zeros((200, 2))
    for k in range(1, 200):
        for j in range(2):
            y_hist[k, j] = -sum(A2[j][i] * y_hist[k - i, j] for i in range(1, len(A2[j])) if k - i >= 0) + sum(
                b * u_hist[k - 1 - s, l] for l in range(2) for s, b in enumerate(B2[j][l]) if k - 1 - s >= 0
            )
        y_hist[k, 0] += 0.3 if k > 120 else 0.0  # output disturbance
        u_hist[k] = controller.step([1.0, -0.5], y_hist[k])
    assert np.allclose(y_hist[-1], [1.0, -0.5], atol=1e-3)  # integral action of the CARIMA model
    assert np.all(np.abs(np.diff(u_hist, axis=0)) <= 0.1 + 1e-9) and np.all(np.abs(u_hist) <= 2.0 + 1e-9)
