"""Scenarios of Cîrtoaje et al. (seed 001_*) through the master on the real FMUs: the paper's findings measured.

Loop: setpoint 0 → 1 at 40 s, load −0.2 on the plant input at 2500 s, 0 … 5000 s, step 2 s.
"""

import math
import sys
import warnings
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

import cosim
from cosim.present.metrics import step_metrics
from greyfmu.control.scheduling import ITAE

SSP = Path(__file__).resolve().parents[2] / "ssp"
NOMINAL, NMP, PID_LOOP = SSP / "sopdt_nominal", SSP / "sopdt_nmp", SSP / "sopdt_pid_itae"
SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"
sys.path.insert(0, str(SSP.parent / "docs"))
from sopdt_report import (  # noqa: E402
    NOMINAL as REPORT_NOMINAL,
    OVERLAP_HORIZONS,
    START,
    best_weighting,
    controller_radius,
    design_row,
    loop_metrics,
    run,
    sampled_loop,
    spectral_radius,
    transient_time,
)
from greyfmu.plants import ThirdOrderPlant  # noqa: E402

sys.path.remove(str(SSP.parent / "docs"))


def simulate(scenario, case=None):
    return cosim.simulate(scenario, parameter_sets=[] if case is None else [scenario / case])


def setpoint_metrics(result):
    return step_metrics(result["time"], result["plant.y"], result["setpoint.y"], t0=40.0, t1=2500.0)


def error_peak(result, start, stop):
    window = (result["time"] >= start) & (result["time"] <= stop)
    return float(np.max(np.abs(result["setpoint.y"][window] - result["plant.y"][window])))


def unstable(result):
    """The oscillation grows: the error's late peak (after the load has settled in a stable loop) exceeds the early one."""
    return error_peak(result, 4000.0, 5000.0) > 1.2 * error_peak(result, 1000.0, 2500.0)


def settled(result, band=0.02):
    return error_peak(result, 4500.0, 5000.0) < band


@pytest.fixture(scope="module")
def nominal():
    return simulate(NOMINAL)


def test_nominal_run_tracks_the_setpoint_and_rejects_the_load(nominal):
    r = nominal
    assert r["time"][-1] == 5000.0 and len(r) == 2501
    assert r["plant.y"][r["time"] <= 40.0 + 90.0 + 2.0].max() == 0.0  # dead time 90 s after the first move at 40 s + 2 s
    m = setpoint_metrics(r)
    assert 20.0 < m["overshoot"] < 32.0  # measured 25.8 % (the paper prints no number)
    assert settled(r) and not unstable(r)
    assert r["controller.u"][-1] == pytest.approx(1.0 / 1.2 + 0.2, abs=2e-3)  # offset-free: u = r/K − d
    assert (r["controller.m"][-1], r["controller.N"][-1]) == (2.0, 17.0)  # printed: m = 2, N = 17


def test_too_small_X_k_destabilises_and_a_larger_one_stabilises_and_slows(nominal):
    """Figs. 3-4.  Loss of stability between X_k = 1.0 and 1.1 (ρ = 1 at X_k = 1.073, docs/sopdt_tables.md)."""
    small, large = simulate(NOMINAL, "fig03_xk_1.0.ssv"), simulate(NOMINAL, "fig04_xk_3.0.ssv")
    assert unstable(small)
    assert settled(large)
    m_nominal, m_large = setpoint_metrics(nominal), setpoint_metrics(large)
    assert m_large["rise_time"] > 1.5 * m_nominal["rise_time"]  # 368 s against 188 s
    assert m_large["overshoot"] < 1.0 < m_nominal["overshoot"]


def test_response_gets_faster_as_X_p_goes_to_1(nominal):
    """Fig. 10: rise time 408 s (X_p = 0.2), 188 s (0.6), 154 s (1.0)."""
    runs = (simulate(NOMINAL, "fig10_xp_0.2.ssv"), nominal, simulate(NOMINAL, "fig10_xp_1.0.ssv"))
    rise = [setpoint_metrics(r)["rise_time"] for r in runs]
    assert rise[0] > rise[1] > rise[2]


