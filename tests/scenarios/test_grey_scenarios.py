"""The grey scenarios (ssp/grey_*) run by the master on the real FMUs: thesis 000_* §3.1.5-§3.2, paper 002_*."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.present.metrics import step_metrics
from greyfmu.grey.ago import ago
from greyfmu.grey.gm11 import gm11_coefficients

EXAMPLE_3_1 = np.array([590.227, 615.369, 591.63, 651.777, 677.115, 699.870, 704.298, 695.565, 749.658, 816.966,
                        788.533, 799.5])
"""e0 of Example 3.1 (Fig. 3.1(a))."""
NOISE_SEEDS = (23341, *range(1, 20)) if os.environ.get("GREYFMU_SEEDS") == "full" else (23341, 1, 2)
"""(3.27c)'s seed and more: all 20 with GREYFMU_SEEDS=full (docs/grey.md gives the 20-seed numbers)."""


def noise_run(seed: int, *sets: str) -> np.ndarray:
    """ssp/grey_noise with the noise seed replaced and parameter sets of the scenario added."""
    with tempfile.TemporaryDirectory() as folder:
        seed_set = Path(folder) / "seed.ssv"
        seed_set.write_text(
            '<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
            'SystemStructureParameterValues" version="1.0" name="seed"><ssv:Parameters><ssv:Parameter '
            f'name="noise.seed"><ssv:Integer value="{seed}"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>\n')
        return cosim.simulate("ssp/grey_noise", parameter_sets=[*(f"ssp/grey_noise/{name}" for name in sets), seed_set])


def settled_spread(r: np.ndarray, predictor: str) -> float:
    """Spread of a predictor's 20 s prediction about the process output after settling (t > 550 s)."""
    settled = r["time"] > 550
    return float(np.std(r[f"{predictor}.x_hat"][settled] - r["process.y"][settled]))


def crossing(time: np.ndarray, x: np.ndarray, level: float, after: float, rising: bool = True) -> float:
    """First time at or after ``after`` that x reaches ``level``."""
    keep = time >= after
    hits = np.flatnonzero(x[keep] >= level if rising else x[keep] <= level)
    return float(time[keep][hits[0]]) if hits.size else float("nan")


def lead(result: np.ndarray, level: float, after: float, rising: bool = True) -> float:
    t = result["time"]
    return crossing(t, result["process.y"], level, after, rising) - crossing(t, result["predictor.x_hat"], level, after, rising)


def test_figure_3_1_ago_lowers_the_scatter_about_the_model_not_the_standard_deviation():
    """Fig. 3.1, Example 3.1: "compared with e0, the standard deviation of e1 is reduced".  Two readings.  Literally:
    NOT REPRODUCED, the AGO sums grow, std(e1) = 2558 against std(e0) = 78.4 (the coefficient of variation 0.60
    against 0.11).  As the scatter about the GM(1,1) model relative to the sequence (Theorem 3.1's point: e1 is close
    to a first-order exponential): REPRODUCED, 0.54 % for e1 against 3.0 % for e0 (the model's IAGO)."""
    e1 = ago(EXAMPLE_3_1)
    k = np.arange(EXAMPLE_3_1.size)
    assert np.std(e1, ddof=1) > 30 * np.std(EXAMPLE_3_1, ddof=1)
    a, b = gm11_coefficients(EXAMPLE_3_1)
    e1_model = (EXAMPLE_3_1[0] - b / a) * np.exp(-a * k) + b / a  # (3.6) over the window
    e0_model = np.diff(e1_model)
    scatter_e1 = np.std((e1 - e1_model) / e1_model)
    scatter_e0 = np.std((EXAMPLE_3_1[1:] - e0_model) / e0_model)
    assert scatter_e1 == pytest.approx(0.0054, abs=5e-4) and scatter_e0 == pytest.approx(0.030, abs=2e-3)
    assert scatter_e1 < scatter_e0 / 5


