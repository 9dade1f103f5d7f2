"""OSMM scheduling: regulating efficiency (31), choice (32), active model (33), the OSMM-GPC step (§4)."""

import logging

import numpy as np
import pytest

from greyfmu.control.gpc import CARIMA, Bounds
from greyfmu.control.osmm import OSMMGPC, ARXStructure, boiler_groups, choose_group, regulating_efficiency
from greyfmu.control.ts_fuzzy import Antecedent, TSModel
from greyfmu.plants import FourTank, HeaderParameters, SteamHeader, least_fuel_firing, segment_demands, steady_firing
from greyfmu.plants.steam_header import firing_for_steam

# A linear 3-boiler, 2-pressure plant: y_j(k) = a y_j(k−1) + Σ_i b_ji M_i(k−1) + c_j.
A_POLE = 0.9
GAINS = np.array([[0.30, 0.10, 0.05], [0.05, 0.10, 0.20]])  # b_ji; boiler 1 and 3 strongest
C = 0.875 - GAINS.sum(axis=1) * 0.75  # steady state y = 8.75 at M = 0.75


def exact_models(groups):
    """One-rule TS models of each group equal to the plant with the third boiler's effect in the affine term."""
    antecedent = Antecedent.from_widths([[0.75, 0.75]], [[1.0, 1.0]])
    models = []
    for group in groups:
        other = [i for i in range(3) if i not in group][0]
        rows = []
        for j in range(2):
            rows.append(TSModel(antecedent, [[A_POLE, *GAINS[j, list(group)], C[j] + GAINS[j, other] * 0.75]]))
        models.append(rows)
    return models


def test_groups_are_the_combinations():
    assert boiler_groups(3, 2) == [(0, 1), (0, 2), (1, 2)]


def test_regulating_efficiency_formula_and_singular_denominator():
    model = CARIMA([[1.0, -0.9], [1.0, -0.5]], [[[0.1], [0.2]], [[0.3], [0.1]]])
    assert regulating_efficiency(model, form="gain") == pytest.approx((0.3 / 0.1) + (0.4 / 0.5))
    assert regulating_efficiency(model, [1.0, 0.0], form="gain") == pytest.approx(3.0)
    assert regulating_efficiency(model) == pytest.approx((0.1 / 0.3) + (0.5 / 0.4))  # (31) as printed: A(1)/ΣB(1)
    with pytest.raises(ValueError, match="'gain' or 'printed'"):
        regulating_efficiency(model, form="inverse")
    integrating = CARIMA([[1.0, -1.0], [1.0, -0.5]], [[[0.1], [0.2]], [[0.3], [0.1]]])
    assert np.isnan(regulating_efficiency(integrating)) and np.isnan(regulating_efficiency(integrating, form="gain"))
    no_gain = CARIMA([[1.0, -0.9], [1.0, -0.5]], [[[0.1], [-0.1]], [[0.3], [0.1]]])  # Σ_l B(1) = 0: (31) as printed is singular
    assert np.isnan(regulating_efficiency(no_gain))


def test_choice_excludes_singular_groups(caplog):
    with caplog.at_level(logging.WARNING):
        assert choose_group([1.0, np.nan, 0.5], previous=2) == 0
        assert choose_group([np.nan, np.nan, np.nan], previous=2) == 2
    assert "excluded" in caplog.text


def test_active_model_is_the_fuzzy_blend():
    antecedent = Antecedent.from_widths([[0.0], [1.0]], [[0.3], [0.3]])
    model = TSModel(antecedent, [[0.5, 1.0, 0.0], [0.7, 3.0, 0.0]])
    controller = OSMMGPC([(0,)], [[model]], ARXStructure(1, 1), [0.5])
    carima = controller.active_model(0)
    assert carima.A[0][1] == pytest.approx(-0.6) and carima.B[0][0][0] == pytest.approx(2.0)  # λ = (½, ½) at z = 0.5


