"""Gain schedules FGS1/FGS2/MFGS/threshold/ITAE, the scheduled PID and the plant (2.13); thesis §2.3 and §4 (4.6)."""

import logging
import math

import numpy as np
import pytest

from greyfmu.control import (
    ITAE,
    PID,
    GainSchedule,
    GainScheduledPID,
    Gains,
    IntegralMode,
    Interpolation,
    OperatingPoint,
    ScheduleError,
)
from greyfmu.plants import FOPDT, PiecewiseParameter, ScheduledFOPDT

const = PiecewiseParameter.constant
Y = np.linspace(0.8, 6.9, 62)  # intermediate values of the scheduling variable y, between 0.76 and 7

# Chapter 4, (4.4)-(4.6): the BTG turbine controller, Kc = 5.707 at Pt = 86 kgf/cm2 (58 MW), 3.581 at 140 (101 MW).
BTG = [OperatingPoint(86.0, 5.707, 16.383), OperatingPoint(140.0, 3.581, 16.383)]


def test_btg_turbine_gain_at_109_kgf_cm2_mfgs_4_555_and_fgs_4_802():
    """Chapter 4, (4.6) and the sentence after it: Kc(Pt = 109) = 4.555 (MFGS), 4.802 (FGS1 and FGS2)."""
    assert GainSchedule(BTG, Interpolation.MFGS)(109.0).Kc == pytest.approx(4.555, abs=5e-4)
    # FGS: 5.707 + (3.581 − 5.707)·23/54 = 4.80148; the thesis prints 4.802 (rounded up in its last digit).
    for law in (Interpolation.FGS1, Interpolation.FGS2):
        assert GainSchedule(BTG, law)(109.0).Kc == pytest.approx(4.80148, abs=1e-5)
        assert GainSchedule(BTG, law)(109.0).Kc == pytest.approx(4.802, abs=1e-3)
    # (4.3): the gain tuned at 76 MW is 4.585, between the two (MFGS 0.7 % lower, FGS 4.7 % higher).
    assert GainSchedule(BTG, Interpolation.MFGS)(109.0).Kc < 4.585 < GainSchedule(BTG, Interpolation.FGS1)(109.0).Kc


def test_interpolation_laws_follow_2_6_2_7_2_9():
    a, b = OperatingPoint(1.0, 4.0, 10.0, 1.0), OperatingPoint(3.0, 1.0, 20.0, 3.0)
    q1, q2 = 0.75, 0.25  # W = 1.5
    fgs1 = GainSchedule([a, b], Interpolation.FGS1)(1.5)
    Kc = q1 * 4.0 + q2 * 1.0
    assert fgs1 == pytest.approx(Gains(Kc, Kc / (q1 * 4.0 / 10.0 + q2 * 1.0 / 20.0), (q1 * 4.0 * 1.0 + q2 * 1.0 * 3.0) / Kc))
    assert GainSchedule([a, b], Interpolation.FGS2)(1.5) == pytest.approx(Gains(Kc, 12.5, 1.5))
    assert GainSchedule([a, b], Interpolation.MFGS)(1.5) == pytest.approx(Gains(1.0 / (q1 / 4.0 + q2 / 1.0), 12.5, 1.5))
    assert GainSchedule([a, b], Interpolation.THRESHOLD)(1.99) == Gains(4.0, 10.0, 1.0)
    assert GainSchedule([a, b], Interpolation.THRESHOLD)(2.01) == Gains(1.0, 20.0, 3.0)
    assert GainSchedule([a, b], Interpolation.THRESHOLD, thresholds=[1.2])(1.3) == Gains(1.0, 20.0, 3.0)


@pytest.mark.parametrize("law", list(Interpolation))
def test_any_number_of_points_exact_at_the_points_and_clamped_outside(law):
    points = [OperatingPoint(w, kc, ti, td) for w, kc, ti, td in [(0, 5, 10, 1), (1, 4, 8, 2), (2.5, 2, 6, 0), (4, 1, 12, 3)]]
    schedule = GainSchedule(points, law)
    for p in points:
        assert schedule(p.W) == pytest.approx(Gains(p.Kc, p.Ti, p.Td))
    assert schedule(-7.0) == schedule(0.0) and schedule(99.0) == schedule(4.0)
    assert schedule(3.0).Kc == pytest.approx({0: 2.0, 1: 2 - 1 / 3, 2: 2 - 1 / 3, 3: 1 / (2 / 3 / 2 + 1 / 3)}[law])
    assert GainSchedule(points[:1], law)(123.0) == Gains(5, 10, 1)


