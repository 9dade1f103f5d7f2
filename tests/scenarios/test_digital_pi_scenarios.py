"""The ssp/dpi_* scenarios through cosim with the real StochasticLTI, DigitalPI and PID FMUs."""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.linalg

import cosim
from greyfmu.control.digital_pi import c2d, closed_loop, design_digital_pi, stationary_variances, stored_design
from greyfmu.control.digital_pi.augment import augment_delay
from greyfmu.control.digital_pi.companion import block_companion
from greyfmu.control.digital_pi.gain_study import closed_loop_records, innovation_predictions, prediction_excess
from greyfmu.control.digital_pi.identification import (
    armax_observer,
    els_convergence_margin,
    extended_least_squares,
    one_step_predictions,
)
from greyfmu.control.digital_pi.examples import ch47, wood_berry

CASES = {"dpi_ch47": (ch47, (1.0, 2.0, 3.0, 4.0)), "dpi_wood_berry": (wood_berry, (200.0, 400.0, 600.0, 800.0))}


def at(result, name, t):
    return result[name][np.argmin(np.abs(result["time"] - t))]


def design_of(example):
    return design_digital_pi(example.plant, example.Ts, example.tau, example.alpha, example.beta, example.q, example.r)


@pytest.fixture(scope="module", params=sorted(CASES))
def deterministic(request, built_fmus):
    return request.param, cosim.simulate(f"ssp/{request.param}")


def test_static_decoupling_and_disturbance_rejection(deterministic):
    """r1 step at 0, r2 step later, −1 on y1 then y2: before each event the outputs sit at (r1, r2)
    (within 5e-3: the CH-47 loop keeps a slow pole at 0.9998, as the paper's, with a small residue; the
    Wood–Berry loop at the paper's disc (0.2, 0.7) needs 117–188 min to get there, hence events 200 min apart)."""
    name, result = deterministic
    t2, t3, t4, stop = CASES[name][1]
    for t, expected in [(t2, (1.0, 0.0)), (t3, (1.0, 1.0)), (t4, (1.0, 1.0)), (stop, (1.0, 1.0))]:
        before = t - CASES[name][0]().Ts
        assert at(result, "plant.y1", before) == pytest.approx(expected[0], abs=5e-3)
        assert at(result, "plant.y2", before) == pytest.approx(expected[1], abs=5e-3)