@pytest.mark.parametrize("case", ["fig06_xd_0.5.ssv", "fig07_xd_3.2.ssv", "fig08_xt_2.0.ssv"])
def test_too_small_or_too_large_X_d_and_too_large_X_t_destabilise(case):
    """Figs. 6-8: the loop is stable for X_d in 0.89 … 3.11 (m = 2 … 6) and X_t up to 1.47 only."""
    assert unstable(simulate(NOMINAL, case))


def test_xi_1_gives_the_best_response(nominal):
    """Fig. 9: 'the best response is obtained for maximum value of ξ'."""
    assert setpoint_metrics(simulate(NOMINAL, "fig09_xi_1.0.ssv"))["IAE"] < setpoint_metrics(nominal)["IAE"]


def test_reference_trajectory_smooths_the_approach(nominal):
    """Fig. 5: with T_ref = 200 s the overshoot drops from 25.8 % to 9.9 %, the loop stays alike."""
    r = simulate(NOMINAL, "fig05_tref_200.ssv")
    assert settled(r) and setpoint_metrics(r)["overshoot"] < setpoint_metrics(nominal)["overshoot"]


def test_law_15_needs_a_larger_X_k():
    r = simulate(NOMINAL, "law15_xk_3.0.ssv")
    assert settled(r) and not unstable(r)


def test_non_minimum_phase_process_is_stabilised_by_a_large_X_k():
    """Fig. 11: T4 = 60 s.  Unstable at X_k = 1.5, stable above X_k = 1.628 (ρ = 1), well damped at 4."""
    assert unstable(simulate(NMP, "fig11_xk_1.5.ssv"))
    r = simulate(NMP)
    assert settled(r)
    assert setpoint_metrics(r)["overshoot"] < 10.0
    after_move = (r["time"] > 130.0) & (r["time"] < 300.0)
    assert r["plant.y"][after_move].min() < -0.01  # the inverse response of the zero at +1/60


def test_horizon_rule_N_at_most_20_is_not_what_decides_stability():
    """Paper (abstract, §4): N in 15 … 20, at most 20, "to ensure the stability and good performances".
    Measured (exact ρ, docs/sopdt_tables.md): N = 21 … 34 are stable at X_k = 1.5 while N = 15 and 13 (m = 1)
    are not; the X_k at which stability is lost grows with the unmodelled dead time τ + master step − m·T,
    whatever N is."""
    periods = (20.0, 28.0, 32.0, 40.0, 46.0, 50.0, 64.0, 80.0)
    rows = {T: design_row({"Ts": T}) for T in periods}
    for T, (controller, rho, _) in rows.items():
        N = controller.design.N
        if N > 20:
            assert rho < 1.0, (T, N)  # beyond the paper's limit and stable
        if T in (46.0, 50.0):
            assert 13 <= N <= 15 and rho > 1.0  # inside (or just under) the paper's range and unstable
    unmodelled = {T: START["tau"] + 2.0 - c.design.m * T for T, (c, _, _) in rows.items()}
    for a in periods:
        for b in periods:
            if unmodelled[a] >= unmodelled[b] + 4.0:
                assert rows[a][2] > rows[b][2], (a, b)  # more unmodelled delay: a larger X_k is needed


def test_horizon_of_24_through_the_master_is_stable_and_better_than_17(nominal):
    """T = 28 s: N = 24, m = 3 (warned, still designed): settles, setpoint IAE 374 against 423 at N = 17."""
    r = simulate(NOMINAL, "horizon_T_28.ssv")
    assert r["controller.N"][-1] == 24.0
    assert settled(r) and not unstable(r)
    assert setpoint_metrics(r)["IAE"] < setpoint_metrics(nominal)["IAE"]