def simulate(controller, steps=300, disturbance=0.02):
    """Plant from its steady state y = 8.75; a load disturbance on output 1 after step 50."""
    y = np.full(2, 8.75)
    M = np.full(3, 0.75)
    history = []
    for k in range(steps):
        y = A_POLE * y + GAINS @ M + C - (np.array([disturbance, 0.0]) if k > 50 else 0.0)
        M = controller.step([8.75, 8.75], y)
        history.append((y.copy(), M.copy(), controller.group, controller.last_path))
    return history


def test_osmm_picks_most_efficient_pair_holds_the_other_and_respects_bounds():
    groups = boiler_groups(3, 2)
    bounds = Bounds(0.5, 1.0, -0.02, 0.02)
    controller = OSMMGPC(groups, exact_models(groups), ARXStructure(1, 1), [0.75] * 3, move_weight=0.5, bounds=bounds, adapt=False,
                         efficiency_form="gain")
    history = simulate(controller)
    efficiencies = [regulating_efficiency(controller.active_model(g), form="gain") for g in range(3)]
    assert controller.group == int(np.argmax(efficiencies)) == 1  # boilers 1 and 3 have the largest gains
    M = np.array([h[1] for h in history])
    assert np.all(M[:, 1] == 0.75)  # boiler 2, never chosen, holds its firing
    assert np.all(M >= 0.5 - 1e-9) and np.all(M <= 1.0 + 1e-9)
    assert np.all(np.abs(np.diff(M, axis=0)) <= 0.02 + 1e-9)
    assert np.all(np.isfinite(M))
    assert np.allclose(history[-1][0], 8.75, atol=1e-3)  # the disturbance is rejected


@pytest.mark.parametrize("form, best, worst", [("printed", 2, 1), ("gain", 1, 2)])
def test_osmm_schedules_the_group_of_largest_efficiency_in_either_form_never_the_smallest(form, best, worst):
    """(32) picks the group of LARGEST η.  On the exact models the two forms of (31) disagree, so the printed form's
    choice is not a by-product of the gain form's: printed η = Σ_j A_j(1)/Σ_l B_jl(1) is 0.917 / 0.686 / 1.000 for
    (1,2) / (1,3) / (2,3) (the weakest pair has the largest), gain η = Σ_j Σ_l B_jl(1)/A_j(1) is 5.5 / 6.0 / 4.5.
    A scheduler that takes the smallest η (or maximises the other form) holds another pair."""
    groups = boiler_groups(3, 2)
    controller = OSMMGPC(groups, exact_models(groups), ARXStructure(1, 1), [0.75] * 3, bounds=Bounds(0.5, 1.0, -0.02, 0.02),
                         adapt=False, efficiency_form=form)
    history = simulate(controller, steps=120)
    printed = [0.1 / 0.4 + 0.1 / 0.15, 0.1 / 0.35 + 0.1 / 0.25, 0.1 / 0.15 + 0.1 / 0.30]  # A(1) = 1 − 0.9, ΣB(1) by hand
    gain = [(0.4 + 0.15) / 0.1, (0.35 + 0.25) / 0.1, (0.15 + 0.30) / 0.1]
    np.testing.assert_allclose(controller.efficiencies, printed if form == "printed" else gain, rtol=1e-9)
    assert {h[2] for h in history} == {best}
    held = [i for i in range(3) if i not in groups[best]][0]
    assert np.all(np.array([h[1] for h in history])[:, held] == 0.75)  # the boiler outside the chosen pair holds
    assert best != worst and choose_group(controller.efficiencies, previous=worst) == best


def test_choice_is_the_largest_finite_value():
    assert choose_group([0.3, 0.9, 0.5], previous=0) == 1
    assert choose_group([-2.0, -1.0, -3.0], previous=0) == 1
    assert choose_group([np.inf, 0.2, 0.1], previous=0) == 1  # a non-finite η is excluded, not the largest


def test_osmm_with_fixed_pair_and_adaptation_stays_finite():
    groups = boiler_groups(3, 2)
    controller = OSMMGPC(groups, exact_models(groups), ARXStructure(1, 1), [0.75] * 3, bounds=Bounds(0.5, 1.0, -0.02, 0.02),
                         fixed_group=0, adapt=True, omega=0.01)
    history = simulate(controller)
    M = np.array([h[1] for h in history])
    assert np.all(M[:, 2] == 0.75) and np.all(np.isfinite(M))
    assert {h[2] for h in history} == {0}