@pytest.mark.parametrize("case, overshoot", [("", False), ("ph30.ssv", False), ("ph40.ssv", True)])
def test_simulation_3_3_first_order_prediction(case, overshoot):
    """Simulation 3.3, Figs. 3.4-3.6: the prediction leads 1/(40s+1) by more on the rise than on the fall (the
    thesis: about 34 s and 26 s at ph = 20 s; ours at 70 % of the step: 32 s and 25 s), and at ph = 40 s it
    overshoots on the rise only (Corollary 3.2: r > 1 rising, r < 1 falling)."""
    r = cosim.simulate("ssp/grey_sim33", parameter_sets=[f"ssp/grey_sim33/{case}"] if case else [])
    t, x_hat = r["time"], r["predictor.x_hat"]
    up, down = lead(r, 2.7, 250), lead(r, 2.3, 470, rising=False)
    assert 20 <= up and 20 <= down and up > down
    rise = x_hat[(t > 250) & (t < 470)].max()
    assert bool(rise > 3.1) == overshoot
    assert x_hat[t > 470].min() > 1.99  # no overshoot on the way down
    assert abs(r["predictor.a"][t == 240][0]) < 1e-3 and abs(r["predictor.a"][t == 252][0]) > 1.0 / 40 / 10


@pytest.mark.parametrize("case, start, lead_up", [("", 320, 36), ("case2.ssv", 600, 24)])
def test_simulation_3_4_second_order_prediction(case, start, lead_up):
    """Simulation 3.4, Figs. 3.7/3.8: real (ph = 40 s) and complex (ph = 30 s) poles; the prediction leads the
    process at mid-step, by more on the rise than on the fall."""
    r = cosim.simulate("ssp/grey_sim34", parameter_sets=[f"ssp/grey_sim34/{case}"] if case else [])
    up = lead(r, 2.5, start)
    down = lead(r, 2.5, start + (220 if not case else 400), rising=False)
    assert up == pytest.approx(lead_up, abs=2) and 0 < down < up


def test_simulations_3_5_to_3_7_noise_sensitivity():
    """Figs. 3.9-3.11: with Ts = 1 s, n = 4 the prediction amplifies the filtered noise (3.27c); Ts = 5 s and
    LDISPI (Ts = 1 s, m = 5) reduce it alike, LDISPI answering the step earlier than Ts = 5 s."""
    r = cosim.simulate("ssp/grey_noise")
    t, y = r["time"], r["process.y"]
    assert np.all(r["measurement.y"][t < 300] == y[t < 300])  # (3.27c): the noise is added from t = 300 s
    assert np.std(r["measurement.y"][t > 550] - y[t > 550]) > 0.01
    settled = t > 550
    spread = {name: np.std(r[f"{name}.x_hat"][settled] - y[settled]) for name in ("grey_1s", "grey_5s", "ldispi")}
    noise = np.std(r["measurement.y"][settled] - y[settled])
    assert spread["grey_1s"] > 5 * noise
    assert spread["grey_1s"] > 2 * spread["ldispi"] and spread["grey_1s"] > 2 * spread["grey_5s"]
    assert crossing(t, r["ldispi.x_hat"], 0.5, 320) < crossing(t, r["grey_5s.x_hat"], 0.5, 320) < crossing(t, y, 0.5, 320)
    assert crossing(t, r["grey_1s.x_hat"], 0.5, 320) < crossing(t, r["ldispi.x_hat"], 0.5, 320)  # "somewhat lower speed"