def test_raising_X_k_recovers_stability_lost_to_X_t_or_a_small_X_d():
    """§4: "the system may be usually stabilized by increasing X_k" — it is for X_t = 1.5 … 3 and X_d = 0.3, 0.5."""
    for tuning, recovered in (({"X_t": 1.8}, 2.0), ({"X_t": 3.0}, 4.6), ({"X_d": 0.5}, 1.9)):
        assert spectral_radius(tuning) > 1.0  # lost at the default X_k = 1.5
        assert spectral_radius({**tuning, "X_k": recovered}) < 1.0, tuning
        assert controller_radius(tuning) == pytest.approx(1.0, abs=1e-9)  # the controller alone: only its integrator
    r = simulate(NOMINAL, "remedy_xt_1.8_xk_3.0.ssv")
    assert settled(r) and not unstable(r)


def test_raising_X_k_cannot_recover_X_d_of_3_12_and_more():
    """m = [2.25 X_d] = 7 for X_d >= 3.12: the controller alone (output held at 0) has a mode of 1.00033, which
    X_k does not change (b ∝ X_k, q ∝ 1/X_k); ρ stays above 1 for every X_k up to 100 and tends to it."""
    assert controller_radius({"X_d": 3.11}) == pytest.approx(1.0, abs=1e-9)  # m = 6: only the integrator
    for X_d in (3.12, 3.2, 3.6):
        radius = controller_radius({"X_d": X_d})
        assert radius > 1.0003
        assert controller_radius({"X_d": X_d, "X_k": 40.0}) == pytest.approx(radius, rel=1e-12)
        rho = [spectral_radius({"X_d": X_d, "X_k": X_k}) for X_k in (1.5, 3.0, 10.0, 30.0, 100.0)]
        assert all(r > radius for r in rho) and rho == sorted(rho, reverse=True)
    assert controller_radius({"X_d": 3.12}) == pytest.approx(1.00033, abs=1e-5)
    assert unstable(simulate(NOMINAL, "remedy_xd_3.2_xk_3.0.ssv"))


def test_itae_pid_comparison_uses_the_rule_2_8():
    values = {p.get("name"): float(p[0].get("value")) for p in ElementTree.parse(PID_LOOP / "pid.ssv").iter(f"{SSV}Parameter")}
    gains = ITAE(A=0.35)(1.2, 200.0, 90.0)
    assert (values["Kc"], values["Ti"], values["Td"]) == pytest.approx(tuple(gains), rel=1e-9)
    full = {p.get("name"): float(p[0].get("value")) for p in ElementTree.parse(PID_LOOP / "itae_full.ssv").iter(f"{SSV}Parameter")}
    assert full["controller.Kc"] == pytest.approx(ITAE()(1.2, 200.0, 90.0).Kc, rel=1e-9)
    pid = simulate(PID_LOOP)
    assert settled(pid)
    assert unstable(simulate(PID_LOOP, "itae_full.ssv"))  # the rule's A = 1.357 (Kc = 2.41) is too strong here


def test_fig_5_reference_trajectory_has_no_important_impact_only_for_T_ref_up_to_T(tmp_path):
    """Fig. 5 / §3: "the introduction of the reference trajectory has not an important impact on the loop dynamics".
    The paper gives no T_ref; studied 0 … 400 s (α^m = e^{−mT/T_ref}, m = 2; docs/sopdt_tables.md).  "No important
    impact" = alike (docs/judging.md: within ±10 %), in both readings of "loop dynamics":
    - the set-point response (overshoot, rise, settling, IAE): up to T_ref = T = 40 s (25.8 → 25.4 %, IAE 423.4 →
      421.6); from 80 s the overshoot falls by more than 10 % (23.2 %), at 200 s to 9.9 % (load IAE −21 %);
    - the loop itself, its slowest mode's time constant −T/ln ρ: 644 s without, 598 s at 100 s (−7 %), 551 s at 150 s
      (−14 %), 510 s at 200 s (−21 %): up to T_ref = 100 s (2.5 T).
    Verdict: reproduced for T_ref ≤ T (response) and ≤ 2.5 T (poles); not beyond."""
    none, short, long = (loop_metrics(run(REPORT_NOMINAL, {"controller.T_ref": T_ref}, tmp_path)) for T_ref in (0.0, 40.0, 200.0))
    for key in ("overshoot", "rise_time", "settling_time", "IAE"):
        assert short[key] == pytest.approx(none[key], rel=0.1)
    assert long["overshoot"] < 0.5 * none["overshoot"] and long["IAE"] < 0.9 * none["IAE"]
    assert long["load_IAE"] < 0.85 * none["load_IAE"]
    constant = {T_ref: -40.0 / math.log(spectral_radius({"T_ref": T_ref})) for T_ref in (0.0, 100.0, 150.0)}
    assert constant[100.0] == pytest.approx(constant[0.0], rel=0.1) and constant[150.0] < 0.9 * constant[0.0]


