"""Thesis 000_*, ch. 4: the boiler-following scheme of Figure 4.1 (ssp/btg_boiler_following) through cosim.

Each test names the simulation whose claim it checks.  Where our reproduction disagrees with
the thesis the test asserts what we measure (and says so); docs/btg.md gives the numbers and
the reason.  Runs are shortened to what a claim needs (one pulse period instead of three,
1200 s instead of 1500 s of load following); docs/btg_report.py runs the full cases.
"""

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import cosim
from greyfmu.plants.boiler_turbine import equilibrium

SCENARIO = Path(__file__).resolve().parents[2] / "ssp" / "btg_boiler_following"
FUEL = {"pi": "fuel_pi.u", "grey": "fuel_grey.u"}
LEVEL_SETPOINT_MODEL_MM = 100.0
"""The thesis's -100 mm set-point on the level datum of the scenario (README: model level - 200 mm)."""


@lru_cache(maxsize=None)
def run(case: str, controller: str, stop: float, step: float = 0.5, noise: bool = True) -> np.ndarray:
    sets = [SCENARIO / f"{case}.ssv", SCENARIO / f"{controller}.ssv"]
    if not noise:
        sets.append(SCENARIO / "noise_free.ssv")
    return cosim.simulate(SCENARIO, stop_time=stop, step_size=step, parameter_sets=sets)


def pressure_error(r: np.ndarray) -> np.ndarray:
    return r["pressure_sp.y"] - r["plant.P"]


def settled(r: np.ndarray, window: float = 300.0) -> bool:
    """Bounded throughout and, over the last `window` seconds, within 2 kgf/cm2 and 2 MW of the set-points."""
    tail = r["time"] >= r["time"][-1] - window
    e_p, e_e = pressure_error(r), r["demand.y"] - r["plant.E"]
    bounded = np.all(np.isfinite(e_p)) and np.max(np.abs(e_p)) < 50 and np.max(np.abs(e_e)) < 50
    return bool(bounded and np.max(np.abs(e_p[tail])) < 2.0 and np.max(np.abs(e_e[tail])) < 2.0)


def overshoot(r: np.ndarray) -> float:
    return float(100 * (np.max(r["plant.P"] - r["plant.P"][0]) / r["sp_step.y"][-1] - 1))


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


@pytest.mark.parametrize("load", [58, 76, 101])
def test_sim_4_1_grey_pi_and_pi_step_responses_alike(load):
    """Sim. 4.1 (Figures 4.5-4.7): overshoots of the pressure step within 2 percentage points. HOLDS.

    Both are 12-16 %, above the thesis's 10 % design criterion (docs/btg.md)."""
    pi, grey = run(f"sim41_{load}", "pi", 800.0), run(f"sim41_{load}", "grey", 800.0)
    assert abs(overshoot(grey) - overshoot(pi)) < 2.0
    assert 10.0 < overshoot(pi) < 17.0
    assert settled(pi) and settled(grey)


@pytest.mark.parametrize("case", [5, 6, 7, 8, 9, 10])
def test_sim_4_2_fast_ramps_pi_stays_stable_here(case):
    """Sim. 4.2 CASES 5-10: the thesis's PI goes unstable, its grey PI stays stable.  NOT REPRODUCED:
    here both settle (the rate-limited fuel valve saturates for a while, then both recover) and their
    peak pressure errors differ by less than 1 kgf/cm2; the grey predictor predicts in under 10 % of
    the samples of these 1200 s runs (|a| > a_min rarely holds with B = 50)."""
    pi, grey = run(f"sim42_case{case}", "pi", 1200.0), run(f"sim42_case{case}", "grey", 1200.0)
    assert settled(pi) and settled(grey)
    assert abs(np.max(np.abs(pressure_error(pi))) - np.max(np.abs(pressure_error(grey)))) < 1.0
    assert np.mean(grey["fuel_grey.mode"] == 2) < 0.10


def test_sim_4_3_case_1_pulse_rejection_equal_not_a_third():
    """Sim. 4.3 CASE 1 (26 % fuel pulse): the thesis's grey PI has about 1/3 of PI's pressure error with a
    smaller fuel command.  NOT REPRODUCED: the peak errors and the fuel command ranges agree within 10 %,
    because the grey PI never predicts here (mode 2 in no sample).  Master step 0.1 s = the noise's sample time."""
    pi, grey = run("sim43_case1", "pi", 700.0, 0.1), run("sim43_case1", "grey", 700.0, 0.1)
    ratio = np.max(np.abs(pressure_error(grey))) / np.max(np.abs(pressure_error(pi)))
    assert 0.9 < ratio < 1.1
    assert 0.9 < np.ptp(grey[FUEL["grey"]]) / np.ptp(pi[FUEL["pi"]]) < 1.1
    assert not np.any(grey["fuel_grey.mode"] == 2)


@pytest.mark.parametrize("case", [1, 2])
def test_sim_4_4_noise_sensitivity_within_20_percent(case):
    """Sim. 4.4 CASES 1-2 (white noise on the pressure): the variance of the fuel command's noise-induced
    part (noisy minus noise-free run) of the grey PI is within 20 % of the PI's. HOLDS."""
    share = {}
    for controller in ("pi", "grey"):
        noisy = run(f"sim44_case{case}", controller, 700.0)
        clean = run(f"sim44_case{case}", controller, 700.0, noise=False)
        share[controller] = np.var(noisy[FUEL[controller]] - clean[FUEL[controller]])
    assert 0.8 < share["grey"] / share["pi"] < 1.2