@pytest.mark.parametrize(
    "points, message",
    [
        ([], "empty"),
        ([OperatingPoint(1, 1, 1), OperatingPoint(1, 2, 1)], "W_2 = 1 does not exceed W_1 = 1"),
        ([OperatingPoint(2, 1, 1), OperatingPoint(1, 2, 1)], "W_2"),
        ([OperatingPoint(1, 1, 1), OperatingPoint(2, 2, 0)], "Ti_2"),
        ([OperatingPoint(1, 1, -3)], "Ti_1"),
        ([OperatingPoint(1, 0, 1)], "Kc_1"),
        ([OperatingPoint(1, 1, 1, -1)], "Td_1"),
        ([OperatingPoint(math.nan, 1, 1)], "W_1"),
        ([OperatingPoint(1, 1, 1), OperatingPoint(2, -1, 1)], "same sign"),
    ],
)
def test_bad_tables_are_refused_naming_the_entry(points, message):
    with pytest.raises(ScheduleError, match=message):
        GainSchedule(points)


def test_bad_thresholds_and_scheduling_values_are_refused():
    with pytest.raises(ScheduleError, match="W\\*_1"):
        GainSchedule(BTG, Interpolation.THRESHOLD, thresholds=[150.0])
    with pytest.raises(ValueError, match="finite"):
        GainSchedule(BTG)(math.nan)


def test_itae_constants_of_2_8_and_the_chapters_detuned_gain_a_0_35():
    """(2.8) with the printed A..F; the chapter's own formulas are (2.8) with A = 0.350 (Sim. 2.1, 2.4, 2.5)."""
    gains = ITAE()(0.2, 20.0, 4.0)
    assert gains.Kc == pytest.approx(1.357 / 0.2 * 0.2**-0.947)
    detuned = ITAE(A=0.35)
    assert detuned(0.2, 20.0, 4.0) == pytest.approx(Gains(1.6069 / 0.2, 7.1713, 1.5363), rel=2e-4)  # Simulation 2.1
    for T in (4.0, 12.0, 20.0):  # Simulation 2.4: 0.4709 T^0.947, 3.2717 T^0.262, 1.5135 T^0.005
        assert detuned(0.2, T, 4.0) == pytest.approx(Gains(0.4709 * T**0.947, 3.2717 * T**0.262, 1.5135 * T**0.005), rel=2e-4)
    for tau in (4.0, 11.0, 20.0):  # Simulation 2.5: 29.8616 tau^-0.947, 2.578 tau^0.738, 0.3867 tau^0.995
        assert detuned(0.2, 20.0, tau) == pytest.approx(
            Gains(29.8616 * tau**-0.947, 2.578 * tau**0.738, 0.3867 * tau**0.995), rel=2e-4
        )
    # The table ends of Simulations 2.4 and 2.5 are these ITAE gains at y = 0.76 and y = 7.
    assert detuned(0.2, 4.0, 4.0) == pytest.approx(Gains(1.75, 4.704, 1.524), rel=2e-4)
    assert detuned(0.2, 20.0, 20.0) == pytest.approx(Gains(1.75, 23.52, 7.62), rel=2e-4)
    # Simulation 2.2 prints Kc = 5.9723 tau^-0.947: (2.8b) with A = 0.350 but Kp = 1, not the process's 0.2.
    assert detuned(1.0, 20.0, 4.0).Kc == pytest.approx(5.9723 * 4.0**-0.947, rel=2e-4)
    # Simulation 2.3: Kc = 0.2961/Kp is A = 0.2961 * 0.2^0.947 = 0.0645.
    assert ITAE(A=0.2961 * 0.2**0.947)(1.3, 20.0, 4.0).Kc == pytest.approx(0.2961 / 1.3)
    with pytest.raises(ValueError, match="tau"):
        detuned(0.2, 20.0, 0.0)