def test_fig_9_xi_changes_the_response_by_more_than_a_tenth_over_the_papers_range():
    """Fig. 9: "The change of the time constants allocation coefficient ξ does not reveal major effects upon the system
    response form"; the conclusion recommends ξ in 0.6 … 1.0.  From ξ = 0.6 to 1.0 (docs/sopdt_tables.md) the set-point
    IAE falls 8.7 % (423.4 → 386.7), the rise time grows 2 % (188 → 192 s), but the overshoot falls 14 % (25.8 → 22.1 %)
    and the settling time 18 % (2180 → 1798 s); over 0.2 … 1.0 the IAE falls 36 %.  "No major effect" = alike
    (docs/judging.md, ±10 %): 2 of 4 quantities over the recommended range — PARTLY REPRODUCED; not over 0.2 … 1.0."""
    low, high = setpoint_metrics(simulate(NOMINAL)), setpoint_metrics(simulate(NOMINAL, "fig09_xi_1.0.ssv"))
    alike = {key: abs(high[key] - low[key]) <= 0.1 * low[key] for key in ("IAE", "rise_time", "overshoot", "settling_time")}
    assert alike == {"IAE": True, "rise_time": True, "overshoot": False, "settling_time": False}


def test_section_3_X_p_in_0_5_to_0_8_is_near_best_only_from_the_default_X_k_on(tmp_path):
    """§3 (Fig. 10): "for many processes X_p can be fixed in advance at a value in the range 0.5 - 0.8".  The setpoint-IAE
    best X_p (grid 0.2 … 1, master runs, docs/sopdt_tables.md) moves with X_k: 0.3 (X_k = 1.2), 0.4 (1.5, the paper's
    default), 0.6 (2), 0.9 (3); the best value inside 0.5 … 0.8 costs +31.6 %, +4.3 %, 0 %, +2.2 % (NMP process:
    +21.5 % at X_k = 2, +0.4 % at 4).  Verdict: partly — near-best (≤ 5 %) at X_k ≥ 1.5, not for a small X_k."""
    cost = {}
    for X_k, expected in ((1.2, 0.3), (1.5, 0.4), (3.0, 0.9)):
        best, iae = best_weighting(REPORT_NOMINAL, 0.0, X_k, tmp_path)
        assert best == expected, (X_k, iae)
        cost[X_k] = min(iae[v] for v in (0.5, 0.6, 0.7, 0.8) if v in iae) / iae[best] - 1.0
    assert cost[1.5] < 0.05 and cost[3.0] < 0.05 < 0.25 < cost[1.2]