def test_method_1_n_15_is_as_quiet_as_methods_2_and_3():
    """§3.1.6 Method 1: "We can increase n = 4 to n = 15, then we can have satisfactory prediction" (n15.ssv: grey_1s,
    Ts = 1 s, with n = 15).  REPRODUCED: the spread falls from 0.128 (n = 4) to 0.049 at (3.27c)'s seed, below
    Ts = 5 s (0.052) and LDISPI (0.052).  Over 20 seeds: median 0.043 (max 0.055) against n = 4's 0.120 (min 0.110),
    below both Methods 2 and 3 in 18 of 20 (seeds 11 and 17: within 0.5 % and 8 % of Ts = 5 s).  The price is speed:
    at (3.27c)'s seed n = 15 crosses 0.5 at 336 s, LDISPI at 328 s, n = 4 at 325 s."""
    held = 0
    for seed in NOISE_SEEDS:
        r = noise_run(seed, "n15.ssv")
        spread = settled_spread(r, "grey_1s")
        assert spread < 0.06  # n = 4: 0.110-0.136 over the 20 seeds
        held += spread < min(settled_spread(r, "grey_5s"), settled_spread(r, "ldispi"))
        if seed == 23341:
            assert spread == pytest.approx(0.0485, abs=1e-3)
            assert crossing(r["time"], r["grey_1s.x_hat"], 0.5, 320) > crossing(r["time"], r["ldispi.x_hat"], 0.5, 320)
    assert held == (18 if len(NOISE_SEEDS) == 20 else len(NOISE_SEEDS))


@pytest.fixture(scope="module")
def pi_vs_grey():
    return cosim.simulate("ssp/grey_pi_vs_pi")


def test_grey_pi_and_pi_reach_the_setpoint_without_offset(pi_vs_grey):
    """Theorem 3.5: the grey predictive PI settles at r like the PI (mean over 300-400 s, before the load pulse)."""
    r = pi_vs_grey
    quiet = (r["time"] > 300) & (r["time"] < 400)
    for plant in ("pi_plant", "grey_plant"):
        assert np.mean(r[f"{plant}.y"][quiet]) == pytest.approx(1.0, abs=5e-3)


def test_grey_pi_versus_pi_metrics(pi_vs_grey):
    """Same Kc/Ti: the grey PI rises faster with a smaller IAE and a larger overshoot; its output is as noisy
    as the PI's (the thesis's §4.4 claim: a properly designed grey PI has about PI's noise sensitivity)."""
    r = pi_vs_grey
    t, quiet = r["time"], (r["time"] > 250) & (r["time"] < 400)
    pi = step_metrics(t, r["pi_plant.y"], r["setpoint.y"], t0=20, t1=400, band=0.05)
    grey = step_metrics(t, r["grey_plant.y"], r["setpoint.y"], t0=20, t1=400, band=0.05)
    assert grey["rise_time"] < 0.6 * pi["rise_time"] and grey["IAE"] < pi["IAE"]
    assert grey["overshoot"] > pi["overshoot"]
    assert np.std(r["grey_pi.u"][quiet]) < 1.2 * np.std(r["pi.u"][quiet])
    assert set(np.unique(r["grey_pi.mode"])) <= {0.0, 1.0, 2.0}


def test_grey_pi_with_the_printed_signed_threshold_loses_the_faster_rise(pi_vs_grey):
    """§4.2's rule as printed (a > a_min: predict only while the biased error decays): the rising error of the
    set-point step is never predicted and the grey PI rises slower than the PI (measured 29.5 s against 13.9 s)."""
    signed = cosim.simulate("ssp/grey_pi_vs_pi", parameter_sets=["ssp/grey_pi_vs_pi/signed.ssv"])
    t = signed["time"]
    pi = step_metrics(t, pi_vs_grey["pi_plant.y"], pi_vs_grey["setpoint.y"], t0=20, t1=400, band=0.05)
    grey = step_metrics(t, signed["grey_plant.y"], signed["setpoint.y"], t0=20, t1=400, band=0.05)
    assert grey["rise_time"] > 1.5 * pi["rise_time"]


