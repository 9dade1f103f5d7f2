"""Thesis 000_*, ch. 4: the boiler-following scheme of Figure 4.1 (ssp/btg_boiler_following) through cosim.

Each test names the simulation whose claim it checks.  Where our reproduction disagrees with
the thesis the test asserts what we measure (and says so); docs/btg.md gives the numbers and
the reason.  Runs are shortened to what a claim needs (one pulse period instead of three,
600-1200 s of load following; 1500 s where the thesis's PI form needs it to settle);
docs/btg_report.py runs the full cases, docs/btg_sensitivity_report.py the grid of grey-PI settings.
Each run names its controller form (FORMS): ours unless the thesis's claim needs the thesis's PI.
"""

import os
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.present.metrics import step_metrics
from greyfmu.plants.boiler_turbine import equilibrium

SCENARIO = Path(__file__).resolve().parents[2] / "ssp" / "btg_boiler_following"
FUEL = {"pi": "fuel_pi.u", "grey": "fuel_grey.u"}
LEVEL_SETPOINT_MODEL_MM = 100.0
"""The thesis's -100 mm set-point on the level datum of the scenario (README: model level - 200 mm)."""


FORMS = {"ours": (), "thesis": ("thesis.ssv",), "thesis |a|": ("thesis.ssv", "magnitude.ssv"),
         "thesis always": ("thesis.ssv", "grey_always.ssv"), "always": ("grey_always.ssv",),
         "parallel": ("thesis.ssv", "parallel.ssv"), "parallel |a|": ("thesis.ssv", "magnitude.ssv", "parallel.ssv"),
         "turbine FGS1": ("turbine_fgs1.ssv",), "thesis slow valve": ("thesis.ssv", "slow_fuel_valve.ssv"),
         "thesis |a| slow valve": ("thesis.ssv", "magnitude.ssv", "slow_fuel_valve.ssv"),
         "thesis always slow valve": ("thesis.ssv", "grey_always.ssv", "slow_fuel_valve.ssv")}
"""Controller forms (docs/btg.md): ours (anti-windup, outputs 0-100 %, |a| > a_min); the thesis's as printed
(no anti-windup, no output limits, a > a_min) with the ISA PI Kc[e + (1/Ti)∫e]; the thesis's PI form with our |a|
rule; the same predicting whenever |a| > 0 (a corner of docs/btg_sensitivity_tables.md); ours predicting whenever
|a| > 0 ("always": the grey PI with its predictor active, where ours never predicts and is the PI on the GM(1,1)
estimate); the two thesis forms with §4.2's printed parallel PI Kc·e + (1/Ti)∫e (parallel.ssv); ours with the
turbine PI scheduled by FGS1 instead of MFGS (turbine_fgs1.ssv); the thesis's forms with the fuel valve at 0.15 %/s
instead of (4.2b)'s 0.7 (slow_fuel_valve.ssv)."""
LEVEL_LIMIT_MM = 100.0
"""§4.2: the drum level stays within ±100 mm of its set-point even in transients."""
SEEDS_FULL = os.environ.get("GREYFMU_SEEDS") == "full"
"""GREYFMU_SEEDS=full runs the stochastic verdicts over the 20 seeds of docs/btg_readings_report.py."""


def predicting(r: np.ndarray) -> float:
    """Share of the samples in which the grey PI acted on a prediction (mode 2 = PREDICTED)."""
    return float(np.mean(r["fuel_grey.mode"] == 2))


@lru_cache(maxsize=None)
def run(case: str, controller: str, stop: float, step: float = 0.5, noise: bool = True, form: str = "ours",
        seed: int | None = None, values: tuple[tuple[str, int | float], ...] = ()) -> np.ndarray:
    """One run of a case with a controller and form; `seed` replaces the case file's noise seed; `values` are
    (component.variable, value) pairs set last (an int is an SSV Integer)."""
    sets = [SCENARIO / f"{case}.ssv", SCENARIO / f"{controller}.ssv", *(SCENARIO / name for name in FORMS[form])]
    if not noise:
        sets.append(SCENARIO / "noise_free.ssv")
    pairs = (*values, *((("noise.seed", seed),) if seed is not None else ()))
    with tempfile.TemporaryDirectory() as folder:
        if pairs:
            sets.append(Path(folder) / "values.ssv")
            rows = "".join(f'<ssv:Parameter name="{name}"><ssv:{"Integer" if isinstance(value, int) else "Real"} '
                           f'value="{value!r}"/></ssv:Parameter>' for name, value in pairs)
            sets[-1].write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/'
                                f'SSP1/SystemStructureParameterValues" version="1.0" name="values"><ssv:Parameters>{rows}'
                                '</ssv:Parameters></ssv:ParameterSet>\n')
        return cosim.simulate(SCENARIO, stop_time=stop, step_size=step, parameter_sets=sets)


def pressure_error(r: np.ndarray) -> np.ndarray:
    return r["pressure_sp.y"] - r["plant.P"]