def test_cosimulation_equals_the_designed_discrete_loop(deterministic):
    """Up to the r2 step the FMU loop equals the closed loop (9)/(10) + PI + observer sampled at kT, built
    from the gains the scenario's controller.ssv gives the FMU (as a deployed controller has them), not
    from a design recomputed here: at the paper's disc the Wood–Berry design moves by up to 2.7 % between
    OpenBLAS kernels (test_stored_design_is_the_design_up_to_its_conditioning).  The tolerance is relative
    to the largest output of the transient: the loop matrix has cond ≈ 1e18 (Wood–Berry), so the
    matrix–vector products of 400 steps, summed in a kernel's own order, differ in their last bits."""
    name, result = deterministic
    example = CASES[name][0]()
    design = stored_design(design_of(example), f"ssp/{name}/controller.ssv")
    A, B_r, _, C_y, _ = closed_loop(design)
    xi = np.zeros(A.shape[0])
    steps = int(round(CASES[name][1][0] / example.Ts))
    expected = []
    for _ in range(steps):
        expected.append(C_y @ xi)
        xi = A @ xi + B_r @ np.array([1.0, 0.0])
    expected = np.array(expected)
    simulated = np.column_stack([result["plant.y1"][:steps], result["plant.y2"][:steps]])
    np.testing.assert_allclose(simulated, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


@pytest.mark.parametrize("name", sorted(CASES))
def test_stored_design_is_the_design_up_to_its_conditioning(name):
    """The controller.ssv gains are this machine's design up to what the design's conditioning allows:
    the closed-loop poles of the stored gains lie in the paper's disc |z − β| < α, and the stored gains
    equal a design recomputed here within 10 % for Wood–Berry (at the disc (0.2, 0.7), cond(P) ≈ 2.3e14:
    measured up to 2.7 % (K2) between the Prescott, Nehalem, Sandybridge, Haswell and Zen kernels of
    OpenBLAS, Riccati backward error 4.2e-3–4.8e-3) and 1e-6 for the CH-47 (the kernels agree to 5e-14)."""
    example = CASES[name][0]()
    fresh = design_of(example)
    stored = stored_design(fresh, f"ssp/{name}/controller.ssv")
    A = stored.Gbar - stored.Hbar @ np.hstack([stored.F + stored.K1 @ stored.augmented.Cp, stored.K2])
    assert np.abs(np.linalg.eigvals(A) - example.beta).max() < example.alpha
    tolerance = {"dpi_wood_berry": 0.10, "dpi_ch47": 1e-6}[name]
    for matrix in ("F", "K2"):
        ours, theirs = getattr(stored, matrix), getattr(fresh, matrix)
        assert np.abs(ours - theirs).max() <= tolerance * np.abs(theirs).max(), matrix


@pytest.mark.parametrize("name, stop", [("dpi_ch47", 20.0), ("dpi_wood_berry", 2000.0)])
def test_regulation_variances_match_the_lyapunov_values(name, stop, built_fmus):
    """Stochastic test (42): r = 0, innovations of covariance Q_η; 2000 samples estimate E{y²}, E{u²}
    within 25 % of the stationary values of the designed loop."""
    example = CASES[name][0]()
    result = cosim.simulate(f"ssp/{name}", stop_time=stop, parameter_sets=[f"ssp/{name}/regulation.ssv"])
    keep = result["time"] >= 0.1 * stop
    simulated = [np.mean(result[c][keep] ** 2) for c in ("plant.y1", "plant.y2", "controller.u1", "controller.u2")]
    var_y, var_u = stationary_variances(design_of(example), example.Q_eta)
    np.testing.assert_allclose(simulated, [*var_y, *var_u], rtol=0.25)


def test_decentralised_pi_comparison_settles(built_fmus):
    """The centralised PI decouples: y2's excursion after the r1 step is smaller than under the two SISO PIs —
    in the unit disc (α = 1, β = 0, `unit_disc.ssv`); at the paper's disc (0.2, 0.7) it is far larger."""
    result = cosim.simulate("ssp/dpi_wood_berry_decentral")
    assert at(result, "plant.y1", 199) == pytest.approx(1.0, abs=0.02)
    assert at(result, "plant.y2", 399) == pytest.approx(1.0, abs=0.1)
    ours = cosim.simulate("ssp/dpi_wood_berry", parameter_sets=["ssp/dpi_wood_berry/unit_disc.ssv"])
    first = ours["time"] < 200
    decentral = np.abs(result["plant.y2"][result["time"] < 200]).max()
    assert np.abs(ours["plant.y2"][first]).max() < 0.1 < decentral
    assert np.abs(ours["plant.y1"][first]).max() < 1.1
    # Paper, after (40): "our proposed PI control gives much better tracking response for both step set-point change
    # and disturbance rejection" than the decentralised PI.  On the substitute (Wood–Berry, BLT PIs): IAE of
    # |e1| + |e2| over each event's 200 min, r1 step / r2 step / −1 on y1 / −1 on y2: 5.9 / 6.7 / 7.5 / 11.1 against
    # 23.9 / 34.1 / 23.4 / 35.1 (ratio 0.20-0.32, "much better" = at most 0.8), within 2 % after 11-17 min against
    # 135-172 min.
    for start in (0, 200, 400, 600):
        references = (1.0, 0.0 if start == 0 else 1.0)  # r1 steps at 0, r2 at 200 min

        def iae(r: np.ndarray) -> float:
            window = (r["time"] >= start) & (r["time"] < start + 200)
            return float(sum(np.sum(np.abs(r[f"plant.y{i + 1}"][window] - references[i])) for i in (0, 1)))
        totals = (iae(ours), iae(result))
        assert totals[0] <= 0.8 * totals[1], (start, totals)


def test_paper_disc_on_wood_berry_has_a_huge_transient(built_fmus):
    """Verdict for the substitute plant: at (α, β) = (0.2, 0.7) with the 16 delay states every pole is in the
    disc, but the unit r1 step drives |y| to ~540 and |u1| to ~180 lb/min; in the unit disc |y| ≤ 1.06."""
    paper = cosim.simulate("ssp/dpi_wood_berry", stop_time=199.0)
    unit = cosim.simulate("ssp/dpi_wood_berry", stop_time=199.0, parameter_sets=["ssp/dpi_wood_berry/unit_disc.ssv"])
    peak = {name: max(np.abs(r["plant.y1"]).max(), np.abs(r["plant.y2"]).max()) for name, r in
            [("paper", paper), ("unit", unit)]}
    assert peak["paper"] > 400 and peak["unit"] < 1.06
    assert np.abs(paper["controller.u1"]).max() > 100


# --- issue 31: what the paper states without showing it ----------------------------------------------------

SEEDS_FULL = os.environ.get("GREYFMU_SEEDS") == "full"
"""GREYFMU_SEEDS=full: the ELS verdicts over 20 seeds (s = 0 … 19) instead of 5 (Wood–Berry) and 3 (SISO)."""
ELS_SEEDS, SISO_SEEDS = (range(20), range(20)) if SEEDS_FULL else (range(5), range(3))


def transmission_zeros(G: np.ndarray, H: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Finite generalised eigenvalues of the Rosenbrock pencil ([[G, H], [C, 0]], diag(I, 0)) of a square plant."""
    n, m, p = G.shape[0], H.shape[1], C.shape[0]
    pencil = np.block([[G, H], [C, np.zeros((p, m))]])
    mass = np.block([[np.eye(n), np.zeros((n, m))], [np.zeros((p, n + m))]])
    zeros = scipy.linalg.eigvals(pencil, mass)
    return np.sort_complex(zeros[np.isfinite(zeros)])


def test_example_2_ch47_is_minimum_phase_in_continuous_time_and_not_once_sampled_with_T_2():
    """Example 2 calls the CH-47 "a 4th-order unstable non-minimum phase system with 3 RHP poles".  With the
    recovered B, C (recovered-models.md §2, from memory) the only transmission zero of (A, B, C) is −0.0180:
    minimum phase; the text's "non-minimum phase" holds for the poles (3 in the RHP), not for a zero.  Sampled at
    T = 0.01 s the plant alone has zeros 0.99982 and −0.9947 (inside the unit circle); with the ZOH's τ = T/2 delay
    (the design model (9)) they are 0.99982, −0.1707, −1.0022 and −5.7975: the sampled design model is
    non-minimum phase (discrete sense) — the one reading under which the paper's word holds for our B, C."""
    example = ch47()
    plant = example.plant
    continuous = transmission_zeros(plant.A, plant.B, plant.C)
    np.testing.assert_allclose(continuous, [-0.01799], atol=1e-5)
    assert np.sum(np.linalg.eigvals(plant.A).real > 0) == 3  # the 3 RHP poles the paper quotes
    no_delay = augment_delay(c2d(plant, example.Ts, 0.0))
    np.testing.assert_allclose(np.sort(transmission_zeros(no_delay.Gp, no_delay.Hp, no_delay.Cp).real),
                               [-0.99468, 0.99982], atol=1e-5)
    design_model = augment_delay(c2d(plant, example.Ts, example.tau))
    zeros = transmission_zeros(design_model.Gp, design_model.Hp, design_model.Cp)
    np.testing.assert_allclose(np.sort(zeros.real), [-5.79753, -1.00219, -0.17066, 0.99982], atol=1e-5)
    assert np.sum(np.abs(zeros) > 1.0) == 2


def test_observer_poles_are_outside_the_lemma_1_disc_on_wood_berry():
    """Lemma 1 places the poles of the state-feedback loop Ḡ − H̄K̄ in |z − β| < α; the innovation observer (47)
    G − ΓC is not placed (its poles are the Kalman predictor's), so the loop with the observer has them too.
    Wood–Berry at the paper's disc (0.2, 0.7): the controller poles reach 0.878 of the radius, but the observer has
    16 poles at z = 0 (the delay states), 0.0418 and 0.9582 — 18 of the 42 poles of the full loop lie outside the
    disc, the slowest at |z| = 0.958 (outside |z| < 0.9).  CH-47 (α = 1, β = 0): all inside (|z| ≤ 0.99982)."""
    wb = design_of(wood_berry())
    assert np.abs(wb.closed_loop_poles - 0.7).max() / 0.2 == pytest.approx(0.878, abs=1e-3)
    assert np.abs(wb.observer_poles).max() == pytest.approx(0.95820, abs=1e-5)
    full = np.linalg.eigvals(closed_loop(wb)[0])
    assert full.size == 42 and np.sum(np.abs(full - 0.7) >= 0.2) == 18
    assert np.abs(full).max() == pytest.approx(0.95820, abs=1e-5)
    ch = design_of(ch47())
    assert np.abs(np.linalg.eigvals(closed_loop(ch)[0])).max() < 1.0


def els_against_truth(seed: int, N: int = 4000) -> tuple[float, float]:
    """Wood–Berry, the whole ARMAX unknown (the paper's route): mean squared one-step prediction error on the
    identification record itself (first 10 % dropped) of the ELS model and of the true innovation model."""
    example = wood_berry()
    discrete = c2d(example.plant, example.Ts, example.tau)
    aug = augment_delay(discrete)
    r = block_companion(discrete.G, discrete.C).Go_blocks.shape[0]
    y, u = closed_loop_records(example, N, seed, dither=0.1)
    model = extended_least_squares(y, u, na=r, nb=r + aug.lags, nc=r).model
    keep = slice(N // 10, None)
    els = float(np.mean((y - one_step_predictions(armax_observer(model), y, u))[keep] ** 2))
    true = float(np.mean((y - innovation_predictions(aug, y, u))[keep] ** 2))
    return els, true


def test_els_fits_its_own_record_better_than_the_true_parameters():
    """On its own record (N = 4000) the ELS model predicts better than the true parameters do (seed 3: 4.849e-3
    against 4.871e-3), on every seed (20/20 with GREYFMU_SEEDS=full).  Any least-squares fit that has converged does
    this, so it does not tell an ELS held off the optimum from a flat criterion: the out-of-sample test below does."""
    pairs = [els_against_truth(seed) for seed in ELS_SEEDS]
    better = sum(els < true for els, true in pairs)
    assert better == len(ELS_SEEDS), pairs


def test_els_predicts_fresh_data_as_an_efficient_estimator_so_the_gain_is_not_identifiable():
    """The discriminating test (issue 46) between "ELS does not converge (its SPR condition fails)" and "the criterion
    is flat in the directions that move K_o": on 20 000 FRESH samples the ELS model's one-step prediction-error variance
    exceeds the true Kalman predictor's by about d/N, the excess of an efficient estimator (Akaike's FPE; d = 28
    parameters per output), and falls as 1/N: Wood–Berry seed 1, 0.63 / 0.63 % at N = 4000 (d/N = 0.70 %), 0.16 / 0.19 %
    at N = 16 000 (0.18 %).  An estimator held away from the optimum keeps a floor: least-squares ARX of the same
    orders (no noise model) 1.25 % → 0.77 % on y1.  So ELS reaches the prediction-error optimum, and the gain it reads
    there is 0.75-0.95 from the Kalman gain because many gains predict alike (docs/digital_pi.md: ‖ΔK‖/‖K‖ 0.85 at
    N = 4000)."""
    short, long = (prediction_excess(wood_berry(), N, seed=1) for N in (4000, 16000))
    for run in (short, long):
        assert np.all(run.els < 2.0 * run.efficient) and np.all(run.els > 0.3 * run.efficient), run
    assert np.all(short.els > 2.5 * long.els)  # 1/N: 4x
    assert long.arx[0] > 3.0 * long.efficient and short.arx[0] < 2.0 * long.arx[0]  # a floor, not 1/N


def siso_els_error(c: tuple[float, float], N: int, seed: int) -> float:
    """Largest parameter error of ELS on y(k) = 0.5 y(k−1) + u(k−1) + e(k) + c1 e(k−1) + c2 e(k−2)."""
    rng = np.random.default_rng(seed)
    e, u, y = rng.standard_normal(N), rng.standard_normal(N), np.zeros(N)
    for k in range(2, N):
        y[k] = 0.5 * y[k - 1] + u[k - 1] + e[k] + c[0] * e[k - 1] + c[1] * e[k - 2]
    model = extended_least_squares(y[:, None], u[:, None], 1, 1, 2).model
    return float(np.abs(np.array([model.A.item(), model.B.item(), *model.D.ravel()]) - [-0.5, 1.0, *c]).max())


def test_els_converges_on_a_siso_armax_whose_spr_condition_fails():
    """Ljung's SPR condition is sufficient, not necessary: with C(z) = 1 + z⁻¹ + 0.9 z⁻² (margin −0.746, as bad as
    Wood–Berry's −0.691) ELS's largest parameter error falls from N = 2000 to N = 100 000 on every seed and is
    below 0.03 there (20/20 with GREYFMU_SEEDS=full; medians 0.152, 0.031 (N = 20 000), 0.013).  So "ELS does not give the Kalman gain because the
    SPR condition fails" does not follow from the margin alone."""
    c = (1.0, 0.9)
    assert els_convergence_margin(np.array([[[c[0]]], [[c[1]]]])) == pytest.approx(-0.746, abs=1e-3)
    errors = [(siso_els_error(c, 2000, seed), siso_els_error(c, 100_000, seed)) for seed in SISO_SEEDS]
    converging = sum(late < early and late < 0.03 for early, late in errors)
    assert converging == len(SISO_SEEDS), errors
