"""Sources, blocks and the sample clock."""

import math

import numpy as np
import pytest

from greyfmu.signals import BandLimitedWhiteNoise, FirstOrderFilter, Gain, Pulse, Ramp, SampleClock, Step, Sum


def test_step_switches_at_its_time_even_with_float_drift():
    step = Step(1.0, 2.0, 5.0)
    assert step.value(0.999) == 2.0
    assert step.value(1.0) == 5.0
    assert step.value(sum([0.1] * 10)) == 5.0  # 0.9999999999999999
    assert step.value(1e6) == 5.0


def test_ramp_moves_toward_final_at_the_magnitude_of_slope_and_stops():
    rising = Ramp(start_time=2.0, slope=-0.5, initial=1.0, final=3.0)
    assert rising.value(0.0) == 1.0
    assert rising.value(2.0) == 1.0
    assert rising.value(4.0) == pytest.approx(2.0)
    assert rising.value(6.0) == 3.0
    assert rising.value(100.0) == 3.0
    falling = Ramp(start_time=0.0, slope=2.0, initial=1.0, final=-1.0)
    assert falling.value(0.5) == pytest.approx(0.0)
    assert falling.value(5.0) == -1.0


def test_ramp_without_final_is_unbounded():
    ramp = Ramp(start_time=1.0, slope=-2.0, initial=0.5)
    assert ramp.value(0.0) == 0.5
    assert ramp.value(11.0) == pytest.approx(-19.5)


def test_single_pulse_edges():
    pulse = Pulse(amplitude=2.0, start_time=1.0, width=0.5, offset=-1.0)
    assert [pulse.value(t) for t in (0.99, 1.0, 1.49, 1.5, 10.0)] == [-1.0, 1.0, 1.0, -1.0, -1.0]


def test_periodic_pulse_edges_with_float_drift():
    pulse = Pulse(amplitude=1.0, start_time=0.0, width=0.3, period=1.0)
    assert pulse.value(2.0) == 1.0
    assert pulse.value(3 * 0.1 * 10 - 1e-15) == 1.0  # a rising edge reached up to drift
    assert pulse.value(2.3) == 0.0
    assert pulse.value(2.29) == 1.0
    assert pulse.value(2.99) == 0.0
    always_on = Pulse(amplitude=1.0, start_time=0.0, width=1.0, period=1.0)
    assert all(always_on.value(t) == 1.0 for t in np.arange(0, 5, 0.05))


@pytest.mark.parametrize("kwargs", [dict(width=-1.0), dict(width=2.0, period=1.0), dict(width=1.0, period=-1.0)])
def test_pulse_refuses_inconsistent_timing(kwargs):
    with pytest.raises(ValueError):
        Pulse(amplitude=1.0, start_time=0.0, **kwargs)


def test_noise_variance_is_power_over_sample_time():
    power, Ts, n = 0.1, 0.1, 20000
    noise = BandLimitedWhiteNoise(power, Ts, seed=11)
    samples = np.array([noise.value(j * Ts) for j in range(n)])
    expected = power / Ts
    # the sample variance of n Gaussian samples has standard deviation expected·sqrt(2/(n−1)); allow 5 of them
    assert abs(samples.var(ddof=1) - expected) < 5 * expected * math.sqrt(2 / (n - 1))
    assert abs(samples.mean()) < 5 * math.sqrt(expected / n)


def test_noise_is_reproducible_by_seed():
    times = np.arange(0, 300, 0.1)
    first = [BandLimitedWhiteNoise(1.0, 0.1, seed=5).value(t) for t in times]
    again = [BandLimitedWhiteNoise(1.0, 0.1, seed=5).value(t) for t in times]
    other = [BandLimitedWhiteNoise(1.0, 0.1, seed=6).value(t) for t in times]
    assert first == again
    assert first != other
    assert first[0] == math.sqrt(1.0 / 0.1) * np.random.default_rng(5).standard_normal()


def test_noise_value_does_not_depend_on_how_the_caller_steps():
    Ts, t0 = 0.1, 2.0
    reference = BandLimitedWhiteNoise(0.5, Ts, seed=3, t0=t0)
    coarse = BandLimitedWhiteNoise(0.5, Ts, seed=3, t0=t0)
    jumpy = BandLimitedWhiteNoise(0.5, Ts, seed=3, t0=t0)
    fine_times = t0 + np.arange(3000) * 0.025
    fine = [reference.value(t) for t in fine_times]
    for k in range(0, 3000, 7):
        assert coarse.value(fine_times[k]) == fine[k]
    rng = np.random.default_rng(0)
    for k in rng.permutation(3000)[:500]:  # backwards and forwards across generator blocks
        assert jumpy.value(fine_times[k]) == fine[k]
    # each sample is held for one sample period: four fine points per sample
    assert fine[0] == fine[3] != fine[4]


def test_noise_refuses_bad_parameters():
    with pytest.raises(ValueError, match="power"):
        BandLimitedWhiteNoise(-1.0, 0.1)
    with pytest.raises(ValueError, match="Ts"):
        BandLimitedWhiteNoise(1.0, 0.0)


def test_first_order_filter_is_exact_for_any_step():
    T, K, y0, u = 2.0, 3.0, 1.0, 0.5
    for h in (0.01, 0.7, 5.0):
        lag = FirstOrderFilter(T, K, y0)
        n = round(10 / h)
        for _ in range(n):
            lag.advance(h, u)
        assert lag.y == pytest.approx(K * u + (y0 - K * u) * math.exp(-n * h / T), abs=1e-13)
    lag.reset()
    assert lag.y == y0
    with pytest.raises(ValueError, match="T"):
        FirstOrderFilter(0.0)


def test_sum_and_gain():
    assert Sum(1.0, -1.0, 0.5).output(3.0, 1.0, 4.0) == 4.0
    assert Gain(-2.5).output(2.0) == -5.0


def test_sample_clock_finds_the_instants_in_each_interval_despite_float_drift():
    clock = SampleClock(0.1, t0=1.0)
    h = 0.05
    seen = [k for j in range(200) for k in clock.samples_in(1.0 + j * h, h)]
    assert seen == list(range(100))  # every sample exactly once
    assert list(clock.samples_in(1.0 + 3 * 0.1, 0.1)) == [3]  # 1.3000000000000003
    assert list(clock.samples_in(0.0, 1.0)) == []  # nothing before t0
    assert list(clock.samples_in(0.0, 1.25)) == [0, 1, 2]
    assert clock.index_at(1.0 + 0.1 * 3) == 3
    assert clock.index_at(1.29999999) == 2
    assert clock.time(7) == pytest.approx(1.7)


def test_sample_clock_with_steps_longer_than_the_sample_time():
    clock = SampleClock(0.3)
    seen = [list(clock.samples_in(j * 1.0, 1.0)) for j in range(3)]
    assert seen == [[0, 1, 2, 3], [4, 5, 6], [7, 8, 9]]