def settled(r: np.ndarray, window: float = 300.0) -> bool:
    """Stable on every output of the plant: bounded throughout and, over the last `window` seconds, within
    2 kgf/cm2 and 2 MW of the set-points with the drum level within §4.2's ±100 mm (a collapsed unit, level
    1e7 mm, is unstable whatever its pressure does)."""
    tail = r["time"] >= r["time"][-1] - window
    e_p, e_e = pressure_error(r), r["demand.y"] - r["plant.E"]
    level = np.abs(r["plant.L"] - LEVEL_SETPOINT_MODEL_MM)
    bounded = np.all(np.isfinite(e_p)) and np.max(np.abs(e_p)) < 50 and np.max(np.abs(e_e)) < 50
    return bool(bounded and np.max(np.abs(e_p[tail])) < 2.0 and np.max(np.abs(e_e[tail])) < 2.0
                and np.all(np.isfinite(level)) and np.max(level[tail]) <= LEVEL_LIMIT_MM)


def overshoot(r: np.ndarray, y: str = "plant.P", setpoint: str = "sp_step.y") -> float:
    """Overshoot [%] of y after the step of `setpoint`, in the step's direction."""
    step = r[setpoint][-1] - r[setpoint][0]
    return float(100 * np.max(np.sign(step) * (r[y] - r[y][0])) / abs(step) - 100)


@pytest.mark.parametrize("load", [58, 76, 101])
def test_case_files_start_at_the_equilibrium(load):
    """Every controller's bias u0 is the valve position of the plant's starting equilibrium (no bump at t = 0)."""
    text = (SCENARIO / f"sim41_{load}.ssv").read_text()
    op = equilibrium(load, level=LEVEL_SETPOINT_MODEL_MM)
    for name, value in (("fuel_pi.u0", op.fuel), ("fuel_grey.u0", op.fuel),
                        ("turbine.u0", op.governor), ("level.u0", op.feedwater)):
        written = float(text.split(f'name="{name}"><ssv:Real value="')[1].split('"')[0])
        assert written == pytest.approx(value, abs=1e-5)


@pytest.mark.parametrize("controller", ["pi", "grey"])
def test_figure_4_1_rests_at_76_MW(controller):
    """Priority 1: the wiring holds its equilibrium at 76 MW / 109 kgf/cm2 / level set-point with either fuel controller."""
    r = run("sim41_76", controller, 300.0)  # no noise; the set-point step comes at 100 s
    rest = r["time"] < 100.0
    assert np.max(np.abs(r["plant.P"][rest] - 109.0)) < 1e-6
    assert np.max(np.abs(r["plant.E"][rest] - 76.0)) < 1e-6
    assert np.max(np.abs(r["plant.L"][rest] - LEVEL_SETPOINT_MODEL_MM)) < 1e-6
    assert np.max(np.abs(r["plant.governor_pos"][rest] - 75.0)) < 0.1  # "governor at about 75 %"


def test_mfgs_turbine_gain_at_76_MW_is_4_555():
    """(4.6): the MFGS turbine controller scheduled on P_t = 109 kgf/cm2 has Kc = 4.555."""
    r = run("sim41_76", "pi", 300.0)
    assert r["turbine.Kc"][50] == pytest.approx(4.555, abs=5e-4)


def step_response(r: np.ndarray) -> dict[str, float]:
    """Overshoot %, rise time (10-90 %) and settling time (±2 %) of the pressure after the set-point step at 100 s."""
    m = step_metrics(r["time"], r["plant.P"], r["pressure_sp.y"], t0=100.0)
    return {key: m[key] for key in ("overshoot", "rise_time", "settling_time")}


def alike(value: float, reference: float) -> bool:
    """docs/judging.md: "almost the same" = within ±10 % of the reference."""
    return bool(abs(value - reference) <= 0.1 * abs(reference))


@pytest.mark.parametrize("load", [58, 76, 101])
def test_sim_4_1_grey_pi_and_pi_step_responses_alike(load):
    """Sim. 4.1 (Figures 4.5-4.7): "Both controllers have almost the same overshoots, rise time and settling time"
    (alike = within ±10 %, docs/judging.md).  Two readings of "the grey PI":
    - at the thesis's a_min = 0.035 (B = 50, m = 5) it predicts in no sample, the PI on the GM(1,1) estimate:
      overshoot 12.44 / 13.13 / 15.46 % against 12.66 / 13.34 / 15.65 %, rise 19 / 19 / 18.5 s and settling
      286 / 305.5 / 395.5 s equal to the PI's: 9 of 9 alike, REPRODUCED;
    - with its predictor active (|a| > 0, 98 % of the samples): overshoot 10.27 / 10.67 / 12.74 % (−19 … −20 %), rise
      37 / 37 / 36.5 s (1.95 ×), settling 339 / 353 / 432.5 s (+18, +16, +9 %): 1 of 9 alike, NOT REPRODUCED.
    Over the data spacing m (docs/btg_spacing_tables.md) the grey PI stays alike while it does not predict.  The PI's
    12.7-15.7 % is above the thesis's 10 % design criterion (docs/btg.md)."""
    pi, grey = run(f"sim41_{load}", "pi", 800.0), run(f"sim41_{load}", "grey", 800.0)
    reference = step_response(pi)
    assert predicting(grey) == 0.0 and all(alike(v, reference[k]) for k, v in step_response(grey).items())
    assert 10.0 < reference["overshoot"] < 17.0
    assert settled(pi) and settled(grey)
    active = run(f"sim41_{load}", "grey", 800.0, form="always")
    assert predicting(active) > 0.9 and settled(active)
    held = {k: alike(v, reference[k]) for k, v in step_response(active).items()}
    assert held == {"overshoot": False, "rise_time": False, "settling_time": load == 101}