# Simulation 2.3 (process gain varies, T = 20 s, tau = 4 s), Figure 2.3.
SIM23_POINTS = [OperatingPoint(0.76, 1.4805, 7.1713, 1.5363), OperatingPoint(7.0, 0.1185, 7.1713, 1.5363)]
SIM23_ITAE = ITAE(A=0.2961 * 0.2**0.947)
SIM23_KP = {
    1: PiecewiseParameter(0.2, 2.5, 0.76, 7.0, a=1.0, b=1.0, c=-0.72, n=0.5),
    2: PiecewiseParameter(0.2, 2.5, 0.76, 7.0, a=1.0, b=0.3686, c=-0.0801, n=1.0),
    3: PiecewiseParameter(0.2, 2.5, 0.76, 7.0, a=0.033, b=1.0, c=1.701, n=2.0),
}


def kc_ratio(points, law, itae, Kp, T, tau):
    """Scheduled Kc / ITAE Kc (and Ti, Td ratios) over the intermediate y."""
    schedule = GainSchedule(points, law)
    return np.array([np.divide(schedule(y), itae(Kp(y), T(y), tau(y))) for y in Y])


def test_sim_2_3_case_2_mfgs_kc_equals_itae_kc():
    """Figure 2.3(b): with Kp linear in y, Kc of MFGS "is exactly the same as Kc in ITAE".

    Exact up to the rounding of the printed numbers: Kc(7) = 0.1185 is 0.2961/2.5 = 0.11844, and
    0.3686·7 − 0.0801 = 2.5001; both leave 0.05 % between the two.
    """
    ratio = kc_ratio(SIM23_POINTS, Interpolation.MFGS, SIM23_ITAE, SIM23_KP[2], const(20.0), const(4.0))
    np.testing.assert_allclose(ratio[:, 0], 1.0, atol=6e-4)
    exact = [OperatingPoint(w, 0.2961 / (0.3686 * w - 0.0801), 7.1713) for w in (0.76, 7.0)]
    ratio = kc_ratio(exact, Interpolation.MFGS, SIM23_ITAE, SIM23_KP[2], const(20.0), const(4.0))
    np.testing.assert_allclose(ratio[:, 0], 1.0, rtol=1e-12)


def test_sim_2_3_figure_2_3_mfgs_closest_fgs_too_large():
    """Figure 2.3 (a)-(c): MFGS slightly above ITAE (CASE 1), below it (CASE 3); FGS1 = FGS2, far too large."""
    args = (SIM23_ITAE,)
    mfgs = {case: kc_ratio(SIM23_POINTS, Interpolation.MFGS, *args, kp, const(20.0), const(4.0))[:, 0] for case, kp in SIM23_KP.items()}
    fgs1 = {case: kc_ratio(SIM23_POINTS, Interpolation.FGS1, *args, kp, const(20.0), const(4.0))[:, 0] for case, kp in SIM23_KP.items()}
    fgs2 = {case: kc_ratio(SIM23_POINTS, Interpolation.FGS2, *args, kp, const(20.0), const(4.0))[:, 0] for case, kp in SIM23_KP.items()}
    assert np.all(mfgs[1] > 1.0) and np.all(mfgs[3] < 1.0)
    for case in SIM23_KP:
        np.testing.assert_array_equal(fgs1[case], fgs2[case])
        assert np.all(fgs1[case] > mfgs[case]) and np.all(fgs1[case] > 1.0)
        assert np.abs(mfgs[case] - 1).max() < np.abs(fgs1[case] - 1).max()
    # "further closer" from CASE 1 to CASE 3: the FGS excess shrinks.
    assert fgs1[1].max() > fgs1[2].max() > fgs1[3].max()


SIM24_POINTS = [OperatingPoint(0.76, 8.0346, 7.1713, 1.5363), OperatingPoint(7.0, 1.75, 4.704, 1.524)]
SIM24_T = {
    1: PiecewiseParameter(20.0, 4.0, 0.76, 7.0, a=7.8446, b=-1.0, c=7.26, n=0.5),
    2: PiecewiseParameter(20.0, 4.0, 0.76, 7.0, a=0.157, b=1.0, c=-12.0483, n=2.0),
    3: PiecewiseParameter(20.0, 4.0, 0.76, 7.0, a=1.0, b=-2.5641, c=21.9487, n=1.0),
}


