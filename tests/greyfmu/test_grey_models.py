"""Grey models against the thesis (000_*, Chapter 3) and the GM(3/t,1) paper (002_*): numbers and edge cases."""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from itertools import accumulate

import numpy as np
import pytest

from greyfmu.control import PID, GrayPredictivePI
from greyfmu.grey import GM11, GM3t1, GreyModelError, GreyPredictor, PredictorMode, StepIdentifier, Threshold, ago, background, iago
from greyfmu.plants import SecondOrder

# Example 3.1 / Simulation 3.2 data (Sim. 3.2 prints e0(9) = 749.685, Example 3.1 749.658; no window below uses it).
E0 = [590.227, 615.369, 591.63, 651.777, 677.115, 699.87, 704.298, 695.565, 749.658, 816.966, 788.533, 799.5]
TABLE1 = np.array([0.4123, 0.4124, 0.4126, 0.4127, 0.413, 0.4133, 0.4137, 0.4141])
PAPER_THETA = GM3t1(-4700.6, 876.422, 360.715)


def test_example_3_1_ago():
    """Example 3.1: e1 = AGO(e0).  Printed: (590.277, 1205.6, 1797.3, 2449.1, 3126.2, 3826.1, 4530.4, 5225.9,
    5975.6, 6972.6, 7761.1, 8560.6).  (3.2a) gives e1(1) = e0(1) = 590.227 (590.277 is a typo), and
    e1(10) = 6792.475: the printed 6972.6 swaps two digits, and the +180 carries into e1(11), e1(12).  The other
    printed values are the sums rounded to 0.1 with up to 0.114 of slack (3826.1 for 3825.988)."""
    e1 = ago(E0)
    printed = [None, 1205.6, 1797.3, 2449.1, 3126.2, 3826.1, 4530.4, 5225.9, 5975.6]
    assert e1[0] == 590.227
    np.testing.assert_allclose(e1[1:9], printed[1:], atol=0.115)
    np.testing.assert_allclose(e1[9:], [6792.475, 7581.008, 8380.508], atol=1e-9)
    np.testing.assert_allclose(np.array([6972.6, 7761.1, 8560.6]) - e1[9:], 180.1, atol=0.1)
    exact = list(accumulate(Fraction(str(x)) for x in E0))  # (3.2a) in exact decimal arithmetic
    np.testing.assert_allclose(e1, [float(v) for v in exact], rtol=1e-14)
    np.testing.assert_allclose(iago(e1), E0, rtol=1e-14)  # (3.2b) undoes (3.2a)
    np.testing.assert_allclose(iago([float(v) for v in exact]), E0, rtol=1e-14)


def reference_gm11(window: list[float]) -> tuple[float, float, Callable[[float], float]]:
    """GM(1,1) written out independently of greyfmu: (a, b) by least squares on (3.5a) with Z of (3.5b)
    (numpy.linalg.lstsq, not the closed form (3.6)), and ê0(k) = ê1(k) − ê1(k − 1) from (3.7a)."""
    x = np.asarray(window, dtype=float)
    e1 = np.cumsum(x)
    z = 0.5 * (e1[1:] + e1[:-1])
    (a, b), *_ = np.linalg.lstsq(np.column_stack((-z, np.ones_like(z))), x[1:], rcond=None)
    r = (1.0 - 0.5 * a) / (1.0 + 0.5 * a)

    def e1_hat(k: float) -> float:
        return (x[0] - b / a) * r ** (k - 1.0) + b / a

    return float(a), float(b), lambda k: e1_hat(k) - e1_hat(k - 1.0)


def test_simulation_3_2_windows():
    """Simulation 3.2, CASE 1 and CASE 2 (n = 7): AGO, Z and a(i), b(i) by (3.6), as printed."""
    w1 = GM11.fit(E0[:7])
    assert round(w1.a, 4) == -0.0345 and round(w1.b, 4) == 570.5639
    w2 = GM11.fit(E0[1:8])
    assert round(w2.a, 4) == -0.0291 and round(w2.b, 4) == 595.2835
    # CASE 1: printed Z(2..7) = 897.912, 1501.411, 2123.115, 2787.561, 3476.053, 4178.137 (3 decimals)
    np.testing.assert_allclose(background(ago(E0[:7])), [897.9115, 1501.411, 2123.1145, 2787.5605, 3476.053, 4178.137])
    # CASE 2: printed e1 = (615.369, 1206.999, 1858.776, 2535.891, 3235.761, 3940.059, 4635.624)
    np.testing.assert_allclose(ago(E0[1:8]), [615.369, 1206.999, 1858.776, 2535.891, 3235.761, 3940.059, 4635.624])