def test_section_4_2_step_responses_at_58_and_101_MW_almost_those_at_76():
    """§4.2: with (4.4)/(4.5) "we get the almost same step responses as Figure 4.2 and 4.3 at N = 58 MW and N = 101
    MW".  The pressure set-point steps (Fig. 4.3's kind; Sim. 4.1's runs), PI, against 76 MW (overshoot 13.34 %, rise
    19 s, settling 305.5 s): at 58 MW 12.66 % / 19 s / 286 s, alike in 3 of 3; at 101 MW 15.65 % (+17 %) / 18.5 s /
    395.5 s (+29 %), alike in 1 of 3.  REPRODUCED at 58 MW, NOT at 101 MW (the power steps of Fig. 4.2 at 58 and 101
    MW are not run)."""
    reference = step_response(run("sim41_76", "pi", 800.0))
    for load, expected in ((58, 3), (101, 1)):
        assert sum(alike(v, reference[k]) for k, v in step_response(run(f"sim41_{load}", "pi", 800.0)).items()) == expected


def test_figures_4_2_4_3_design_criterion_10_percent_overshoot():
    """§4.2: "The control criteria are 10% overshoots for the unit-step responses of electric power and throttle
    pressure" (Figs. 4.2/4.3, both directions).  NOT REPRODUCED with the printed gains (4.3): the pressure overshoots
    13.3 % up and down (Fig. 4.3); the power follows a unit load step without overshoot (0.07 %), the pressure
    overshooting its Fcn-Gen set-point change by 13.1 % (Fig. 4.2)."""
    for direction in ("up", "down"):
        assert 12.5 < overshoot(run(f"fig43_{direction}", "pi", 800.0)) < 14.0
        power = run(f"fig42_{direction}", "pi", 800.0)
        assert overshoot(power, "plant.E", "demand.y") < 1.0
        assert 12.5 < overshoot(power, "plant.P", "pressure_sp.y") < 14.0


def test_section_4_2_fgs_turbine_controller_does_not_overshoot_more_than_mfgs():
    """§4.2: MFGS is suggested for the turbine PI "for FGS1 PI and FGS2 PI, after all, may lead to higher over-shoot, and
    tend to cause the system unstable for time-varying process gains" (Kc(109) = 4.802 against MFGS's 4.555).  NOT
    REPRODUCED on this unit: the power overshoots less with FGS1 — 0.052 % against 0.073 % (+1 MW step, Fig. 4.2) and
    1.45 % against 1.71 % (Sim. 4.2 CASE 8, 17 MW/min) — and both settle; FGS's larger gain gives a larger power error
    during the ramp (0.97 against 0.72 MW), not a larger overshoot."""
    def power_overshoot(r: np.ndarray) -> float:
        change = r["demand.y"][-1] - r["demand.y"][0]
        return float(max(0.0, np.max(np.sign(change) * (r["plant.E"] - r["demand.y"][-1]))) / abs(change) * 100)
    for case, stop in (("fig42_up", 800.0), ("sim42_case8", 1500.0)):
        mfgs, fgs = run(case, "pi", stop), run(case, "pi", stop, form="turbine FGS1")
        assert np.max(fgs["turbine.Kc"] - mfgs["turbine.Kc"]) > 0.2  # FGS's gain is larger between the points
        assert power_overshoot(fgs) < power_overshoot(mfgs) and settled(fgs) and settled(mfgs)


def test_sim_4_2_drum_level_criterion_steady_met_transient_exceeded():
    """§4.2's drum-level criterion: within ±50 mm at a steady load demand, short excursions within ±100 mm.  The
    steady part holds (last 300 s within 21 mm in every stable case); the transient part does NOT: the level peaks
    at 110-144 mm in the 9 MW/min ramps and 321 mm in CASE 8 (17 MW/min) with our PI."""
    for case, peak in ((1, 100.0), (8, 250.0)):
        r = run(f"sim42_case{case}", "pi", 1200.0)
        level = np.abs(r["plant.L"] - LEVEL_SETPOINT_MODEL_MM)
        assert np.max(level) > peak
        assert np.max(level[r["time"] >= 900.0]) < 50.0


@pytest.mark.parametrize("case", [5, 6, 7, 8, 9, 10])
def test_sim_4_2_fast_ramps_our_anti_windup_pi_stays_stable(case):
    """Sim. 4.2 CASES 5-10 with OUR controllers (conditional-integration anti-windup, outputs 0-100 %): both the PI
    and the grey PI settle (the rate-limited fuel valve saturates for a while, then both recover) and their peak
    pressure errors differ by less than 1 kgf/cm2; the grey PI predicts in under 10 % of the samples.  The thesis's
    instability is a property of its PI without anti-windup (next tests), not of the plant."""
    pi, grey = run(f"sim42_case{case}", "pi", 1200.0), run(f"sim42_case{case}", "grey", 1200.0)
    assert settled(pi) and settled(grey)
    assert abs(np.max(np.abs(pressure_error(pi))) - np.max(np.abs(pressure_error(grey)))) < 1.0
    assert np.mean(grey["fuel_grey.mode"] == 2) < 0.10