def test_sim_2_4_figures_2_5_2_7_2_9_mfgs_kc_too_low_fgs_close():
    """T(y) falls as y grows: MFGS's Kc is too low in every case; FGS's is slightly low (CASE 1), slightly
    high (CASE 2), almost ITAE's (CASE 3); MFGS = FGS2 in Ti, Td, below ITAE; FGS1's Ti nearest ITAE in CASE 1."""
    itae = ITAE(A=0.35)
    r = {(case, law): kc_ratio(SIM24_POINTS, law, itae, const(0.2), T, const(4.0)) for case, T in SIM24_T.items() for law in Interpolation if law}
    for case in SIM24_T:
        assert np.all(r[case, Interpolation.MFGS][:, 0] < r[case, Interpolation.FGS1][:, 0])
        assert r[case, Interpolation.MFGS][:, 0].min() < 0.7
        np.testing.assert_array_equal(r[case, Interpolation.MFGS][:, 1:], r[case, Interpolation.FGS2][:, 1:])
        assert np.all(r[case, Interpolation.FGS2][:, 1] < 1.0)
    assert np.all(r[1, Interpolation.FGS1][:, 0] < 1.0)
    assert np.all(r[2, Interpolation.FGS1][:, 0] > 1.0)
    assert np.abs(r[3, Interpolation.FGS1][:, 0] - 1).max() < 0.02
    assert np.abs(r[1, Interpolation.FGS1][:, 1] - 1).max() < np.abs(r[1, Interpolation.FGS2][:, 1] - 1).max()
    assert np.all(r[2, Interpolation.FGS1][:, 1] > 1.0) and np.all(r[3, Interpolation.FGS1][:, 1] > 1.0)


SIM25_POINTS = [OperatingPoint(0.76, 8.0346, 7.1713, 1.5363), OperatingPoint(7.0, 1.75, 23.52, 7.62)]
SIM25_TAU = {
    1: PiecewiseParameter(4.0, 20.0, 0.76, 7.0, a=7.8446, b=1.0, c=-0.5, n=0.5),
    2: PiecewiseParameter(4.0, 20.0, 0.76, 7.0, a=0.157, b=1.0, c=4.2883, n=2.0),
    3: PiecewiseParameter(4.0, 20.0, 0.76, 7.0, a=1.0, b=2.5641, c=2.0513, n=1.0),
}


def test_sim_2_5_figures_2_10_2_12_2_14_fgs_kc_too_large_fgs1_ti_too_small():
    itae = ITAE(A=0.35)
    r = {(case, law): kc_ratio(SIM25_POINTS, law, itae, const(0.2), const(20.0), tau) for case, tau in SIM25_TAU.items() for law in Interpolation if law}
    assert np.all(r[1, Interpolation.MFGS][:, 0] > 1.0)  # "very close to, but somewhat higher than" ITAE
    for case in SIM25_TAU:
        assert np.all(r[case, Interpolation.FGS1][:, 0] > r[case, Interpolation.MFGS][:, 0])
        assert np.all(r[case, Interpolation.FGS1][:, 0] > 1.0)
        assert np.all(r[case, Interpolation.FGS1][:, 1] < r[case, Interpolation.FGS2][:, 1])  # FGS1: too small Ti
        assert np.abs(r[case, Interpolation.FGS2][:, 1] - 1).max() < np.abs(r[case, Interpolation.FGS1][:, 1] - 1).max()


# --- GainScheduledPID -----------------------------------------------------------------------------------------


def test_scheduled_pid_uses_the_pid_integral_modes_worked_example():
    """§2.3.2 example through the scheduled PID: integral 60 with Kc 4.5, Ti 15; then Kc 5, Ti 10, e = 1, Ts = 1.

    The integral follows `integral_step` (60.5, 100.5, 67.1667; the thesis prints 90.5 and 67.15 for the
    last two, see tests/greyfmu/test_pid.py); u adds the proportional part Kc·e = 5.
    """
    for mode, expected in ((1, 60.5), (2, 100.5), (3, 403.0 / 6.0)):  # (2.10)-(2.12) by hand: 60 + 0.5, 0.5·201, 5·(40/3 + 1/10)
        gains = iter([Gains(4.5, 15.0, 0.0), Gains(5.0, 10.0, 0.0), Gains(5.0, 10.0, 0.0)])
        pid = GainScheduledPID(lambda _: next(gains), 1.0, integral_mode=mode, u0=60.0)
        assert pid.step(0.0, 0.0, W=None) == 60.0
        assert pid.step(1.0, 0.0, W=None) == pytest.approx(5.0 + expected, abs=1e-12)
        assert pid.pid.I == pytest.approx(expected, abs=1e-12)
        # Gains unchanged from k+1 to k+2: every mode adds Kc·Ts/Ti·e = 0.5 (the rescaling cancels).
        assert pid.step(1.0, 0.0, W=None) == pytest.approx(5.0 + expected + 0.5, abs=1e-12)