def test_abstract_horizon_overlapping_the_transient_time_is_no_threshold(nominal):
    """Abstract/§4: "the prediction horizon should completely overlap the transient time".  Model fixed (T0 = 200 s,
    T = 40 s), N set directly: N·T from 240 s to 1200 s against T_r = 518 s (±5 %).  The loop of `sampled_loop` is the
    master's to the last bit.  Setpoint IAE falls steadily with N (1479, 744, 559, 486, 466 at N = 13 = T_r/T, 439, …,
    391 at N = 30) with diminishing returns and no step where N·T passes T_r; horizons shorter than T_r (N = 8 … 12)
    are stable at X_k = 1.5, only N = 6 (0.46 T_r) is not; the X_k where stability is lost falls with N (1.34 → 1.01).
    Verdict: partly — a longer horizon helps, but the overlap point is not where stability or performance changes."""
    np.testing.assert_array_equal(sampled_loop({})["plant.y"], nominal["plant.y"])
    assert transient_time(ThirdOrderPlant()) == 518.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = {N: (design_row({"N": N}), loop_metrics(sampled_loop({"N": N}))["IAE"]) for N in OVERLAP_HORIZONS}
    iae = [rows[N][1] for N in OVERLAP_HORIZONS]
    assert iae == sorted(iae, reverse=True)
    per_sample = {N: (rows[a][1] / rows[N][1]) ** (1.0 / (N - a)) for a, N in zip(OVERLAP_HORIZONS, OVERLAP_HORIZONS[1:])}
    assert per_sample[13] < per_sample[12]  # crossing N·T = T_r (12 → 13) gains less per sample than 10 → 12
    assert rows[6][0][1] > 1.0 and all(rows[N][0][1] < 1.0 for N in (8, 10, 12))
    limits = [rows[N][0][2] for N in OVERLAP_HORIZONS]
    assert limits == sorted(limits, reverse=True)


# --- the FMUs alone ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["SOPDTPredictive", "ThirdOrderPlant"])
def test_fmu_passes_fmpy_validation(built_fmus, name):
    assert validate_fmu(str(built_fmus[name])) == []


@pytest.fixture
def controller_fmu(built_fmus, tmp_path):
    path = built_fmus["SOPDTPredictive"]
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(
        guid=description.guid,
        unzipDirectory=extract(path, tmp_path),
        modelIdentifier=description.coSimulation.modelIdentifier,
        instanceName="c",
    )
    fmu.instantiate(loggingOn=True)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    yield fmu, refs, description
    fmu.terminate()
    fmu.freeInstance()


def test_operator_changes_are_tunable_and_redesign_the_controller(controller_fmu):
    fmu, refs, description = controller_fmu
    variability = {v.name: v.variability for v in description.modelVariables}
    assert all(variability[name] == "tunable" for name in ("K", "T0", "tau", "xi", "X_k", "X_t", "X_d", "X_p"))
    fmu.setReal([refs["r"]], [1.0])
    for k in range(3):
        fmu.doStep(40.0 * k, 40.0)
    fmu.setReal([refs["tau"]], [130.0])  # the operator changes τ: m = [130/40] = 3, N = [(130 + 600)/40] = 18
    fmu.doStep(120.0, 40.0)
    assert fmu.getReal([refs["m"], refs["N"]]) == [3.0, 18.0]
    fmu.setReal([refs["K"]], [-1.0])  # refused with a logged warning; the old value stays
    assert fmu.getReal([refs["K"]]) == [1.2]
    fmu.doStep(160.0, 40.0)
    u = fmu.getReal([refs["u"]])[0]
    fmu.setReal([refs["y"]], [math.nan])  # a missing measurement holds u (warning logged)
    fmu.doStep(200.0, 40.0)
    assert fmu.getReal([refs["u"]])[0] == u


def test_horizon_above_20_is_warned_in_the_fmu_log(controller_fmu, capfd):
    """An operator change to T0 = 300 s gives N = [(90 + 900)/40] = 24 > 20: designed, and the warning is logged."""
    fmu, refs, _ = controller_fmu
    fmu.setReal([refs["T0"]], [300.0])
    fmu.doStep(0.0, 40.0)
    assert fmu.getReal([refs["N"]]) == [24.0]
    assert "horizon N = [(tau + 3 T0)/Ts] = 24 exceeds the paper's limit of 20" in capfd.readouterr().out