@pytest.mark.parametrize("case, grey_stable", [(5, True), (7, True), (8, True), (9, False)])
def test_sim_4_2_fast_ramps_thesis_pi_unstable_grey_pi_stable_with_magnitude_rule(case, grey_stable):
    """Sim. 4.2 CASES 5-8: "the BTG system under PI control becomes unstable, it is still stable under the control of
    gray predictive PI"; CASES 9-10: the grey PI "can keep stable for wide ranges of load demand rates".  With the
    thesis's PI form (no anti-windup, no output limits) the PI limit-cycles (last 300 s |e_P| 18-20 kgf/cm2 in CASES
    5, 7, 8, 9) and the grey PI with the |a| rule settles in CASES 5, 7, 8: REPRODUCED there; in CASE 9 (34 MW/min)
    it limit-cycles too (14 kgf/cm2): NOT REPRODUCED.  (CASES 6 and 10, falling loads, settle with both.)"""
    pi = run(f"sim42_case{case}", "pi", 1500.0, form="thesis")
    grey = run(f"sim42_case{case}", "grey", 1500.0, form="thesis |a|")
    tail = pi["time"] >= 1200.0
    assert not settled(pi) and np.max(np.abs(pressure_error(pi)[tail])) > 15.0
    assert settled(grey) is grey_stable


@pytest.mark.parametrize("case", [5, 8])
def test_sim_4_2_printed_parallel_pi_settles_so_the_claim_fails_in_the_papers_reading(case):
    """§4.2 prints the fuel PI as v_b = Kc·e + (1/Ti)∫e (parallel.ssv); read so, with the thesis's other settings
    (no anti-windup, no output limits), the PI SETTLES in CASES 5 and 8 (last 300 s |e_P| 0.42 and 0.73, level
    within 23 mm), so "the BTG system under PI control becomes unstable" is NOT REPRODUCED in the printed
    reading; it holds only in the ISA reading Kc[e + (1/Ti)∫e] of (2.6a)/(2.9a) (previous test,
    docs/btg_readings_tables.md)."""
    pi = run(f"sim42_case{case}", "pi", 1500.0, form="parallel")
    assert settled(pi)
    assert not settled(run(f"sim42_case{case}", "pi", 1500.0, form="thesis"))  # the same case in the ISA reading


SEEDS_20 = (None, *range(1, 20))
"""The case file's seed 23341 (the thesis's) and 19 more: the 20 seeds of docs/btg_readings_report.py."""
SEEDS = SEEDS_20 if SEEDS_FULL else (None, 1, 2)
"""Noise seeds: None = the case file's 23341 (the thesis's); 1-19 more with GREYFMU_SEEDS=full."""
CLAIM_HELD = {5: 11, 7: 15, 8: 12} if SEEDS_FULL else {7: 3}
"""Seeds (of SEEDS) in which "PI unstable, grey PI stable" holds, per CASE: docs/btg_readings_tables.md (full)."""


@pytest.mark.parametrize("case", sorted(CLAIM_HELD))
def test_sim_4_2_stability_verdict_over_noise_seeds(case):
    """Sim. 4.2 CASES 5-8 "PI unstable, grey PI stable" over noise realisations, in the reading where it holds with
    the thesis's seed (ISA PI without anti-windup, grey PI with |a|, turbine and level PIs ours).  Default: CASE 7,
    the thesis's seed and two more (3/3); GREYFMU_SEEDS=full: CASES 5, 7, 8 over 20 seeds: 11, 15, 12 of 20 (most seeds, CASE 5
    barely; the PI is unstable in all 20, the grey PI's last 300 s |e_P| median 0.29 / 0.23 / 0.37, max 14.6 /
    13.3 / 17.6 kgf/cm2).
    Stability includes the drum level (settled)."""
    held = sum(not settled(run(f"sim42_case{case}", "pi", 1500.0, form="thesis", seed=seed))
               and settled(run(f"sim42_case{case}", "grey", 1500.0, form="thesis |a|", seed=seed)) for seed in SEEDS)
    assert held == CLAIM_HELD[case]


STUDY_FULL = os.environ.get("GREYFMU_STUDY") == "full"
"""GREYFMU_STUDY=full re-runs the stability verdict of docs/btg_spacing_tables.md over the data spacing m (20 seeds
per setting and case: 320 grey and 80 PI runs of 1500 s)."""
SPACING_HELD = {(1, 5): 0, (1, 7): 0, (1, 8): 0, (1, 9): 0, (5, 5): 11, (5, 7): 15, (5, 8): 12, (5, 9): 2,
                (10, 5): 20, (10, 7): 20, (10, 8): 20, (10, 9): 20, (25, 5): 0, (25, 7): 11, (25, 8): 13, (25, 9): 20}