@pytest.mark.parametrize("mode, expected", [(1, 60.0 + 0.25), (2, 0.5 * 200.5), (3, 5.0 * (40.0 / 3.0 + 0.05))])
def test_scheduled_pid_worked_example_at_a_sample_time_of_half_a_second(mode, expected):
    """The same example at Ts = 0.5 s: each mode adds the rectangle Ts·e = 0.5 of the new error sample, (2.10)
    60 + 5·0.5/10, (2.11) (5/10)·(200 + 0.5), (2.12) 5·(40/3 + 0.5/10); a law that drops Ts (the worked example's
    Ts = 1 hides it) gives 60.5, 100.5, 67.1667."""
    gains = iter([Gains(4.5, 15.0, 0.0), Gains(5.0, 10.0, 0.0)])
    pid = GainScheduledPID(lambda _: next(gains), 0.5, integral_mode=mode, u0=60.0)
    assert pid.step(0.0, 0.0, W=None) == 60.0
    assert pid.step(1.0, 0.0, W=None) == pytest.approx(5.0 + expected, abs=1e-12)


def test_scheduled_pid_equals_a_pid_with_the_same_gain_sequence():
    rng = np.random.default_rng(4)
    schedule = GainSchedule(SIM23_POINTS, Interpolation.MFGS)
    for mode in IntegralMode:
        scheduled = GainScheduledPID(schedule, 0.1, integral_mode=mode, u0=1.0)
        plain = None
        for r, y, w in rng.uniform(0, 7, size=(200, 3)):
            gains = schedule(w)
            if plain is None:
                plain = PID(*gains, 0.1, integral_mode=mode, u0=1.0)
            plain.set_gains(*gains)
            assert scheduled.step(r, y, W=w) == plain.step(r, y)
            assert scheduled.gains == gains


def test_scheduled_pid_holds_the_gains_on_a_nan_scheduling_variable(caplog):
    pid = GainScheduledPID(GainSchedule(BTG), 1.0)
    pid.step(1.0, 0.0, W=100.0)
    held = pid.gains
    with caplog.at_level(logging.WARNING):
        u = pid.step(1.0, 0.0, W=math.nan)
    assert math.isfinite(u) and pid.gains == held and pid.held_samples == 1
    assert "holding" in caplog.text
    fresh = GainScheduledPID(GainSchedule(BTG), 1.0)
    with pytest.raises(ValueError):
        fresh.step(1.0, 0.0, W=math.nan)
    assert fresh.u == 0.0 and fresh.gains is None


# --- ScheduledFOPDT (2.13) ------------------------------------------------------------------------------------


def test_piecewise_parameter_situations():
    kp = SIM23_KP[1]
    assert (kp(0.0), kp(0.76), kp(3.0), kp(7.0), kp(9.0)) == (0.2, 0.2, pytest.approx(math.sqrt(2.28)), 2.5, 2.5)
    assert const(20.0)(-5.0) == const(20.0)(3.0) == const(20.0)(50.0) == 20.0
    # Situations 2 and 3: above and below the linear interpolation of the ends; 5 and 6: increasing, decreasing.
    line = lambda p, y: p(0.76) + (p(7.0 - 1e-9) - p(0.76)) * (y - 0.76) / (7.0 - 0.76)  # noqa: E731
    assert all(SIM25_TAU[1](y) > line(SIM25_TAU[1], y) for y in Y)
    assert all(SIM25_TAU[2](y) < line(SIM25_TAU[2], y) for y in Y)
    assert all(SIM24_T[2](y) < line(SIM24_T[2], y) for y in Y)
    assert np.all(np.diff([SIM24_T[3](y) for y in Y]) < 0) and np.all(np.diff([SIM25_TAU[3](y) for y in Y]) > 0)