def test_simulation_3_2_case_1_predictions_within_0_1_percent():
    """Simulation 3.2 CASE 1: ê0(k) by (3.7a)/(3.7b).  Printed: (590.227, 615.369, 622.3441, 644.1897, 666.8020,
    690.2081, 714.4358, 739.5140, 765.471, 792.3421, 820.1549, 848.944); the first two printed values are the data
    themselves ((3.7b) gives ê0(2) = 601.324), so the comparison starts at k = 3."""
    printed = [622.3441, 644.1897, 666.8020, 690.2081, 714.4358, 739.5140, 765.471, 792.3421, 820.1549, 848.944]
    model = GM11.fit(E0[:7])
    ours = model.predict(np.arange(3, 13))
    np.testing.assert_allclose(ours, printed, rtol=1e-3)
    assert model.predict(1) == 590.227
    np.testing.assert_allclose(np.diff(model.predict_ago(np.arange(1, 13))), model.predict(np.arange(2, 13)), rtol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_theorem_3_4_form_equals_3_6(seed):
    """Theorem 3.4 (3.20)/(3.22) and the closed form (3.6) are the same least-squares solution (Theorem 3.2)."""
    x = 50.0 + np.random.default_rng(seed).uniform(0, 10, 4 + seed)
    model = GM11.fit(x)
    a, b = GM11.theorem34(x)
    assert a == pytest.approx(model.a, rel=1e-9, abs=1e-13) and b == pytest.approx(model.b, rel=1e-9)
    z = background(ago(x))
    lstsq = np.linalg.lstsq(np.column_stack((-z, np.ones_like(z))), x[1:], rcond=None)[0]
    np.testing.assert_allclose([model.a, model.b], lstsq, rtol=1e-7, atol=1e-12)


def test_corollary_3_1_sign_of_a():
    """Corollary 3.1 (n = 4): sign(a) = sign(e0(2) − e0(4)) via (3.23); rising data give a < 0, r > 1."""
    assert GM11.fit([1.0, 1.2, 1.5, 1.9]).a < 0 and GM11.fit([1.0, 1.2, 1.5, 1.9]).r > 1
    assert GM11.fit([2.0, 1.8, 1.5, 1.1]).a > 0
    assert GM11.fit([2.0, 1.5, 3.0, 1.5]).a == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("E", [1e-3, 1.0, 50.0, 1e6])
def test_proposition_3_4_constant_sequence(E):
    """Proposition 3.4: for e0(k) = E∞, a → 0 and b → E∞; Proposition 3.5: the prediction is E∞ at any horizon."""
    model = GM11.fit([E] * 6)
    assert abs(model.a) < 1e-12 and model.b == pytest.approx(E, rel=1e-12)
    assert model.predict(50) == pytest.approx(E, rel=1e-10)
    assert model.predict_ago(4) == pytest.approx(4 * E, rel=1e-10)
    predictor = GreyPredictor(n=4, m=2, horizon=25, bias=50.0)
    for _ in range(10):
        value = predictor.update(E - 50.0 + 1.0)
    assert value == pytest.approx(E - 49.0, abs=1e-9 * max(1.0, E))


def test_gm11_errors():
    with pytest.raises(ValueError, match="at least 3"):
        GM11.fit([1.0, 2.0])
    with pytest.raises(ValueError, match="sample 2 is nan"):
        GM11.fit([1.0, math.nan, 2.0])
    with pytest.raises(GreyModelError, match="C\\(i\\)"):
        GM11.fit([5.0, 0.0, 0.0, 0.0])  # Z(k) constant
    with pytest.raises(GreyModelError, match="\\|a\\| < 2"):
        GM11(a=2.5, b=1.0, first=1.0, n=4).predict(5)


def test_predictor_modes_and_ldispi_window():
    """The moving window takes every m-th sample (§3.1.6 Method 3) and predicts n − 1 + horizon/m GM steps on."""
    predictor = GreyPredictor(n=4, m=5, horizon=20, bias=1.0, a_min=0.0)
    signal = [0.1 * k + 0.002 * k * k for k in range(40)]
    for k, x in enumerate(signal[:16]):
        out = predictor.update(x)
        if k < 15:
            assert predictor.mode is PredictorMode.FILLING and out == x
    assert predictor.mode is PredictorMode.PREDICTED
    window = [signal[k] + 1.0 for k in (0, 5, 10, 15)]  # every 5th sample, biased by B = 1
    a, _, e0_hat = reference_gm11(window)
    assert predictor.a == pytest.approx(a, rel=1e-9)
    assert out == pytest.approx(e0_hat(4 + 20 / 5) - 1.0, rel=1e-9)  # n + horizon/m = 8th GM sample
    assert out > signal[15]  # a rising signal is predicted to keep rising


def test_predictor_a_min_rule_estimates_the_current_value():
    """§4.2: |a| <= a_min → the model's estimate ê(n) of the current sample instead of a prediction."""
    predictor = GreyPredictor(n=4, m=1, horizon=25, bias=50.0, a_min=0.035)
    for x in [0.0, 0.1, 0.2, 0.3]:
        out = predictor.update(x)
    a, _, e0_hat = reference_gm11([50.0, 50.1, 50.2, 50.3])
    assert predictor.a == pytest.approx(a, rel=1e-9) and abs(a) <= 0.035
    assert predictor.mode is PredictorMode.ESTIMATED
    assert out == pytest.approx(e0_hat(4) - 50.0, rel=1e-9)  # ê0(n), not ê0(n + 25)
    assert abs(e0_hat(4 + 25) - 50.0 - out) > 1.0  # the prediction would differ
    assert out == pytest.approx(0.3, abs=1e-3)


@pytest.mark.parametrize("threshold, predicts_rising", [(Threshold.SIGNED, False), (Threshold.MAGNITUDE, True)])
def test_predictor_threshold_signed_as_printed_or_magnitude(threshold, predicts_rising):
    """§4.2 "a(i) larger than 0.035": SIGNED predicts only a decaying biased signal (a > 0); MAGNITUDE either."""
    rising, falling = [0.0, 2.0, 4.5, 7.5], [7.5, 4.5, 2.0, 0.0]
    for signal, predicted in ((rising, predicts_rising), (falling, True)):
        predictor = GreyPredictor(n=4, m=1, horizon=25, bias=50.0, a_min=0.035, threshold=threshold)
        for x in signal:
            predictor.update(x)
        assert abs(predictor.a) > 0.035
        assert (predictor.mode is PredictorMode.PREDICTED) is predicted


def test_predictor_fallbacks():
    """A biased sample <= 0 (B too small) or a singular fit gives the current sample; NaN raises."""
    predictor = GreyPredictor(n=3, horizon=5, bias=0.5)
    for x in [-1.0, -0.9, -0.8]:
        out = predictor.update(x)
    assert predictor.mode is PredictorMode.FALLBACK and out == -0.8
    flat = GreyPredictor(n=3, horizon=5)
    for x in [1e6, 1e-9, 1e-9]:
        out = flat.update(x)  # Z(2) ≈ Z(3): C(i) of (3.6b) vanishes relative to ΣZ²
    assert flat.mode is PredictorMode.FALLBACK and out == 1e-9
    with pytest.raises(ValueError, match="not a finite"):
        predictor.update(math.inf)
    with pytest.raises(ValueError, match="n must be"):
        GreyPredictor(n=2)


def test_table_1_with_the_papers_equations():
    """002_* Table 1 through (12)-(16) with rows k = 2..8 and x(0) = 0, as the paper writes them.

    The rounded table gives θ = [−615.99, −12.881, −5.5371]; the paper prints θ = [−4700.6, 876.422, 360.715].
    The printed θ is what (16) gives for data within the table's rounding (±0.5e-4): θ is not determined by
    Table 1 to its sign (docs/grey.md)."""
    theta = GM3t1.fit(TABLE1)
    np.testing.assert_allclose([theta.a1, theta.a2, theta.b], [-615.9856, -12.88141, -5.537078], rtol=1e-6)
    unrounded = TABLE1 + 1e-5 * np.array([3.5658, 1.2407, -3.4382, 4.8128, 0.4086, 0.9476, -2.5633, -0.5628])
    assert np.all(np.abs(unrounded - TABLE1) < 0.5e-4)
    near = GM3t1.fit(unrounded)
    np.testing.assert_allclose([near.a1, near.a2, near.b], [-4700.6, 876.422, 360.715], rtol=1e-4)
    without_x0 = GM3t1.fit(TABLE1, x_before=None)  # rows 3..8: well conditioned, a1 < 0 as well
    np.testing.assert_allclose([without_x0.a1, without_x0.a2, without_x0.b], [-1.664894, 0.3297872, 0.1358106], rtol=1e-5)
    assert without_x0.constants(0.925).ks == pytest.approx(0.445, abs=5e-4)


def test_paper_constants_and_whitening_response():
    """002_* §4: θ → k_s = 0.445, ω_n = 29.6, ζ = 79.4 (ω_n taken −√a2 for ζ), λ1 = −0.186, λ2 = −4700.3 (19);
    Table 2's y(t) by (20) with y(10.1 min) = x1(1): 0.41228, 0.41226, 0.41225, 0.41224, 0.41223, 0.41222."""
    constants = PAPER_THETA.constants(0.925)
    assert round(constants.ks, 3) == 0.445 and round(constants.wn, 1) == 29.6 and round(constants.zeta, 1) == 79.4
    assert constants.stable is False  # a1 < 0: the sign the paper's convention hides
    slow, fast = constants.roots()
    assert round(slow.real, 3) == -0.186 and fast.real == pytest.approx(-4700.3, rel=1e-4)  # ours −4700.41
    t = np.array([10.3, 10.4, 10.5, 10.6, 10.7, 10.8])
    y = constants.dominant_response(t, 10.1, TABLE1[0], 0.925)
    np.testing.assert_allclose(y, [0.41228, 0.41226, 0.41225, 0.41224, 0.41223, 0.41222], atol=1.5e-5)
    assert 0.925 * constants.ks == pytest.approx(0.4116, abs=5e-5)  # the level of (20)


def test_recursion_17_is_equation_8():
    """(17) solves (8) for x̂1(k).  Table 2 prints x̂1(3..8) = 0.4125, 0.4126, 0.4127, 0.4128, 0.413, 0.4132; (17)
    with the printed θ gives 0.41257, 0.41277, 0.41302, 0.41332, 0.41367, 0.41410 (within 0.22 %)."""
    xhat = PAPER_THETA.recursion(TABLE1[0], TABLE1[1], 8)
    np.testing.assert_allclose(xhat[2:], [0.412569, 0.412773, 0.413019, 0.413316, 0.413674, 0.414105], atol=1e-6)
    np.testing.assert_allclose(xhat[2:], [0.4125, 0.4126, 0.4127, 0.4128, 0.413, 0.4132], rtol=2.5e-3)
    a1, a2, b = PAPER_THETA.a1, PAPER_THETA.a2, PAPER_THETA.b
    alpha1 = np.diff(xhat)
    residual = np.diff(alpha1) + a1 * alpha1[1:] + a2 * 0.5 * (xhat[2:] + xhat[1:-1]) - b
    np.testing.assert_allclose(residual, 0.0, atol=1e-9)


def _step_samples(ks: float, wn: float, zeta: float, Ts: float, count: int) -> list[float]:
    plant = SecondOrder(ks, wn, zeta)
    return [0.0] + [plant.advance(k * Ts, Ts, 1.0) for k in range(count - 1)]


@pytest.mark.parametrize("ks, wn, zeta", [(2.0, 0.1, 0.5), (0.5, 0.05, 2.0), (1.0, 1.0, 0.2), (3.0, 0.2, 1.0)])
def test_gm3t1_recovers_a_simulated_second_order_process(ks, wn, zeta):
    """Noise-free step response sampled at ω_n·Ts = 0.05 (125 samples per natural period) until settled:
    k_s within 2 %, ω_n and ζ within 10 % (measured: within 0.7 %, 4.5 %, 7 %)."""
    Ts = 0.05 / wn
    settle = 8.0 / (wn * (zeta - math.sqrt(zeta * zeta - 1.0))) if zeta > 1.0 else 8.0 / (zeta * wn)
    identifier = StepIdentifier(1.0, int(settle / Ts), Ts)
    for y in _step_samples(ks, wn, zeta, Ts, identifier.count):
        identifier.add(y)
    result = identifier.result
    assert result is not None and result.stable
    assert result.ks == pytest.approx(ks, rel=0.02)
    assert result.wn == pytest.approx(wn, rel=0.10)
    assert result.zeta == pytest.approx(zeta, rel=0.10)


def test_gm3t1_numerical_safety():
    with pytest.raises(GreyModelError, match="no dynamics"):
        GM3t1.fit([0.3] * 20)  # constant data
    with pytest.raises(GreyModelError, match="3 unknowns"):
        GM3t1.fit([0.1, 0.2, 0.3])  # too short
    with pytest.raises(GreyModelError, match="3 unknowns"):
        GM3t1.fit([0.1, 0.2, 0.3, 0.4], x_before=None)
    with pytest.raises(ValueError, match="sample 3 is inf"):
        GM3t1.fit([0.1, 0.2, math.inf, 0.4, 0.5])
    with pytest.raises(GreyModelError, match="singular"):
        GM3t1.fit(0.5 * np.arange(1, 21), x_before=0.0)  # a ramp from x(0) = 0: α2 ≡ 0, a1 and a2 not separable
    with pytest.raises(GreyModelError, match="a2 = "):
        GM3t1(1.0, -2.0, 1.0).constants(1.0)
    underdamped = GM3t1(0.2, 0.04, 0.08).constants(1.0)  # complex roots: ζ = 0.5
    slow, fast = underdamped.roots()
    assert underdamped.zeta == pytest.approx(0.5) and slow.imag != 0.0 and slow == fast.conjugate()
    with pytest.raises(GreyModelError, match="real roots"):
        underdamped.dominant_response(1.0, 0.0, 0.0, 1.0)
    growing = StepIdentifier(1.0, 10, 1.0)
    for k in range(10):
        growing.add(math.exp(0.2 * k) * (1.0 - math.cos(0.5 * k)))  # an unstable "process"
    assert growing.result is None and "not stable" in growing.error


def test_grey_pi_has_no_offset_theorem_3_5():
    """Theorem 3.5: under a constant load the grey predictive PI drives y to r (Propositions 3.4/3.5: ê → e → 0)."""
    controller = GrayPredictivePI(3.0, 30.0, 1.0, n=4, m=5, ph=10.0, B=2.0, a_min=0.035)
    plant = SecondOrder(1.0, 1 / math.sqrt(150.0), 35 / (2 * math.sqrt(150.0)))
    for k in range(1500):
        u = controller.step(1.0, plant.y)
        plant.advance(k, 1.0, u, -0.5 if k >= 400 else 0.0)
    assert plant.y == pytest.approx(1.0, abs=1e-6)
    assert controller.e_hat == pytest.approx(0.0, abs=1e-6) and controller.u == pytest.approx(1.5, abs=1e-5)


def test_grey_pi_is_the_pi_until_the_window_is_full():
    grey = GrayPredictivePI(2.0, 20.0, 1.0, n=4, m=5, ph=25.0, B=50.0)
    pi = PID(2.0, 20.0, 0.0, 1.0)
    for k in range(15):
        assert grey.step(1.0, 0.01 * k) == pytest.approx(pi.step(1.0, 0.01 * k), rel=1e-15)
    assert grey.mode is PredictorMode.FILLING


def test_grey_pi_defaults_to_the_printed_rule_and_passes_anti_windup_to_its_pi():
    """GrayPredictivePI's threshold defaults to §4.2 as printed (SIGNED); anti_windup=False reaches its PID."""
    grey = GrayPredictivePI(2.0, 20.0, 1.0, u_min=0.0, u_max=1.0, anti_windup=False)
    assert grey.predictor.threshold is Threshold.SIGNED and grey.pi.anti_windup is False
    for _ in range(300):
        grey.step(1.0, 0.0)
    assert grey.u == 1.0 and grey.pi.I > 10.0  # the integral winds up behind the limited output


def test_second_order_plant_is_exact():
    """The plant used by the scenarios: the analytic under-damped step response at any step size."""
    wn, zeta = 0.1, 0.5
    coarse, fine = SecondOrder(1.0, wn, zeta, tau=3.0), SecondOrder(1.0, wn, zeta, tau=3.0)
    for k in range(10):
        coarse.advance(0.7 * k, 0.7, 1.0)
    for k in range(70):
        fine.advance(0.1 * k, 0.1, 1.0)
    t = 7.0 - 3.0
    wd = wn * math.sqrt(1 - zeta**2)
    exact = 1 - math.exp(-zeta * wn * t) * (math.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * math.sin(wd * t))
    assert coarse.y == pytest.approx(exact, rel=1e-12) and fine.y == pytest.approx(exact, rel=1e-12)


def test_simulation_3_3_a_is_not_the_reciprocal_of_the_time_constant():
    """Sim. 3.3: "a(i) for each case is not equal to the reciprocal of process time constant".  The process 1/(40s + 1)
    with u = 2·1(t) + 1(t − 250) − 1(t − 470), sampled every second, GM(1,1) on n = 4 samples (m = 1): after each step
    |a| stays below 0.013 (1/T = 0.025 per sample), falling to 0 as the output settles.  REPRODUCED.  a is 1/T only for
    a pure exponential (the output's distance from its final value): 2·tanh(1/80) = 0.024999, the bilinear (3.5a)."""
    T = 40.0
    t = np.arange(0.0, 700.0)
    u = 2.0 * (t >= 0) + (t >= 250) - (t >= 470)
    y = np.zeros_like(t)
    for k in range(1, len(t)):  # exact zero-order-hold step of 1/(40 s + 1)
        y[k] = y[k - 1] * math.exp(-1 / T) + u[k - 1] * (1 - math.exp(-1 / T))
    predictor = GreyPredictor(n=4, m=1, horizon=20)
    a = []
    for value in y:
        predictor.update(value)
        a.append(predictor.a)
    a = np.array(a, dtype=float)
    after_steps = ((t >= 252) & (t < 470)) | (t >= 472)
    assert np.nanmax(np.abs(a[after_steps])) < 0.013 < 0.6 / T
    assert abs(a[-1]) < 1e-4
    decay = GreyPredictor(n=4, m=1, horizon=20)
    for value in 2.0 * np.exp(-np.arange(8.0) / T):
        decay.update(value)
    assert decay.a == pytest.approx(2.0 * math.tanh(0.5 / T), rel=1e-9) == pytest.approx(1.0 / T, rel=1e-3)


def test_chapter_5_a_large_bias_makes_the_prediction_symmetric():
    """Ch. 5: "the bias B should be large enough to reduce the different predictive effects for the process output
    increase and decrease".  A rise and a fall of the same first-order shape (±(1 − e^{−t/20})), n = 4, m = 1, 10
    samples ahead: how far the prediction runs ahead of the signal, rise over fall, is 1.61 at B = 1.2, 1.33 at B = 2,
    1.06 at B = 10, 1.011 at B = 50 (the thesis's ch. 4 value), 1.001 at B = 1000.  REPRODUCED."""
    t = np.arange(0.0, 200.0)
    shape = np.where(t >= 20, 1 - np.exp(-(t - 20) / 20.0), 0.0)

    def asymmetry(B: float) -> float:
        leads = []
        for sign in (1.0, -1.0):
            predictor = GreyPredictor(n=4, m=1, horizon=10, bias=B)
            predicted = np.array([predictor.update(v) for v in sign * shape])
            leads.append(float(np.max(sign * (predicted - sign * shape)[20:60])))
        return leads[0] / leads[1]
    ratios = [asymmetry(B) for B in (1.2, 2.0, 10.0, 50.0, 1000.0)]
    assert ratios == sorted(ratios, reverse=True) and ratios[0] > 1.5
    assert abs(ratios[3] - 1.0) < 0.02 and abs(ratios[4] - 1.0) < 0.002
