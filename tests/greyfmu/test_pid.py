"""PID and the integral modes (2.10)-(2.12) of the thesis, §2.3.2."""

import math
from fractions import Fraction

import numpy as np
import pytest

from greyfmu.control import PID, DerivativeOn, IntegralMode, PIForm, integral_step

# §2.3.2 worked example: at k the three I-mode controllers output 60 with Kc = 4.5, Ti = 15;
# at k+1, e = 1, Kc = 5, Ti = 10, Ts = 1.
EXAMPLE = dict(I_prev=60.0, e=1.0, Kc=5.0, Ti=10.0, Kc_prev=4.5, Ti_prev=15.0, Ts=1.0)


def test_worked_example_method1_matches_thesis():
    assert integral_step(IntegralMode.METHOD1, **EXAMPLE) == 60.5


def test_worked_example_methods_2_and_3_follow_the_equations_not_the_printed_numbers():
    """The thesis prints U2 = 90.5 and U3 = 67.15; its own (2.11)/(2.12) give 100.5 and 67.1667.

    (2.11) back-scales with the previous gains: I1(k) = 60/(4.5/15) = 200, so
    U2 = (5/10)·(200 + 1) = 100.5.  The printed 90.5 back-scales with Kc(k+1) = 5 and
    Ti(k) = 15 instead: 60·15/5 = 180, (5/10)·(180 + 1) = 90.5.
    (2.12) gives 5·(60/4.5 + 1/10) = 67.1667; the printed 67.15 rounds 60/4.5 to 13.33.
    """
    # (2.11) and (2.12) in exact rational arithmetic: 201/2 and 403/6.
    I_prev, e, Kc, Ti, Kc_prev, Ti_prev = (Fraction(v) for v in ("60", "1", "5", "10", "4.5", "15"))
    method2 = (Kc / Ti) * (I_prev / (Kc_prev / Ti_prev) + e)
    method3 = Kc * (I_prev / Kc_prev + e / Ti)
    assert (method2, method3) == (Fraction(201, 2), Fraction(403, 6))
    assert integral_step(IntegralMode.METHOD2, **EXAMPLE) == pytest.approx(float(method2), rel=1e-15)
    assert integral_step(IntegralMode.METHOD3, **EXAMPLE) == pytest.approx(float(method3), rel=1e-15)
    # The printed numbers are not what the equations give: 10 and 0.0167 away.
    assert integral_step(IntegralMode.METHOD2, **EXAMPLE) - 90.5 == pytest.approx(10.0, abs=1e-12)
    assert integral_step(IntegralMode.METHOD3, **EXAMPLE) - 67.15 == pytest.approx(1.0 / 60.0, abs=1e-12)


@pytest.mark.parametrize("Ts", ["0.5", "2", "0.1"])
def test_worked_example_with_a_sample_time_other_than_1(Ts):
    """The worked example has Ts = 1, where a law that forgets the sample time gives the same numbers.  With Ts the
    rectangle of the new error sample is Ts·e in every mode: (2.10) 60 + 5·Ts/10, (2.11) (5/10)·(200 + Ts),
    (2.12) 5·(40/3 + Ts/10), in exact fractions (Ts = 0.5: 60.25, 100.25, 66.9167)."""
    T = Fraction(Ts)
    I_prev, e, Kc, Ti, Kc_prev, Ti_prev = (Fraction(v) for v in ("60", "1", "5", "10", "4.5", "15"))
    expected = {IntegralMode.METHOD1: I_prev + Kc * T / Ti * e,
                IntegralMode.METHOD2: (Kc / Ti) * (I_prev / (Kc_prev / Ti_prev) + T * e),
                IntegralMode.METHOD3: Kc * (I_prev / Kc_prev + T * e / Ti)}
    for mode, value in expected.items():
        assert integral_step(mode, **{**EXAMPLE, "Ts": float(T)}) == pytest.approx(float(value), rel=1e-14)


def test_integral_step_accepts_plain_integers_and_rejects_unknown_modes():
    assert integral_step(3, **EXAMPLE) == integral_step(IntegralMode.METHOD3, **EXAMPLE)
    with pytest.raises(ValueError):
        integral_step(4, **EXAMPLE)