"""(m, CASE): seeds of 20 in which "PI unstable, grey PI stable" holds (|a| > 0.035, n = 4; docs/btg_spacing_tables.md)."""
SPACING_LIVE = {(1, 5): 0, (10, 5): 2, (25, 5): 0, (10, 9): 2}
"""The default run: CASE 5, seeds 23341 and 1 — the claim fails at both ends of the range of m and holds at m = 10 — and
CASE 9 (34 MW/min, "stable for wide ranges") at m = 10."""


@pytest.mark.parametrize("m, case", sorted(SPACING_HELD if STUDY_FULL else SPACING_LIVE))
def test_sim_4_2_stability_verdict_over_the_data_spacing(m, case):
    """Sim. 4.2 CASES 5-8 "PI unstable, grey PI stable" over the grey predictor's data spacing m, which the thesis does
    not give for ch. 4 (docs/btg.md borrowed Sim. 3.7's m = 5).  ISA PI without anti-windup, grey PI with |a| > 0.035,
    n = 4; of 20 seeds: m = 1 0 / 0 / 0 (CASES 5 / 7 / 8), m = 5 11 / 15 / 12, m = 10 20 / 20 / 20, m = 25 0 / 11 / 13.
    REPRODUCED at m = 10 (at least 16 of 20 in every case), seed-dependent at m = 5, not at m = 1 nor (CASE 5) at
    m = 25: the claim holds in a band of m.  m·Ts scales the development coefficient a of an error trend, so m decides
    when the threshold lets the grey PI predict (median share of predicting samples in CASE 8: docs/btg_spacing_tables.md).
    CASE 9 (34 MW/min, where the thesis says the grey PI "can keep stable for wide ranges"): 0 / 2 / 20 / 20 of 20 at
    m = 1 / 5 / 10 / 25.  Default: CASE 5 at m = 1, 10, 25 and CASE 9 at m = 10, the case file's seed 23341 (its PI runs
    are the magnitude-rule test's) and seed 1; GREYFMU_STUDY=full: the 16 (m, CASE) of the table over 20 seeds."""
    seeds = SEEDS_20 if STUDY_FULL else SEEDS_20[:2]
    held = sum(not settled(run(f"sim42_case{case}", "pi", 1500.0, form="thesis", seed=seed))
               and settled(run(f"sim42_case{case}", "grey", 1500.0, form="thesis |a|", seed=seed,
                               values=(("fuel_grey.m", m), ("fuel_grey.n", 4))))
               for seed in seeds)
    assert held == (SPACING_HELD if STUDY_FULL else SPACING_LIVE)[m, case]


PI_STABLE_FALLING = {6: 20, 10: 20} if SEEDS_FULL else {6: 3, 10: 3}
"""Seeds (of SEEDS) in which the thesis's ISA PI settles in the falling fast ramps (docs/btg_readings_tables.md)."""


@pytest.mark.parametrize("case", sorted(PI_STABLE_FALLING))
def test_sim_4_2_cases_6_10_falling_ramps_thesis_pi_settles(case):
    """Sim. 4.2 CASE 6 (76 → 58 MW at 25 MW/min) is among "Case 5 to Case 8 ... the BTG system under PI control becomes
    unstable"; CASE 10 (50 MW/min) shows the grey PI "more stable than PI".  NOT REPRODUCED: the thesis's ISA PI (no
    anti-windup, no limits) settles in both, at the thesis's seed (last 300 s |e_P| 0.25 / 0.25) and in 20 of 20 seeds
    (median 0.19, max 0.30 in each; the grey |a| PI alike); the printed parallel PI too (0.21 / 0.31).  The PI's
    command leaves the valve's 0-100 % once (below 0 for 103 / 117 s, never above 100) and recovers; in CASE 5
    (101 → 76 MW) it sits below 0 for 673 s and above 100 for 430 s and limit-cycles."""
    stable = sum(settled(run(f"sim42_case{case}", "pi", 1500.0, form="thesis", seed=seed)) for seed in SEEDS)
    assert stable == PI_STABLE_FALLING[case]


@pytest.mark.parametrize("case", [1, 2, 3, 4])
def test_sim_4_2_slow_ramps_same_overshoot(case):
    """Sim. 4.2 CASES 1-4 (9 MW/min): "the overshoots for both systems ... are almost the same" (alike = peak |e_P|
    within ±10 % of the PI's, docs/judging.md).  At the thesis's a_min the grey PI never predicts (the PI acting on
    the GM(1,1) estimate of the error): 2.78 / 2.73 / 2.92 / 2.95 against 2.69 / 2.83 / 3.02 / 2.86, alike in 4 of 4,
    REPRODUCED.  With its predictor active (97 % of the samples): 2.41 / 3.08 / 3.31 / 2.58, alike in 3 of 4 (CASE 1:
    −10.4 %)."""
    pi, grey = run(f"sim42_case{case}", "pi", 600.0), run(f"sim42_case{case}", "grey", 600.0)
    peak_pi = np.max(np.abs(pressure_error(pi)))
    assert alike(np.max(np.abs(pressure_error(grey))), peak_pi)
    assert predicting(grey) == 0.0
    active = run(f"sim42_case{case}", "grey", 600.0, form="always")
    assert predicting(active) > 0.9
    assert alike(np.max(np.abs(pressure_error(active))), peak_pi) is (case != 1)