@pytest.mark.parametrize(
    "function, name, message",
    [
        (PiecewiseParameter(0.2, 2.5, 0.76, 7.0, a=1.0, b=1.0, c=-1.0, n=0.5), "Kp", "undefined at y = 0.76"),
        (PiecewiseParameter(20.0, 4.0, 0.76, 7.0, a=1.0, b=-3.0, c=20.0, n=1.0), "T", r"T\(7.0\) = -1.0 must be > 0"),
        (PiecewiseParameter(20.0, -1.0, 0.76, 7.0), "T", "T_hi = -1.0"),
        (PiecewiseParameter(20.0, 4.0, 7.0, 0.76), "T", "T_y_lo"),
        (PiecewiseParameter(math.nan, 4.0, 0.76, 7.0), "T", "T_lo must be finite"),
    ],
)
def test_plant_refuses_bad_parameter_functions(function, name, message):
    functions = {"Kp": const(0.2), "T": const(20.0), "tau": const(4.0), name: function}
    with pytest.raises(ValueError, match=message):
        ScheduledFOPDT(functions["Kp"], functions["T"], functions["tau"])


@pytest.mark.parametrize("h", [0.1, 0.3, 0.7])
def test_plant_with_constant_parameters_is_the_exact_fopdt(h):
    plant = ScheduledFOPDT(const(0.2), const(20.0), const(4.0), y0=0.5)
    reference = FOPDT(0.2, 20.0, 4.0, 0.5)
    rng = np.random.default_rng(2)
    for k in range(int(60 / h)):
        u = rng.uniform(0, 5)
        d = 0.3 if k * h > 20 else 0.0
        assert plant.advance(k * h, h, u, d) == pytest.approx(reference.advance(k * h, h, u, d), abs=1e-12)


def test_plant_gain_applies_at_the_delayed_output():
    """Simulation 2.1's process in open loop: the steady state is Kp(y)·u solved for y, after the 4 s dead time."""
    plant = ScheduledFOPDT(SIM23_KP[1], const(20.0), const(4.0), y0=1.0)
    for k in range(40):
        assert plant.advance(k * 0.1, 0.1, 2.0) == 1.0  # nothing before the dead time
    for k in range(40, 20000):
        plant.advance(k * 0.1, 0.1, 2.0)
    # y = 2·sqrt(y − 0.72): y² − 4y + 2.88 = 0, stable root y = 2 + sqrt(1.12) (the other, 0.94, is unstable)
    assert plant.y == pytest.approx(2.0 + math.sqrt(1.12), abs=1e-9)
    assert plant.Kp == pytest.approx(math.sqrt(plant.y - 0.72), abs=1e-9)


def test_plant_dead_time_follows_the_output_and_the_step_barely_matters():
    """tau(y(t − D)) of Simulation 2.5 CASE 3 in open loop; master steps 0.1 s and 0.25 s agree to 1e-4."""
    outputs = {}
    for h in (0.1, 0.25):
        plant = ScheduledFOPDT(const(0.2), const(20.0), SIM25_TAU[3], y0=1.0)
        ys = {}
        for k in range(int(round(200 / h))):
            ys[round((k + 1) * h, 6)] = plant.advance(k * h, h, 5.0 if k * h < 10 else 20.0)
        outputs[h] = np.array([ys[t] for t in np.arange(0.5, 200.01, 0.5).round(6)])
        assert plant.tau == pytest.approx(SIM25_TAU[3](plant.y), abs=1e-3)
    assert outputs[0.1][-1] == pytest.approx(4.0, abs=1e-3)  # 0.2·20
    np.testing.assert_allclose(outputs[0.25], outputs[0.1], atol=1e-4)
    # The step reaches the output after the dead time at y = 1: 2.5641 + 2.0513 = 4.6154 s.
    plant = ScheduledFOPDT(const(0.2), const(20.0), SIM25_TAU[3], y0=1.0)
    ys = [plant.advance(k * 0.01, 0.01, 5.0 if k < 1000 else 20.0) for k in range(2000)]
    first_move = next(k for k, y in enumerate(ys) if abs(y - 1.0) > 1e-9) * 0.01
    assert first_move == pytest.approx(10.0 + 4.6154, abs=0.02)