@pytest.mark.parametrize("Td", [0.0, 1.5363])
def test_constant_gains_make_the_three_modes_identical(Td):
    rng = np.random.default_rng(1)
    setpoints = rng.normal(size=300)
    measurements = rng.normal(size=300)
    outputs = {}
    for mode in IntegralMode:
        pid = PID(8.0345, 7.1713, Td, 0.1, integral_mode=mode, u0=0.3)
        outputs[mode] = np.array([pid.step(r, y) for r, y in zip(setpoints, measurements)])
    np.testing.assert_allclose(outputs[IntegralMode.METHOD2], outputs[IntegralMode.METHOD1], rtol=0, atol=1e-11)
    np.testing.assert_allclose(outputs[IntegralMode.METHOD3], outputs[IntegralMode.METHOD1], rtol=0, atol=1e-11)


def test_p_plus_i_output_and_bumpless_start():
    Kc, Ti, Ts, u0 = 2.0, 5.0, 0.5, 1.25
    pid = PID(Kc, Ti, 0.0, Ts, u0=u0)
    assert pid.step(3.0, 3.0) == u0  # e = 0 holds the bias
    for k in range(1, 6):
        u = pid.step(1.0, 0.0)
        assert u == pytest.approx(u0 + Kc * (1.0 + k * Ts / Ti), abs=1e-12)
    pid.reset()
    assert (pid.u, pid.I, pid.e) == (u0, u0, 0.0)


@pytest.mark.parametrize("mode", list(IntegralMode))
def test_parallel_form_integrates_without_kc(mode):
    """§4.2's printed u = Kc·e + (1/Ti)∫e: with a constant error the integral grows by Ts·e/Ti per sample, not
    Kc·Ts·e/Ti (the ISA form of the previous test)."""
    Kc, Ti, Ts, u0 = 2.0, 5.0, 0.5, 1.25
    pid = PID(Kc, Ti, 0.0, Ts, u0=u0, form=PIForm.PARALLEL, integral_mode=mode)
    for k in range(1, 6):
        assert pid.step(1.0, 0.0) == pytest.approx(u0 + Kc * 1.0 + k * Ts / Ti, abs=1e-12)


def test_set_gains_applies_the_integral_law_with_the_previous_gains_on_the_next_sample():
    for mode in IntegralMode:
        pid = PID(4.5, 15.0, 0.0, 1.0, integral_mode=mode, u0=60.0)
        pid.step(0.0, 0.0)  # e = 0: the integral output stays 60
        pid.set_gains(5.0, 10.0, 0.0)
        u = pid.step(1.0, 0.0)
        expected_I = integral_step(mode, **EXAMPLE)
        assert pid.I == pytest.approx(expected_I, abs=1e-12)
        assert u == pytest.approx(5.0 * 1.0 + expected_I, abs=1e-12)


def test_anti_windup_leaves_saturation_within_a_few_samples_of_the_error_changing_sign():
    Kc, Ti, Ts = 2.0, 5.0, 0.1
    pid = PID(Kc, Ti, 0.0, Ts, u_min=0.0, u_max=1.0)
    saturated = 500
    for _ in range(saturated):
        assert pid.step(1.0, 0.0) == 1.0
    assert pid.I <= 1.0  # the integral stopped at the limit
    assert next(k for k in range(1, 1000) if pid.step(0.0, 0.2) < 1.0) <= 2

    # the same controller without anti-windup (limits applied outside) stays saturated far longer
    windup = PID(Kc, Ti, 0.0, Ts)
    for _ in range(saturated):
        windup.step(1.0, 0.0)
    assert next(k for k in range(1, 10000) if min(windup.step(0.0, 0.2), 1.0) < 1.0) > 100


@pytest.mark.parametrize("mode", list(IntegralMode))
def test_anti_windup_holds_for_every_integral_mode_and_the_low_limit(mode):
    pid = PID(3.0, 2.0, 0.0, 0.1, u_min=-1.0, u_max=1.0, integral_mode=mode)
    for _ in range(400):
        pid.step(-1.0, 0.0)
    assert pid.u == -1.0
    assert abs(pid.I) <= 1.0
    assert pid.step(0.0, -0.5) > -1.0