def test_sim_4_2_grey_error_8_to_10_only_in_case_5():
    """Sim. 4.2 CASES 5-8: the grey PI stays stable "although the error of the throttle pressure is large, about
    8-10 kgf/cm2".  NOT REPRODUCED beyond CASE 5: with the thesis's PI form and |a| the peak |e_P| is 9.8 in CASE 5
    and 20.5 in CASE 8."""
    peaks = {case: np.max(np.abs(pressure_error(run(f"sim42_case{case}", "grey", 1500.0, form="thesis |a|"))))
             for case in (5, 8)}
    assert 8.0 <= peaks[5] <= 10.0 and peaks[8] > 15.0


def test_sim_4_2_case_8_printed_signed_threshold_loses_the_stability():
    """§4.2's rule as printed, "a(i) larger than 0.035" (signed: predict only while the biased error decays),
    with the thesis's PI form: the grey PI limit-cycles like the PI in Sim. 4.2 CASE 8 (last 300 s |e_P| 18.3
    kgf/cm2).  The thesis's stability claim needs |a| > a_min (previous test)."""
    grey = run("sim42_case8", "grey", 1500.0, form="thesis")
    assert not settled(grey)
    assert np.max(np.abs(pressure_error(grey)[grey["time"] >= 1200.0])) > 15.0


def test_sim_4_3_case_1_pulse_rejection_equal_not_a_third():
    """Sim. 4.3 CASE 1 (26 % fuel pulse): the thesis's grey PI has about 1/3 of PI's pressure error with a
    smaller fuel command.  NOT REPRODUCED: the peak errors and the fuel command ranges agree within 10 %,
    because the grey PI never predicts here (mode 2 in no sample).  Master step 0.1 s = the noise's sample time."""
    pi, grey = run("sim43_case1", "pi", 700.0, 0.1), run("sim43_case1", "grey", 700.0, 0.1)
    ratio = np.max(np.abs(pressure_error(grey))) / np.max(np.abs(pressure_error(pi)))
    assert 0.9 < ratio < 1.1
    assert 0.9 < np.ptp(grey[FUEL["grey"]]) / np.ptp(pi[FUEL["pi"]]) < 1.1
    assert not np.any(grey["fuel_grey.mode"] == 2)


def test_sim_4_3_case_1_electric_power_error_alike_at_the_thesis_settings():
    """Sim. 4.3 CASE 1: "Errors for both throttle pressure and ELECTRIC POWER under the control of the gray predictive
    PI are about 1:3 less than under the control of PI".  The power error: peak |N_d - E| 0.033 MW with either
    controller (ratio 1.015: the grey PI predicts in no sample): NOT REPRODUCED at the thesis's settings.  With the
    predictor active (|a| > 0, 98 %) the ratio is 0.63 (pressure 0.67): "a third less" holds, "a third of" (0.33)
    in neither."""
    def peak_power_error(r: np.ndarray) -> float:
        return float(np.max(np.abs(r["demand.y"] - r["plant.E"])))
    pi = run("sim43_case1", "pi", 700.0, 0.1)
    grey, active = run("sim43_case1", "grey", 700.0, 0.1), run("sim43_case1", "grey", 700.0, 0.1, form="always")
    assert 0.9 < peak_power_error(grey) / peak_power_error(pi) < 1.1 and predicting(grey) == 0.0
    assert 0.55 < peak_power_error(active) / peak_power_error(pi) < 0.7 and predicting(active) > 0.9


def test_ch5_actuators_near_saturation_grey_pi_is_the_pi_at_the_thesis_settings():
    """Ch. 5 (3) (and Sim. 4.3: "at high load or low load ... PI may not because of reset windup"): "if the actuators
    are near saturation limits, gray predictive PI can still achieve good control quality, while PI may not".  Sim. 4.3
    CASE 1 at 58 MW (fuel valve at 28.9 %), noise-free: with the 26 % pulse (sim43_58.ssv) the PI's command touches
    0 %, with 28 % (sim43_58_28.ssv) it sits there 31 s.  NOT REPRODUCED at the thesis's settings: the grey PI
    predicts in no sample and saturates alike (35 s, peak |e_P| 3.23 against the PI's 3.18).  With the predictor
    active (|a| > 0) it never reaches 0 % and peaks at 1.99, but the PI hardly suffers from the limit either: 3.18
    against 2.89 · 28/26 = 3.11 for the unsaturated 26 % pulse scaled.  The "low actuator speed" reading: next test."""
    def at_limit_s(r: np.ndarray, controller: str) -> float:
        return float(np.sum(r[FUEL[controller]] <= 0.05) * 0.5)
    pi, grey = run("sim43_58_28", "pi", 700.0, noise=False), run("sim43_58_28", "grey", 700.0, noise=False)
    active = run("sim43_58_28", "grey", 700.0, noise=False, form="always")
    peak = {name: float(np.max(np.abs(pressure_error(r)))) for name, r in (("pi", pi), ("grey", grey), ("active", active))}
    assert at_limit_s(pi, "pi") > 20.0 and at_limit_s(grey, "grey") > 20.0 and predicting(grey) == 0.0
    assert abs(peak["grey"] - peak["pi"]) < 0.1
    assert at_limit_s(active, "grey") == 0.0 and peak["active"] < 0.7 * peak["pi"]
    unsaturated = np.max(np.abs(pressure_error(run("sim43_58", "pi", 700.0, noise=False)))) * 28.0 / 26.0
    assert peak["pi"] < 1.05 * unsaturated