def plant_marginal_steam(plant: SteamHeader, firing: np.ndarray, delta: float = 1e-4) -> np.ndarray:
    """d(steady steam)/d(fuel) of each boiler measured on the plant: central differences of the steam flows w_g of
    its equilibrium (firing and steam states checked to be at rest in its dynamics) over its fuel F_i, not
    `marginal_steam`."""
    result = np.empty(3)
    for i in range(3):
        step = np.zeros(3)
        step[i] = delta
        states, fuels = [], []
        for u in (firing - step, firing + step):
            x = plant.equilibrium(u, np.array([0.5, 0.5]))
            assert np.max(np.abs(plant.derivative(x, u, np.array([0.5, 0.5]))[0:6])) < 1e-12  # firing, steam at rest
            plant.x = x
            states.append(x[3:6])
            fuels.append(plant.fuel)
        result[i] = (states[1][i] - states[0][i]) / (fuels[1][i] - fuels[0][i])
    return result


def test_header_plant_efficiency_ordering_behind_the_papers_switching():
    """§5.2: boiler 1 most efficient throughout; boiler 3 better than 2 at first, 2 better once 3 is loaded.
    Measured on the plant (steady steam per fuel, central differences), and `marginal_steam` — what the
    reconstruction says regulating efficiency tracks — agrees with it.  This is the plant property behind the
    paper's switching; whether our OSMM-GPC switches that way is tests/scenarios/test_osmm_scenarios.py's (it
    with (31) as printed on seed 0 it does — one switch (1,3) → (1,2) — but not over seeds, docs/osmm_gpc.md)."""
    p = HeaderParameters()
    plant = SteamHeader(p)
    assert np.allclose(plant.pressures, 8.75) and plant.fuel.sum() == pytest.approx(16.2)  # Table 3's firing scale
    for firing in (np.full(3, 0.75), np.array([0.9, 0.75, 0.9])):
        np.testing.assert_allclose(p.marginal_steam(firing), plant_marginal_steam(plant, firing), rtol=1e-6)
    design = plant_marginal_steam(plant, np.full(3, 0.75))
    assert design[0] > design[2] > design[1]
    loaded3 = plant_marginal_steam(plant, np.array([0.9, 0.75, 0.9]))
    assert loaded3[0] > loaded3[1] > loaded3[2]


def test_four_tank_ramp_continuous_and_literal():
    """(41)–(42): the scenario's c(k) = 1 − 0.0005 (k − 500) and the printed 1 − 0.0005 k (ramp_origin = 0)."""
    continuous, literal = FourTank(), FourTank(ramp_origin=0)
    assert continuous.coefficient(500) == literal.coefficient(500) == 1.0  # no change up to step 500
    assert continuous.coefficient(501) == pytest.approx(1.0 - 0.0005)
    assert literal.coefficient(501) == pytest.approx(1.0 - 0.0005 * 501)  # a jump to 0.75 at the change
    assert literal.coefficient(1500) == pytest.approx(0.25) and continuous.coefficient(1500) == pytest.approx(0.5)


OPERATING_POINTS = {"design": (0.5, 0.5), "valve 1 at 70 %": (0.7, 0.5), "valve 2 at 35 %": (0.7, 0.35)}