def test_rate_limit_is_respected_and_the_output_then_settles():
    du_max, Ts = 0.5, 0.2
    pid = PID(10.0, 1.0, 0.5, Ts, du_max=du_max)
    outputs = [pid.u] + [pid.step(1.0, 0.0) for _ in range(200)]
    steps = np.abs(np.diff(outputs))
    assert steps.max() <= du_max * Ts + 1e-12
    assert steps[0] == pytest.approx(du_max * Ts, abs=1e-12)


def test_output_limits_win_over_the_rate_limit():
    pid = PID(1.0, 10.0, 0.0, 1.0, u_min=0.0, u_max=0.1, du_max=100.0)
    assert pid.step(5.0, 0.0) == 0.1


def test_derivative_filter_step_response():
    """A step Δy gives D(k) = −Kc·Td/(Tf+Ts)·Δy·a^k, a = Tf/(Tf+Ts) (backward Euler), with area −Kc·Td·Δy."""
    Kc, Ti, Td, N, Ts, dy = 2.0, 1e6, 1.5, 10.0, 0.1, 0.4
    pid = PID(Kc, Ti, Td, Ts, N=N)
    pid.step(0.0, 0.0)
    Tf = Td / N
    a = Tf / (Tf + Ts)
    derivative = []
    for _ in range(400):
        pid.step(0.0, dy)
        derivative.append(pid.D)
    expected = -Kc * Td / (Tf + Ts) * dy * a ** np.arange(400)
    np.testing.assert_allclose(derivative, expected, rtol=1e-12, atol=1e-15)
    assert sum(derivative) * Ts == pytest.approx(-Kc * Td * dy, rel=1e-9)


def test_derivative_acts_on_the_measurement_only():
    pid = PID(2.0, 1e6, 1.5, 0.1)
    pid.step(0.0, 0.0)
    pid.step(1.0, 0.0)  # set-point step: no derivative kick
    assert pid.D == 0.0


def test_derivative_on_the_error_kicks_on_a_set_point_step_as_the_thesis_law():
    """(2.6a) Td·de/dt: a set-point step Δr gives the same filtered pulse as a measurement step −Δr."""
    on_error = PID(2.0, 1e6, 1.5, 0.1, derivative_on=DerivativeOn.ERROR)
    on_measurement = PID(2.0, 1e6, 1.5, 0.1)
    on_error.step(0.0, 0.0)
    on_measurement.step(0.0, 0.0)
    on_error.step(1.0, 0.0)
    on_measurement.step(0.0, -1.0)
    assert on_error.D > 0.0
    assert on_error.D == pytest.approx(on_measurement.D, rel=1e-12)


def test_without_anti_windup_the_integral_keeps_integrating_at_the_limit():
    """anti_windup=False (the thesis's PI): the output is limited, the integral is not."""
    Kc, Ti, Ts = 2.0, 5.0, 0.1
    pid = PID(Kc, Ti, 0.0, Ts, u_min=0.0, u_max=1.0, anti_windup=False)
    for _ in range(500):
        assert pid.step(1.0, 0.0) == 1.0
    assert pid.I == pytest.approx(500 * Kc * Ts / Ti, rel=1e-12)
    assert next(k for k in range(1, 10000) if pid.step(0.0, 0.2) < 1.0) > 100


def test_zero_derivative_time_disables_the_derivative():
    pid = PID(2.0, 5.0, 0.0, 0.1)
    for y in np.linspace(0, 3, 20):
        pid.step(1.0, y)
        assert pid.D == 0.0


@pytest.mark.parametrize(
    "kwargs, word",
    [
        (dict(Kc=0.0), "Kc"),
        (dict(Ti=0.0), "Ti"),
        (dict(Ti=math.inf), "Ti"),
        (dict(Td=-1.0), "Td"),
        (dict(Ts=0.0), "Ts"),
        (dict(N=0.0), "N"),
        (dict(u_min=1.0, u_max=0.0), "u_min"),
        (dict(du_max=-1.0), "du_max"),
        (dict(u0=2.0, u_max=1.0), "u0"),
        (dict(integral_mode=0), "IntegralMode"),
    ],
)
def test_invalid_settings_are_refused_with_the_parameter_named(kwargs, word):
    settings = dict(Kc=1.0, Ti=1.0, Td=0.0, Ts=1.0) | kwargs
    with pytest.raises(ValueError, match=word):
        PID(**settings)