@pytest.mark.parametrize("case", ["sim43_case1", "sim43_58_28"])
def test_ch5_low_actuator_speed_grey_pi_helps_only_when_it_predicts(case):
    """Ch. 5 (3): "if the speeds of actuators are low ... gray predictive PI can still achieve good control quality, while
    PI may not".  The fuel valve at 0.15 %/s instead of 0.7 (plant.rate_fuel; slow_fuel_valve.ssv), thesis's PI form,
    noise-free first pulse of Sim. 4.3 CASE 1 (76 MW, 26 %) and at 58 MW (28 %): the PI may not — its peak |e_P| grows
    from 2.92 to 9.06 kgf/cm² (3.20 to 7.33 at 58 MW).  At the thesis's settings (a_min = 0.035, m = 5) the grey PI
    predicts in no sample and suffers alike: 8.89 (ratio 0.98) and 6.76 (0.92), NOT "much better" (≤ 0.8): NOT
    REPRODUCED; predicting (|a| > 0) it keeps 2.13 and 2.32 (ratios 0.24, 0.32): REPRODUCED for a grey PI that predicts.
    Over m and the valve speeds: docs/btg_spacing_tables.md."""
    def peak(r: np.ndarray) -> float:
        return float(np.max(np.abs(pressure_error(r))))
    fast = peak(run(case, "pi", 700.0, noise=False, form="thesis"))
    pi = peak(run(case, "pi", 700.0, noise=False, form="thesis slow valve"))
    grey = run(case, "grey", 700.0, noise=False, form="thesis |a| slow valve")
    active = run(case, "grey", 700.0, noise=False, form="thesis always slow valve")
    assert pi > 2.0 * fast
    assert predicting(grey) == 0.0 and 0.8 < peak(grey) / pi < 1.0
    assert predicting(active) > 0.9 and peak(active) / pi < 0.4


@pytest.mark.parametrize("case, active_ratio", [(2, (0.55, 0.75)), (3, (0.6, 0.8))])
def test_sim_4_3_cases_2_3_first_pulse_alike(case, active_ratio):
    """Sim. 4.3 CASE 2 (400 s period): "still much better" with the grey PI; CASE 3 (13 % pulse): "almost the same.
    This is an expected result, since we do not desire to improve the disturbance rejection for a small disturbance at
    the cost of quickly worn out actuator".  At the thesis's a_min = 0.035 the grey PI never predicts and both are
    alike: first-pulse peak |e_P| and fuel range within 10 % of the PI's (CASE 2: 1.02 and 1.05; full runs with noise:
    peak ratios 1.02 and 0.99) — CASE 2 NOT REPRODUCED; CASE 3 REPRODUCED, by the mechanism the thesis names (the
    threshold keeps the grey PI from acting on a small disturbance; whether one threshold also lets it act on the 26 %
    pulse, over the data spacing m: docs/btg_spacing_tables.md).  With the predictor always active (|a| > 0, 97 % of
    the samples) the peak ratio is 0.64 (CASE 2, fuel range 0.85: "much better") and 0.70 (CASE 3, fuel 0.99) — a
    setting the thesis's explanation of CASE 3 excludes, so it does not decide CASE 3.  Noise-free, step 0.5 s."""
    pi = run(f"sim43_case{case}", "pi", 500.0, noise=False)
    peak_pi, range_pi = np.max(np.abs(pressure_error(pi))), np.ptp(pi[FUEL["pi"]])
    grey = run(f"sim43_case{case}", "grey", 500.0, noise=False)
    ratio = np.max(np.abs(pressure_error(grey))) / peak_pi
    assert 0.9 < ratio < 1.1 and 0.9 < np.ptp(grey[FUEL["grey"]]) / range_pi < 1.1
    assert predicting(grey) == 0.0
    active = run(f"sim43_case{case}", "grey", 500.0, noise=False, form="always")
    assert predicting(active) > 0.9
    low, high = active_ratio
    assert low < np.max(np.abs(pressure_error(active))) / peak_pi < high
    assert np.ptp(active[FUEL["grey"]]) / range_pi < 1.0


