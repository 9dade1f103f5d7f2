"""FOPDT plant and delay line: exact response for piecewise-constant input, whatever the step."""

import math

import numpy as np
import pytest
from scipy import signal

from greyfmu.plants import FOPDT, DelayLine

K, T, TAU, Y0 = 0.2, 20.0, 4.0, 0.3


def simulate(plant, h, stop, u_of_t):
    """Drive ``plant`` with communication points t_k = k·h (computed, not accumulated)."""
    n = round(stop / h)
    times = np.arange(n + 1) * h
    outputs = [plant.y]
    for k in range(n):
        outputs.append(plant.advance(times[k], h, u_of_t(times[k])))
    return times, np.array(outputs)


def exact_response(times, switch_times, values, delay=TAU):
    """Superposition of delayed first-order step responses; before the first switch the input is y0/K."""
    y = np.full_like(times, Y0)
    previous = Y0 / K
    for switch, value in zip(switch_times, values):
        elapsed = times - switch - delay
        y += np.where(elapsed > 0, K * (value - previous) * -np.expm1(-np.maximum(elapsed, 0) / T), 0.0)
        previous = value
    return y


@pytest.mark.parametrize("h", [0.1, 0.3, 1.0, 0.7, 5.0])
def test_step_response_is_exact_at_every_communication_point(h):
    u1 = 4.0
    times, y = simulate(FOPDT(K, T, TAU, Y0), h, 100.0, lambda t: u1)
    expected = np.where(times > TAU, Y0 + K * (u1 - Y0 / K) * (1 - np.exp(-(times - TAU) / T)), Y0)
    assert np.max(np.abs(y - expected)) < 1e-12


def test_random_piecewise_constant_input_matches_the_exact_solution_for_every_step():
    rng = np.random.default_rng(7)
    period = 2.1  # the input switches every 2.1 s; 0.1, 0.3 and 0.7 all hit these instants
    levels = rng.uniform(-5, 5, size=60)

    def u_of_t(t):
        return levels[min(int(math.floor(t / period + 1e-9)), len(levels) - 1)]

    results = {}
    for h in (0.1, 0.3, 0.7, 2.1):
        times, y = simulate(FOPDT(K, T, TAU, Y0), h, 120.0 - 120.0 % 2.1, u_of_t)
        step = round(period / h)
        results[h] = (times[::step], y[::step])
    reference_times = results[2.1][0]
    reference = exact_response(reference_times, np.arange(len(levels)) * period, levels)
    for h, (times, y) in results.items():
        np.testing.assert_allclose(times, reference_times, rtol=0, atol=1e-9)
        assert np.max(np.abs(y - reference)) < 1e-12, h
        assert np.max(np.abs(y - results[0.1][1])) < 1e-12, h


def test_agrees_with_scipy_zoh_simulation_on_a_fine_grid():
    rng = np.random.default_rng(3)
    dt = 0.1
    u = np.repeat(rng.uniform(0, 10, size=50), 20)  # switches every 2 s
    times = np.arange(len(u) + 1) * dt
    plant = FOPDT(K, T, TAU, Y0)
    y = [plant.y] + [plant.advance(t, dt, value) for t, value in zip(times[:-1], u)]
    lag = round(TAU / dt)
    delayed = np.concatenate([np.full(lag, Y0 / K), u])[: len(u)]
    A, B, C, D = (np.array([[value]]) for value in (-1.0 / T, K / T, 1.0, 0.0))
    system = signal.cont2discrete((A, B, C, D), dt, method="zoh")
    _, reference, _ = signal.dlsim(system, delayed - Y0 / K)  # output n is at time n·dt
    np.testing.assert_allclose(y[:-1], Y0 + reference[:, 0], rtol=0, atol=1e-12)


def test_step_longer_than_the_dead_time_and_zero_dead_time():
    for tau in (4.0, 0.0):
        plant = FOPDT(K, T, tau, 0.0)
        y = plant.advance(0.0, 10.0, 1.0)
        assert y == pytest.approx(K * (1 - math.exp(-(10.0 - tau) / T)), abs=1e-15)


def test_load_disturbance_enters_with_the_input():
    with_load, combined = FOPDT(K, T, TAU, Y0), FOPDT(K, T, TAU, Y0)
    for k in range(100):
        u, d = 1.0 + 0.01 * k, -0.5 if k >= 30 else 0.0
        assert with_load.advance(k * 0.3, 0.3, u, d) == combined.advance(k * 0.3, 0.3, u + d)


def test_starts_in_equilibrium_and_reset_restores_it():
    plant = FOPDT(K, T, TAU, Y0)
    assert plant.advance(0.0, 50.0, Y0 / K) == pytest.approx(Y0, abs=1e-15)
    plant.advance(50.0, 10.0, 100.0)
    plant.reset()
    assert plant.y == Y0
    assert plant.advance(0.0, 3.0, 7.0) == Y0  # still inside the dead time


@pytest.mark.parametrize(
    "args, word",
    [((0.0, T, TAU), "K"), ((K, 0.0, TAU), "T"), ((K, -1.0, TAU), "T"), ((K, T, -0.1), "tau"), ((K, math.nan, TAU), "T")],
)
def test_invalid_parameters_are_refused(args, word):
    with pytest.raises(ValueError, match=rf"\b{word}\b"):
        FOPDT(*args)


def test_delay_line_segments_and_pruning():
    line = DelayLine(1.0)
    line.push(0.0, 2.0)
    line.push(0.5, 3.0)
    line.push(0.5, 4.0)  # a second value at the same instant replaces the first
    assert list(line.segments(0.0, 2.0, 1.0)) == [(1.0, 1.0), (0.5, 2.0), (0.5, 4.0)]
    assert list(line.segments(1.2, 0.1, 1.0)) == [(pytest.approx(0.1), 2.0)]
    line.prune(1.6, 1.0)
    assert len(line) == 1
    assert list(line.segments(1.6, 1.0, 1.0)) == [(pytest.approx(1.0), 4.0)]
    line.push(2.0, 4.0)  # no switch: nothing recorded
    assert len(line) == 1
    with pytest.raises(ValueError, match="backwards"):
        line.push(0.2, 5.0)
    with pytest.raises(ValueError, match="finite"):
        line.push(3.0, math.nan)


def test_history_stays_bounded_by_the_dead_time():
    plant = FOPDT(K, T, TAU, Y0)
    rng = np.random.default_rng(0)
    for k in range(2000):
        plant.advance(k * 0.1, 0.1, rng.normal())
    assert len(plant._inputs) <= round(TAU / 0.1) + 2