def test_simulation_3_6_too_large_a_sample_interval_worsens_control(pi_vs_grey):
    """Sim. 3.6: "it may worsen control quality to increase the sample interval too much".  REPRODUCED in both readings.
    The predictor's data interval alone (PI at 1 s): m·Ts = 5 s gives IAE 11.5 and rise 6.4 s, 20 s
    (data_interval_20s.ssv) IAE 22.7 and rise 13.9 s, worse than the PI (14.5, 13.9 s).  The whole grey PI at 10 s
    with m = 1 (sample_10s.ssv, Method 2 in the loop): IAE 210, never settles, where the PI at 10 s settles
    (IAE 21.0)."""
    def metrics(r: np.ndarray, plant: str) -> dict[str, float]:
        return step_metrics(r["time"], r[f"{plant}.y"], r["setpoint.y"], t0=20, t1=400, band=0.05)
    base, pi = metrics(pi_vs_grey, "grey_plant"), metrics(pi_vs_grey, "pi_plant")
    wide = metrics(cosim.simulate("ssp/grey_pi_vs_pi", parameter_sets=["ssp/grey_pi_vs_pi/data_interval_20s.ssv"]),
                   "grey_plant")
    assert wide["IAE"] > 1.5 * base["IAE"] and wide["IAE"] > pi["IAE"]
    assert wide["rise_time"] > 2 * base["rise_time"]
    slow = cosim.simulate("ssp/grey_pi_vs_pi", parameter_sets=["ssp/grey_pi_vs_pi/sample_10s.ssv"])
    slow_pi, slow_grey = metrics(slow, "pi_plant"), metrics(slow, "grey_plant")
    assert np.isfinite(slow_pi["settling_time"]) and not np.isfinite(slow_grey["settling_time"])
    assert slow_grey["IAE"] > 5 * slow_pi["IAE"]


def test_figure_3_12_basic_scheme_no_overshoot_but_slow():
    """Fig. 3.12 (the PI acts on the GM(1,1) prediction of y): "for setpoint tracking, usually no overshoot exists";
    "the shortcoming ... is that tracking speed for setpoint may be too slow".  REPRODUCED (measured: overshoot 0 %
    against the PI's 6.1 %, rise time 39.7 s against 14.1 s; the error-prediction grey PI of Fig. 3.14 rises in
    6.4 s with 21.9 %)."""
    r = cosim.simulate("ssp/grey_fig312")
    t = r["time"]
    m = {plant: step_metrics(t, r[f"{plant}.y"], r["setpoint.y"], t0=20, t1=400)
         for plant in ("pi_plant", "out_plant", "grey_plant")}
    assert m["out_plant"]["overshoot"] < 1.0 < m["pi_plant"]["overshoot"]
    assert m["out_plant"]["rise_time"] > 2 * m["pi_plant"]["rise_time"] > 4 * m["grey_plant"]["rise_time"]
    assert np.mean(r["out_plant.y"][(t > 300) & (t < 400)]) == pytest.approx(1.0, abs=1e-3)  # no offset


@pytest.mark.parametrize("case, ks, wn, zeta", [("", 2.0, 0.1, 0.5), ("overdamped.ssv", 0.5, 0.05, 2.0)])
def test_gm3t1_identification_scenario(case, ks, wn, zeta):
    """GM(3/t,1) (002_* (4), (12)-(16)) on the simulated step response at ω_n·Ts = 0.05 and 0.025: k_s within 2 %,
    ω_n and ζ within 10 % (measured: −0.2 %, −1.2 %, −4.1 % under-damped; −0.1 %, −2.4 %, −2.9 % over-damped)."""
    r = cosim.simulate("ssp/grey_gm3t1", parameter_sets=[f"ssp/grey_gm3t1/{case}"] if case else [])
    assert r["identifier.valid"][0] == 0.0 and r["identifier.valid"][-1] == 1.0
    assert r["identifier.ks"][-1] == pytest.approx(ks, rel=0.02)
    assert r["identifier.wn"][-1] == pytest.approx(wn, rel=0.10)
    assert r["identifier.zeta"][-1] == pytest.approx(zeta, rel=0.10)