@pytest.mark.parametrize("case", [1, 2])
def test_sim_4_4_noise_sensitivity_alike(case):
    """Sim. 4.4 CASES 1-2 (white noise on the pressure): the grey PI "has almost the same sensitivity to noises as PI":
    the standard deviation of the fuel command's noise-induced part (noisy minus noise-free run) within ±10 % of the
    PI's (docs/judging.md; ±10 % of std = −19 … +21 % of variance).  HOLDS ONLY WHERE THE GREY PI DOES NOT PREDICT: at
    a_min = 0.035 it predicts in 0 % of the samples (std ratio 0.98, 1.01: the PI compared with itself on the GM(1,1)
    estimate); with the predictor active (|a| > 0, 98 %) the std ratio is 3.5 and 5.4: NOT REPRODUCED for a grey PI
    that predicts.  Over the data spacing m: docs/btg_spacing_tables.md."""
    spread, modes = {}, {}
    for controller, form in (("pi", "ours"), ("grey", "ours"), ("grey", "always")):
        noisy = run(f"sim44_case{case}", controller, 700.0, form=form)
        clean = run(f"sim44_case{case}", controller, 700.0, noise=False, form=form)
        spread[controller, form] = np.std(noisy[FUEL[controller]] - clean[FUEL[controller]])
        modes[controller, form] = predicting(noisy) if controller == "grey" else None
    assert alike(spread["grey", "ours"], spread["pi", "ours"]) and modes["grey", "ours"] == 0.0
    assert modes["grey", "always"] > 0.9
    assert spread["grey", "always"] / spread["pi", "ours"] > 3.0


SIM44_CASES = (1, 2, 3, 4, 5) if SEEDS_FULL else (1,)
"""Sim. 4.4 cases run over SEEDS for the disturbance claim (all five with GREYFMU_SEEDS=full)."""


@pytest.mark.parametrize("case", SIM44_CASES)
def test_sim_4_4_much_better_disturbance_rejection_in_no_seed(case):
    """Sim. 4.4: "From CASE 1 to CASE 6 ... the gray predictive PI ... has much better disturbance rejection ... than
    PI" (the 26 % pulse under five noises).  Peak |e_P| after the pulse (100-700 s, with the noise), grey / PI: at
    the thesis's seed 3.70 / 3.54 (CASE 1), 3.33 / 3.16, 3.11 / 3.05, 3.38 / 3.42, 3.10 / 3.07.  NOT REPRODUCED:
    over 20 seeds the ratio has median 1.012 / 1.006 / 1.010 / 1.003 / 1.012 (min 0.93, max 1.10), below 1 in 6 / 8 /
    3 / 9 / 3 and below 0.8 ("much better") in 0 of 20 in every case, because at a_min = 0.035 the grey PI never
    predicts: the differences are the noise's.  (With the predictor active, CASE 1: 2.18,
    ratio 0.62 — at 3.5 times the noise-induced fuel command, test_sim_4_4_noise_sensitivity_alike.)"""
    step = 0.1 if case == 3 else 0.5  # CASE 3's noise is sampled every 0.1 s
    ratios = []
    for seed in SEEDS:
        pi = run(f"sim44_case{case}", "pi", 700.0, step, seed=seed)
        grey = run(f"sim44_case{case}", "grey", 700.0, step, seed=seed)
        after = pi["time"] >= 100.0
        ratios.append(np.max(np.abs(pressure_error(grey)[after])) / np.max(np.abs(pressure_error(pi)[after])))
        assert predicting(grey) == 0.0
    assert sum(ratio < 0.8 for ratio in ratios) == 0
    assert 0.9 < np.median(ratios) < 1.1


def pulse_merits(controller: str, form: str) -> tuple[float, float, float]:
    """Sim. 4.4 CASE 1's first pulse period (100-700 s): peak |e_P| and fuel range without noise, std of the
    noise-induced fuel command (docs/btg_sensitivity_report.py's figures of merit D and N)."""
    noisy = run("sim44_case1", controller, 700.0, form=form)
    clean = run("sim44_case1", controller, 700.0, noise=False, form=form)
    fuel = FUEL[controller]
    return (float(np.max(np.abs(pressure_error(clean)))), float(np.ptp(np.clip(clean[fuel], 0.0, 100.0))),
            float(np.std(noisy[fuel] - clean[fuel])))


@pytest.mark.parametrize("form, disturbance, noise", [("thesis", False, True), ("thesis always", True, False)])
def test_sensitivity_study_corners_trade_the_disturbance_claim_against_the_noise_claim(form, disturbance, noise):
    """The thesis's claims D (Sim. 4.3: smaller pressure error with less fuel action) and N (Sim. 4.4: the grey PI's
    noise sensitivity about the PI's) at two corners of docs/btg_sensitivity_tables.md, the thesis's PI form:
    as printed (a > 0.035, B = 50, m = 5) the grey PI almost never predicts under the pulse, so N holds (noise std
    ratio 0.98) and D does not (peak ratio 1.01, fuel range 1.03); predicting always (|a| > 0) D holds (0.64, 0.81)
    and N fails (3.9).  The study finds no setting of a_min, B, m and the threshold where S, D and N all hold."""
    pi_peak, pi_range, pi_noise = pulse_merits("pi", "thesis")
    peak, fuel_range, noise_std = pulse_merits("grey", form)
    assert (peak <= 0.8 * pi_peak and fuel_range < pi_range) is disturbance
    assert (0.8 <= noise_std / pi_noise <= 1.2) is noise