def test_segment_balances_fix_each_pairs_steady_firing():
    """§5.2's valve steps on our header: the firing a pair must reach to hold both pressures at 8.75 MPa is
    fixed by the two segment balances, and the plant's own equilibrium at that firing has both pressures at 8.75."""
    p = HeaderParameters()
    plant = SteamHeader(p)
    for valves in OPERATING_POINTS.values():
        for pair in boiler_groups(3, 2):
            q = steady_firing(p, pair, valves, 0.75)
            if np.all(np.isfinite(q)):
                assert plant.equilibrium(q, np.asarray(valves))[9:11] == pytest.approx([8.75, 8.75], abs=1e-9)
    step1 = {pair: steady_firing(p, pair, OPERATING_POINTS["valve 1 at 70 %"], 0.75) for pair in boiler_groups(3, 2)}
    assert np.allclose(step1[(0, 1)], step1[(0, 2)]) and step1[(0, 1)][0] == pytest.approx(1.195, abs=1e-3)  # B1 takes it all
    assert np.isnan(step1[(1, 2)][1])  # (2,3) cannot: B2 would need more than its peak steam
    step2 = {pair: steady_firing(p, pair, OPERATING_POINTS["valve 2 at 35 %"], 0.75) for pair in boiler_groups(3, 2)}
    assert step2[(0, 1)][1] < 0.3  # (1,2) would need B2 below M_min = 0.3: it cannot hold both pressures
    assert 0.3 < step2[(0, 2)][2] < 0.75 and step2[(0, 2)][0] == pytest.approx(1.195, abs=1e-3)


def test_least_fuel_allocation_leaves_no_room_for_the_papers_saving():
    """Table 3's 1.6 % cannot come from scheduling in this header: pair (1,3)'s forced firing is within 0.02 %
    of the least-fuel firing at every operating point of the experiment; even a boiler 2 with 11 % more steam
    per fuel than boiler 3 leaves less than 1 %."""
    p = HeaderParameters()
    for valves in OPERATING_POINTS.values():
        least = least_fuel_firing(p, valves, 0.3, 1.2)
        pair = steady_firing(p, (0, 2), valves, 0.75)
        assert np.all((least >= 0.3 - 1e-9) & (least <= 1.2 + 1e-9))
        assert plant_pressures(p, least, valves) == pytest.approx([8.75, 8.75], abs=1e-9)
        assert 0.0 <= (pair.sum() - least.sum()) / pair.sum() < 2e-3
        for w2 in np.linspace(0.0, 2.0 * min(segment_demands(p, valves)), 41):  # no feasible point of the family burns less
            D1, D2 = segment_demands(p, valves)
            q = np.array([firing_for_steam(p, i, w) for i, w in enumerate((D1 - w2 / 2, w2, D2 - w2 / 2))])
            if np.all(np.isfinite(q)) and np.all((q >= 0.3) & (q <= 1.2)):
                assert q.sum() >= least.sum() - 1e-9
    better_b2 = HeaderParameters(eta_max=(0.92, 0.99, 0.90))
    valves = OPERATING_POINTS["valve 1 at 70 %"]
    pair, least = steady_firing(better_b2, (0, 2), valves, 0.75), least_fuel_firing(better_b2, valves, 0.3, 1.2)
    assert 0.005 < (pair.sum() - least.sum()) / pair.sum() < 0.0161


def plant_pressures(p, q, valves):
    return SteamHeader(p).equilibrium(q, np.asarray(valves))[9:11]


def test_equilibrium_is_at_rest_away_from_the_design_point():
    """SteamHeader.equilibrium is a steady state of SteamHeader.derivative for any firing and valves, also where the
    segment pressures differ: B2 sits between the segments, so at rest its flow G_s (P_b2 − (P1 + P2)/2) = w2 enters
    segment 1 as 0.5 G_s (P_b2 − P1) = w2/2 + 0.25 G_s (P2 − P1) — the 0.25 G_s (P2 − P1) term the balance of
    the equilibrium missed before (its pressures were off by up to 0.041 MPa in these cases; exact only for P1 = P2)."""
    plant = SteamHeader(HeaderParameters())
    for u, v in (([1.0, 0.5, 0.8], [0.7, 0.3]), ([0.4, 1.1, 0.6], [0.35, 0.65]), ([0.75, 0.75, 0.75], [0.5, 0.5])):
        u, v = np.asarray(u), np.asarray(v)
        x = plant.equilibrium(u, v)
        assert np.max(np.abs(plant.derivative(x, u, v))) < 1e-9, (u, v)
    x = plant.equilibrium(np.array([1.0, 0.5, 0.8]), np.array([0.7, 0.3]))
    assert abs(x[9] - x[10]) > 0.01  # the case where the term matters
