"""Simulations 2.1-2.5 of the thesis (§2.3) run as SSP scenarios through cosim on the real FMUs.

Each test names the figure whose conclusion it checks.  The thesis gives neither the set-point
values nor the disturbance sizes; the scenarios' README.md files say what we chose.  Where a
conclusion of the chapter does not hold here, the test asserts what we see and says so.
"""

import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import cosim
from cosim.present.metrics import step_metrics

SSP = Path(__file__).resolve().parents[2] / "ssp"
CASES = (1, 2, 3)
LAWS = ("itae", "mfgs", "fgs1", "fgs2")


@lru_cache(maxsize=None)
def run(simulation: str, *sets: str, stop_time: float) -> np.ndarray:
    folder = SSP / simulation
    return cosim.simulate(folder, stop_time=stop_time, parameter_sets=[folder / f"{name}.ssv" for name in sets])


def setpoint_metrics(simulation: str, *sets: str, stop_time: float = 400.0) -> dict[str, float]:
    result = run(simulation, *sets, stop_time=stop_time)
    return step_metrics(result["time"], result["plant.y"], result["setpoint.y"], t0=10.0)


def direction_metrics(simulation: str, case: int, mirrored: bool, down: bool) -> dict[str, dict[str, float]]:
    """Set-point metrics of every law for a case of Sims. 2.3-2.5 in one of the four directions the text discusses:
    the parameter rising with y or `mirrored` (p(7.76 - y), table swapped), set-point 1 → 4 or `down` 4 → 1."""
    sets = [f"mirrored_case{case}" if mirrored else f"case{case}"]
    if down:
        sets.append("down" if simulation != "gs_sim2_3" else f"{'mirrored_' if mirrored else ''}down_case{case}")
    return {law: setpoint_metrics(simulation, *sets, law) for law in LAWS}


def load_iae(simulation: str, *sets: str, start: float, end: float) -> float:
    """IAE of y against the set-point over [start, end] (the load steps of Sims. 2.3-2.5 come at 400 and 800 s)."""
    result = run(simulation, *sets, stop_time=1200.0)
    t, e = result["time"], result["setpoint.y"] - result["plant.y"]
    window = (t >= start) & (t <= end)
    return float(np.sum(np.abs(e[window])) * 0.1)


@pytest.mark.parametrize("name", ["GainScheduledPID", "ScheduledFOPDT"])
def test_fmus_validate_and_declare_units(built_fmus, name):
    assert validate_fmu(str(built_fmus[name])) == []
    md = read_model_description(str(built_fmus[name]))
    units = {v.name: v.unit for v in md.modelVariables}
    assert "Requires Python 3.10+ with numpy and scipy" in md.description
    assert all(v.description for v in md.modelVariables)
    if name == "GainScheduledPID":
        seconds = {"Ts", "Ti", "Td", "T", "tau"} | {f"{p}_{i}" for p in ("Ti", "Td") for i in range(1, 9)}
    else:
        seconds = {"T", "tau", "D", "dt"} | {f"{p}_{k}" for p in ("T", "tau") for k in ("lo", "hi", "a")}
    assert {n for n, unit in units.items() if unit == "s"} == seconds
    assert all(not u.dependencies for u in md.outputs)  # no direct feedthrough


def test_unsorted_table_is_refused_naming_the_parameter(tmp_path):
    bad = tmp_path / "bad.ssv"
    bad.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" '
        'name="bad"><ssv:Parameters><ssv:Parameter name="controller.W_2"><ssv:Real value="0.5"/></ssv:Parameter>'
        "</ssv:Parameters></ssv:ParameterSet>\n"
    )
    with pytest.raises(cosim.RunError, match="W_2 = 0.5 does not exceed W_1 = 0.76"):
        cosim.simulate(SSP / "gs_sim2_3", stop_time=1.0, parameter_sets=[bad])


def test_scheduled_gains_are_recorded_for_the_figure_2_3_curves():
    """Figure 2.3(b) from a run: the Kc output is MFGS's Kc at the output y one sample earlier (Jacobi, Ts = h)."""
    result = run("gs_sim2_3", "case2", "mfgs", stop_time=400.0)
    # (2.9b) written out: 1/Kc linear in y between the operating points (0.76, 1.4805) and (7.0, 0.1185), held outside.
    expected = 1.0 / np.interp(result["plant.y"][:-1], [0.76, 7.0], [1.0 / 1.4805, 1.0 / 0.1185])
    np.testing.assert_allclose(result["controller.Kc"][1:], expected, rtol=1e-12)
    assert np.ptp(expected) > 0.5  # the run crosses enough of the table for the law to matter
    itae = run("gs_sim2_3", "case2", "itae", stop_time=400.0)
    np.testing.assert_allclose(itae["controller.Kc"][1:], 0.2961 / itae["plant.Kp"][:-1], rtol=1e-3)


@pytest.mark.parametrize("law", ["mfgs", "fgs1", "fgs2"])
def test_scheduled_ti_and_td_follow_their_law_where_the_table_changes_them(law):
    """Figures 2.10(b),(c): in Sim. 2.5 the table changes all three gains, (0.76: 8.0346, 7.1713, 1.5363) to
    (7: 1.75, 23.52, 7.62), so Ti and Td show the law too (in Sim. 2.3 only Kc moves).  The recorded Kc, Ti, Td
    against (2.6), (2.7), (2.9) written out with numpy.interp on the output one sample earlier: MFGS 1/Kc, Ti, Td
    linear; FGS2 Kc, Ti, Td linear; FGS1 Kc, Kc/Ti and Kc·Td linear."""
    result = run("gs_sim2_5", "case1", law, stop_time=400.0)
    y = result["plant.y"][:-1]
    ends, kc, ti, td = [0.76, 7.0], [8.0346, 1.75], [7.1713, 23.52], [1.5363, 7.62]
    def linear(values):
        return np.interp(y, ends, values)
    Kc = 1.0 / linear([1.0 / k for k in kc]) if law == "mfgs" else linear(kc)
    if law == "fgs1":
        Ti = Kc / linear([k / t for k, t in zip(kc, ti)])
        Td = linear([k * d for k, d in zip(kc, td)]) / Kc
    else:
        Ti, Td = linear(ti), linear(td)
    for name, expected in (("Kc", Kc), ("Ti", Ti), ("Td", Td)):
        np.testing.assert_allclose(result[f"controller.{name}"][1:], expected, rtol=1e-12, err_msg=name)
    assert np.ptp(Ti) > 3.0  # the run crosses enough of the table for Ti's law to matter (FGS1: 7.2 … 11.0 s)


# --- Simulation 2.1 (Figure 2.1): process gain varies, Kc = 1.6069/Kp(y) -------------------------------------


def test_sim_2_1_integral_mode_2_10_overshoots_when_the_gain_grows():
    """Figure 2.1(a): with (2.10) the overshoot is "unacceptable compared with its response at y < 0.76";
    (2.11) and (2.12) offset the gain change by rescaling the integral output."""
    low = {m: setpoint_metrics("gs_sim2_1", "step_low", f"mode{m}", stop_time=300.0) for m in (1, 2, 3)}
    up = {m: setpoint_metrics("gs_sim2_1", "step_up", f"mode{m}", stop_time=300.0) for m in (1, 2, 3)}
    # Below y = 0.76 the gains are constant and the three modes are one controller.
    assert low[1]["IAE"] == pytest.approx(low[3]["IAE"], rel=1e-9) == pytest.approx(low[2]["IAE"], rel=1e-9)
    # The thesis states an overshoot below 20 % there; ours is 33 % (discrete PID, derivative on y, see pid_fopdt).
    assert low[1]["overshoot"] == pytest.approx(33.2, abs=1.0)
    # With Ti constant, (2.11) and (2.12) rescale the integral identically.
    assert up[2]["IAE"] == pytest.approx(up[3]["IAE"], rel=1e-9)
    assert up[3]["overshoot"] == pytest.approx(low[3]["overshoot"], abs=2.0)  # Kc·Kp constant: same response
    assert up[1]["overshoot"] > 10 * up[3]["overshoot"] and up[1]["overshoot"] > 100.0


def test_sim_2_1_below_20_percent_not_reached_with_either_derivative_form():
    """Sim. 2.1: "its response at y < 0.76 (overshoot is less than 20%)".  NOT REPRODUCED with either derivative
    form: ours (on the measurement) 33.7 %, the thesis's Td·de/dt of (2.6a) (derivative_error.ssv) 28.9 %:
    the derivative form explains 4.8 of the 13.7 points."""
    ours = setpoint_metrics("gs_sim2_1", "step_low", "mode3", stop_time=300.0)
    thesis = setpoint_metrics("gs_sim2_1", "step_low", "mode3", "derivative_error", stop_time=300.0)
    assert ours["overshoot"] == pytest.approx(33.7, abs=0.5)
    assert thesis["overshoot"] == pytest.approx(28.9, abs=0.5)
    assert thesis["overshoot"] > 20.0


def test_sim_2_1_reversed_gain_mode_2_10_is_the_more_damped():
    """Sim. 2.1: "If we have Kp(y) increase as y decreases, PID with the integral mode (2.10) will have a greatly
    over damped step response."  Under the thesis's condition, Kp FALLING along the step (kp_falling.ssv: Kp(y)
    mirrored, step 0.5 → 4, Kp 2.5 → 1.74; as Sim. 2.2's tau_falling.ssv mirrors τ(y) and keeps the step):
    (2.10) is the more damped one, overshoot 14.6 % against 33.6 % of (2.11) = (2.12), settling 42.8 s against
    72.4 s — REPRODUCED in direction; "greatly over damped" is NOT: its rise time 9.2 s is that of (2.11)/(2.12),
    8.8 s.  The integral (2.10) accumulated at the small initial Kc is too small for the larger final Kc."""
    m = {k: setpoint_metrics("gs_sim2_1", f"mode{k}", "kp_falling", stop_time=300.0) for k in (1, 2, 3)}
    assert m[1]["overshoot"] < 0.6 * m[3]["overshoot"] and m[1]["settling_time"] < m[3]["settling_time"]
    assert m[3]["overshoot"] == pytest.approx(33.6, abs=0.5) and m[2]["IAE"] == pytest.approx(m[3]["IAE"], rel=1e-9)
    assert m[1]["rise_time"] < 1.5 * m[3]["rise_time"]  # not "greatly over damped"


def one_value(folder: Path, name: str, value: float) -> Path:
    """A parameter set in `folder` giving the Real `name` (component.variable) the value `value`."""
    path = folder / "value.ssv"
    path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
                    'SystemStructureParameterValues" version="1.0" name="value"><ssv:Parameters><ssv:Parameter '
                    f'name="{name}"><ssv:Real value="{value!r}"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>\n')
    return path


def sim_2_1_to(target: float, *sets: str, stop_time: float) -> dict[str, float]:
    """Sim. 2.1's set-point step 0.5 → target (the thesis gives none; docs/gain_scheduling_ranges_tables.md)."""
    folder = SSP / "gs_sim2_1"
    with tempfile.TemporaryDirectory() as temp:
        end = one_value(Path(temp), "setpoint.final", target)
        r = cosim.simulate(folder, stop_time=stop_time, parameter_sets=[*(folder / f"{n}.ssv" for n in sets), end])
    return step_metrics(r["time"], r["plant.y"], r["setpoint.y"], t0=10.0)


def test_sim_2_1_reversed_holds_away_from_the_end_of_the_gain_table():
    """Sim. 2.1 reversed over the step's end point y_f (docs/gain_scheduling_ranges_tables.md, 12 end points from 1 to
    10, 1000 s runs): (2.10) is the most damped mode and settles for y_f ≤ 6.5 and y_f ≥ 7.5, but for a step into the
    table's end, y_f = 6.9 and 7 (Kp(y) = sqrt(7.04 − y) bends to 0.2 at y = 7), it has not settled into ±2 % by 1000 s
    while (2.12) settles in 74 s.  The claim's range: steps that stay clear of y = 7.  Here: y_f = 6 holds (1.9 % /
    17 s against 32.6 % / 74 s), y_f = 7 does not."""
    near, at_end = (sim_2_1_to(target, "mode1", "kp_falling", stop_time=1000.0) for target in (6.0, 7.0))
    reference = {target: sim_2_1_to(target, "mode3", "kp_falling", stop_time=300.0) for target in (6.0, 7.0)}
    assert near["overshoot"] < 0.2 * reference[6.0]["overshoot"] and near["settling_time"] < reference[6.0]["settling_time"]
    assert np.isnan(at_end["settling_time"]) and reference[7.0]["settling_time"] < 100.0


# --- Simulation 2.2 (Figure 2.2): dead time varies, ITAE gains of tau(y(t - D)) -------------------------------


@pytest.mark.parametrize("direction", ["step_up", "step_down"])
def test_sim_2_2_integral_modes_2_11_2_12_are_more_damped(direction):
    """Figure 2.2: (2.11) and (2.12) "have much over-damped step responses at both directions of y";
    (2.12) lies between (2.10) and (2.11) (the chapter's trade-off)."""
    m = {k: setpoint_metrics("gs_sim2_2", direction, f"mode{k}", stop_time=600.0) for k in (1, 2, 3)}
    assert m[2]["rise_time"] > m[3]["rise_time"] > m[1]["rise_time"]
    assert m[2]["overshoot"] <= m[1]["overshoot"] and m[3]["overshoot"] <= m[1]["overshoot"]


@pytest.mark.parametrize("direction, large", [("step_up", True), ("step_down", False)])
def test_sim_2_2_reversed_dead_time_modes_2_11_2_12_overshoot(direction, large):
    """Sim. 2.2: "If we have τ(y) decrease as y increases, PID with the integral mode (2.11) and (2.12) will have a
    step response with large over-shoot."  REPRODUCED for (2.11) on the rising step (tau_falling.ssv: τ 20 → 14.2 s):
    overshoot 268.7 % ((2.12) 16.8 %, (2.10) 0.6 %); on the falling step (τ grows) 7.0 / 4.0 / 0.3 %.  The order
    (2.11) > (2.12) > (2.10) holds in both directions."""
    m = {k: setpoint_metrics("gs_sim2_2", direction, f"mode{k}", "tau_falling", stop_time=600.0) for k in (1, 2, 3)}
    assert m[2]["overshoot"] > m[3]["overshoot"] > m[1]["overshoot"]
    assert bool(m[2]["overshoot"] > 100.0) is large


def test_sim_2_2_similar_for_time_constant_not_reproduced_the_direction_flips():
    """Sim. 2.2: "The similar responses can be observed for the variation of process time constant T(y)."  Sim. 2.2's
    τ(y) put on T (t_rising.ssv: T 4 → 20 s as y rises, τ = 4 s; t_falling.ssv: mirrored), ITAE gains on T(y).
    NOT REPRODUCED: the responses are the mirror image of Sim. 2.2's.  Kc ∝ T^0.947 grows with T where it fell with
    τ (τ^-0.947), so rescaling the integral output overshoots when T rises: step 0.5 → 4, (2.10) 9.5 %, (2.11)
    41.6 %, (2.12) 69.4 %; when T falls (2.10) overshoots most (42.9 % against 23.0 / 18.1 %).  No mode is
    over-damped in either direction (rise times 8.5-14.5 s)."""
    rising = {k: setpoint_metrics("gs_sim2_2", "step_up", f"mode{k}", "t_rising", stop_time=600.0) for k in (1, 2, 3)}
    falling = {k: setpoint_metrics("gs_sim2_2", "step_up", f"mode{k}", "t_falling", stop_time=600.0) for k in (1, 2, 3)}
    assert min(rising[2]["overshoot"], rising[3]["overshoot"]) > 3 * rising[1]["overshoot"]  # τ: 0 % against 52 %
    assert max(rising[2]["rise_time"], rising[3]["rise_time"]) < rising[1]["rise_time"]  # not over-damped
    assert falling[1]["overshoot"] > falling[2]["overshoot"] > falling[3]["overshoot"]  # τ falling: (2.11) 269 %
    assert falling[2]["overshoot"] < 30.0


def sim_2_2_variants() -> dict[str, tuple[str, ...]]:
    """The eight responses of Sim. 2.2's studies: τ(y) rising (the thesis's), τ falling, T(y) rising, T falling, each
    with the set-point step 0.5 → 4 and 4 → 0.5."""
    return {f"{label}, {step}": (step, *extra) for label, extra in (("τ rising", ()), ("τ falling", ("tau_falling",)),
                                                                      ("T rising", ("t_rising",)), ("T falling", ("t_falling",)))
            for step in ("step_up", "step_down")}


def best_and_worst_mode(*sets: str, simulation: str = "gs_sim2_2", stop_time: float = 600.0) -> tuple[int, int]:
    """The integral modes (1, 2, 3 = (2.10)-(2.12)) of smallest and largest set-point IAE."""
    iae = {k: setpoint_metrics(simulation, *sets[:1], f"mode{k}", *sets[1:], stop_time=stop_time)["IAE"] for k in (1, 2, 3)}
    return min(iae, key=iae.get), max(iae, key=iae.get)


def test_sim_2_2_time_constant_in_the_reading_mode_2_10_is_best_in_2_of_4():
    """Sim. 2.2's "the similar responses can be observed for the variation of process time constant T(y)", read by the
    thesis's own gloss (§2.3.2 (3), "if only process time constant or time delay changes, it is suggested to use the
    integral mode (2.10)"): (2.10) has the smallest IAE in 2 of the 4 T(y) responses — T rising, step up (48.2 against
    75.9 / 108.4) and T falling, step down (54.5 against 55.7 / 56.2, by 2 %) — and the largest in the other two.
    PARTLY REPRODUCED (2 of 4); in the mirrored reading (the test above) not reproduced."""
    best = {name: best_and_worst_mode(*sets)[0] for name, sets in sim_2_2_variants().items() if name.startswith("T ")}
    assert best == {"T rising, step_up": 1, "T rising, step_down": 3, "T falling, step_up": 3, "T falling, step_down": 1}


def test_ch5_mode_2_10_best_for_time_constant_and_dead_time_in_4_of_8_and_2_12_not_worst_in_7_of_10():
    """Ch. 5 (1): "for the variation of process time constant T and time delay τ, the integral mode (2.10) is the best
    selection"; "the integral mode (2.12) is a reasonable trade-off for general purposes" (§2.3.2: "the best trade-off
    solution").  Over Sim. 2.2's eight responses (τ and T rising or falling in y, steps up and down) (2.10) has the
    smallest set-point IAE in 4 (τ rising step down, τ falling step up, T rising step up, T falling step down): PARTLY
    REPRODUCED.  Adding Sim. 2.1's two gain responses (Kp rising and falling along the step 0.5 → 4), (2.12) is not
    the worst of the three modes in 7 of 10 (the worst with T rising step up, T falling step down and Kp falling,
    where it equals (2.11)): PARTLY REPRODUCED."""
    modes = {name: best_and_worst_mode(*sets) for name, sets in sim_2_2_variants().items()}
    assert sorted(name for name, (best, _) in modes.items() if best == 1) == [
        "T falling, step_down", "T rising, step_up", "τ falling, step_up", "τ rising, step_down"]
    modes["Kp rising"] = best_and_worst_mode("step_up", simulation="gs_sim2_1", stop_time=300.0)
    modes["Kp falling"] = best_and_worst_mode("kp_falling", simulation="gs_sim2_1", stop_time=300.0)
    assert sorted(name for name, (_, worst) in modes.items() if worst == 3) == [
        "Kp falling", "T falling, step_down", "T rising, step_up"]


# --- Simulations 2.3-2.5 (Figures 2.4, 2.6, 2.8, 2.11, 2.13): ITAE vs MFGS vs FGS1 vs FGS2 ----------------------


@pytest.mark.parametrize("case", CASES)
def test_sim_2_3_gain_varies_mfgs_overshoots_less_than_fgs(case):
    """Figure 2.4(a): FGS1 and FGS2 "have unacceptable over-shoots"; MFGS is the definite selection (§2.3.4, 1)."""
    m = {law: setpoint_metrics("gs_sim2_3", f"case{case}", law) for law in ("mfgs", "fgs1", "fgs2")}
    assert m["fgs1"] == m["fgs2"]  # Ti and Td are the same at both points: (2.6) and (2.7) coincide
    assert m["mfgs"]["overshoot"] < m["fgs1"]["overshoot"] - 25.0


def test_sim_2_3_disturbance_rejection_is_not_worse_with_fgs_here():
    """Figure 2.4(b),(c) say FGS1/FGS2 reject the ±d steps worse than MFGS.  Here (d = 0.5 at y = 4) the larger
    FGS gain rejects them with a smaller IAE and peak: we record this (CASE 1) rather than tune towards it."""
    iae = {(law, start): load_iae("gs_sim2_3", "case1", law, start=start, end=start + 400.0)
           for law in ("mfgs", "fgs1") for start in (400.0, 800.0)}
    for start in (400.0, 800.0):
        assert iae["fgs1", start] < iae["mfgs", start]


@pytest.mark.parametrize("case", CASES)
def test_sim_2_4_time_constant_varies_fgs_settle_faster_than_mfgs(case):
    """Figures 2.6, 2.8: FGS1 and FGS2 are the better selection; MFGS is more damped (§2.3.4, 2)."""
    m = {law: setpoint_metrics("gs_sim2_4", f"case{case}", law) for law in ("mfgs", "fgs1", "fgs2")}
    assert m["fgs1"]["settling_time"] < m["mfgs"]["settling_time"]
    assert m["fgs2"]["settling_time"] < m["mfgs"]["settling_time"]
    assert m["mfgs"]["overshoot"] < min(m["fgs1"]["overshoot"], m["fgs2"]["overshoot"])
    assert m["mfgs"]["rise_time"] > max(m["fgs1"]["rise_time"], m["fgs2"]["rise_time"])


@pytest.mark.parametrize("case", CASES)
def test_sim_2_4_fgs_reject_the_load_better_than_mfgs(case):
    """Sim. 2.4 and §2.3.4 (2): FGS1 and FGS2 achieve "slightly better disturbance rejection than MFGS, since Kc(y) in
    MFGS is too small".  REPRODUCED in direction in every case and for both load steps: IAE of +d (400-800 s) MFGS /
    FGS1 / FGS2 7.20 / 4.87 / 4.79 (CASE 1), 6.31 / 4.22 / 4.10 (CASE 2), 6.65 / 4.47 / 4.37 (CASE 3); the margin,
    a third of MFGS's IAE, is more than "slightly"."""
    for start in (400.0, 800.0):
        iae = {law: load_iae("gs_sim2_4", f"case{case}", law, start=start, end=start + 400.0)
               for law in ("mfgs", "fgs1", "fgs2")}
        assert max(iae["fgs1"], iae["fgs2"]) < 0.75 * iae["mfgs"]
        assert min(iae["fgs1"], iae["fgs2"]) > 0.6 * iae["mfgs"]


def test_sim_2_4_case_2_mfgs_disturbance_rejection_is_not_bad_in_neither_reading():
    """Sim. 2.4 CASE 2: "Certainly the disturbance rejection of MFGS in this case is not bad compared with ITAE, FGS1
    and FGS2" (after CASE 1's "comparatively worse disturbance rejection").  IAE of the +d step (400-800 s) MFGS / ITAE
    / FGS1 / FGS2: 6.31 / 4.58 / 4.22 / 4.10 (CASE 2), 7.20 / 4.09 / 4.87 / 4.79 (CASE 1).  Absolute reading ("not
    bad" = alike, within 10 %): MFGS 38-54 % worse, NOT REPRODUCED.  Relative reading (better than in CASE 1): MFGS's
    ratio to ITAE falls from 1.76 to 1.38, but to FGS1 and FGS2 it does not (1.48 → 1.50, 1.50 → 1.54): against ITAE
    only, 1 of 3.  NOT REPRODUCED in either reading."""
    iae = {(case, law): load_iae("gs_sim2_4", f"case{case}", law, start=400.0, end=800.0)
           for case in (1, 2) for law in LAWS}
    assert all(iae[2, "mfgs"] > 1.1 * iae[2, law] for law in ("itae", "fgs1", "fgs2"))
    improved = [iae[2, "mfgs"] / iae[2, law] < iae[1, "mfgs"] / iae[1, law] for law in ("itae", "fgs1", "fgs2")]
    assert improved == [True, False, False]


def test_time_constant_variation_matters_less_than_gain_and_dead_time():
    """§2.3.4 (2) / Sim. 2.4: "the variations of process time constants usually do influence control quality much less
    than the variation of process gains and time delays".  Read as how far the four gain laws (ITAE, MFGS, FGS1, FGS2)
    spread: the set-point overshoot spans 6.2 / 7.3 / 6.9 points in Sim. 2.4's CASES 1-3 (T varies) against 42.8 /
    49.5 / 47.0 in Sim. 2.3 (Kp) and 62.6 / 36.9 / 50.8 in Sim. 2.5 (τ): a seventh to a fifth.  REPRODUCED."""
    spread = {simulation: [np.ptp([setpoint_metrics(simulation, f"case{case}", law)["overshoot"] for law in LAWS])
                           for case in CASES] for simulation in ("gs_sim2_3", "gs_sim2_4", "gs_sim2_5")}
    assert max(spread["gs_sim2_4"]) < 10.0 < 30.0 < min(spread["gs_sim2_3"] + spread["gs_sim2_5"])


@pytest.mark.parametrize("case", CASES)
def test_sim_2_4_mfgs_is_not_over_damped(case):
    """Figures 2.6, 2.8: MFGS has a "greatly over-damped" (CASE 1) / "over-damped" (CASE 2) step response.
    NOT REPRODUCED: MFGS overshoots 37-39 % with our derivative and 30 % with the thesis's derivative on the error
    (derivative_error.ssv); every law overshoots here (ITAE 41-46 %).  What holds is "more damped than FGS1/FGS2"
    (test above)."""
    for extra in ((), ("derivative_error",)):
        assert setpoint_metrics("gs_sim2_4", f"case{case}", "mfgs", *extra)["overshoot"] > 25.0


@pytest.mark.parametrize("case", CASES)
def test_sim_2_5_dead_time_varies_overshoot_mfgs_fgs2_fgs1(case):
    """Figures 2.11, 2.13: "FGS1 has the largest over-shoot ..., FGS2 has larger ones, and MFGS has the least"."""
    m = {law: setpoint_metrics("gs_sim2_5", f"case{case}", law) for law in ("mfgs", "fgs1", "fgs2")}
    assert m["mfgs"]["overshoot"] <= m["fgs2"]["overshoot"] < m["fgs1"]["overshoot"]


@pytest.mark.parametrize("case, order_holds", [(1, True), (2, False), (3, False)])
def test_sim_2_5_settling_order_holds_in_case_1_only(case, order_holds):
    """Fig. 2.11: "FGS1 has the largest over-shoot and settling time, FGS2 has larger ones, and MFGS has the least".
    The settling part is NOT REPRODUCED in CASES 2 and 3: MFGS, without overshoot, settles last (131 / 129 s
    against FGS2's 82 / 93 s); in CASE 1 MFGS settles first (132 s; FGS2 149 s, FGS1 not within 400 s)."""
    m = {law: setpoint_metrics("gs_sim2_5", f"case{case}", law) for law in ("mfgs", "fgs2")}
    assert bool(m["mfgs"]["settling_time"] < m["fgs2"]["settling_time"]) is order_holds


def test_sim_2_5_case_3_between_cases_1_and_2_in_10_of_12():
    """Sim. 2.5 CASE 3 (τ linear): "the control qualities for MFGS, FGS1 and FGS2 should be between the corresponding
    control qualities in CASE 1 and CASE 2.  Still MFGS is expected to be the best, FGS2 is worse and FGS1 is the
    worst".  Set-point IAE, overshoot, settling (not settled = longest) and rise time of CASE 3 lie between CASES 1 and
    2 (inclusive; MFGS's rise time 19.8 s equals CASE 1's) in 10 of 12: all four for FGS1 and FGS2, not MFGS's IAE (68.4
    against 70.7 / 70.1) nor its settling (129.3 against 131.8 / 131.2 s).  The order MFGS < FGS2 < FGS1 holds for the overshoot (0 / 30.4 / 50.8 %), not for
    the IAE (FGS2 63.5 is the smallest).  PARTLY REPRODUCED."""
    metrics = ("IAE", "overshoot", "settling_time", "rise_time")
    m = {(case, law): setpoint_metrics("gs_sim2_5", f"case{case}", law) for case in CASES for law in ("mfgs", "fgs1", "fgs2")}
    value = lambda case, law, key: np.nan_to_num(m[case, law][key], nan=np.inf)  # noqa: E731
    between = {(law, key): min(value(1, law, key), value(2, law, key)) - 1e-6 <= value(3, law, key)
               <= max(value(1, law, key), value(2, law, key)) + 1e-6 for law in ("mfgs", "fgs1", "fgs2") for key in metrics}
    assert [k for k, held in between.items() if not held] == [("mfgs", "IAE"), ("mfgs", "settling_time")]
    assert value(3, "mfgs", "overshoot") < value(3, "fgs2", "overshoot") < value(3, "fgs1", "overshoot")
    assert value(3, "fgs2", "IAE") < value(3, "mfgs", "IAE")


def test_a_third_operating_point_brings_fgs_to_mfgs_overshoot():
    """§2.3.4 (1), ch. 5 (2): FGS1 and FGS2 need "more operating points" for "the desired control quality" when Kp
    varies.  Sim. 2.3 with a third point at y = 3.88 (third_point_case*.ssv, the case's ITAE gain there): FGS's
    overshoot falls from 44.1 / 57.8 / 58.9 % to 0.7 / 1.2 / 1.7 % (CASES 1-3), below MFGS's 1.3 / 8.4 / 11.9 % with
    two points; its IAE improves in CASES 2-3 (81.0, 79.0 against 92.1, 113.3) and not in CASE 1 (88.0 against 62.8,
    a slow approach: settling 259 s).  REPRODUCED (overshoot)."""
    for case in CASES:
        two = setpoint_metrics("gs_sim2_3", f"case{case}", "fgs1")
        three = setpoint_metrics("gs_sim2_3", f"case{case}", "fgs1", f"third_point_case{case}")
        mfgs = setpoint_metrics("gs_sim2_3", f"case{case}", "mfgs")
        assert two["overshoot"] > 40.0 and three["overshoot"] < 2.0 and three["overshoot"] <= mfgs["overshoot"]


def test_sim_2_5_mfgs_load_rejection_is_not_the_best_here():
    """Sim. 2.5: "the disturbance rejection of MFGS is the best compared with FGS1 and FGS2" (judged against the
    shape of ITAE's).  NOT REPRODUCED by the numbers: FGS2 rejects the +d step with a smaller IAE (CASE 1: 8.5
    against MFGS's 14.3)."""
    iae = {}
    for law in ("mfgs", "fgs2"):
        result = run("gs_sim2_5", "case1", law, stop_time=800.0)
        t, e = result["time"], result["setpoint.y"] - result["plant.y"]
        iae[law] = float(np.sum(np.abs(e[t >= 400.0])) * 0.1)
    assert iae["fgs2"] < 0.7 * iae["mfgs"]


# --- The reversed directions of Sims. 2.3-2.5 (the paragraphs after each CASE 3): down_*/mirrored_* parameter sets ---


@pytest.mark.parametrize("case", CASES)
def test_sim_2_3_gain_falling_with_y_mfgs_best_and_the_laws_closer(case):
    """Sim. 2.3, "the case in which the process gain decreases as y decreases" (set-point 4 → 1): MFGS again the best
    for set-point tracking and the laws "have much less difference".  REPRODUCED on the overshoot: MFGS 15.1 / 8.5 /
    1.8 % against FGS 26.6 / 25.5 / 24.3 % (CASES 1-3); the gap 11-23 points against 43-49 on the step 1 → 4."""
    up, down = (direction_metrics("gs_sim2_3", case, mirrored=False, down=d) for d in (False, True))
    assert down["mfgs"]["overshoot"] < down["fgs1"]["overshoot"] - 10.0
    gap = {name: m["fgs1"]["overshoot"] - m["mfgs"]["overshoot"] for name, m in (("up", up), ("down", down))}
    assert gap["down"] < 0.6 * gap["up"]


@pytest.mark.parametrize("down", [False, True], ids=["y_rises", "y_falls"])
@pytest.mark.parametrize("case", CASES)
def test_sim_2_3_gain_rising_as_y_falls_fgs_not_more_damped(case, down):
    """Sim. 2.3, "the case in which the process gain increases as the process output y decreases" (mirrored_case*,
    step 4 → 1) and "the cases when y increases the process gain decreases" (step 1 → 4): "the set-point step
    responses for FGS1 and FGS2 will be more, or much more, damped than MFGS".  NOT REPRODUCED: FGS's too high gain
    overshoots more and rises faster, as in the forward cases (y falls: FGS 26.6 / 25.5 / 23.7 % and rise 10-16 s
    against MFGS 14.3 / 8.6 / 3.7 % and 30-54 s; y rises: 86.3 / 57.0 / 37.4 % against 31.4 / 8.7 / 0.1 %)."""
    m = direction_metrics("gs_sim2_3", case, mirrored=True, down=down)
    assert m["fgs1"]["IAE"] == pytest.approx(m["fgs2"]["IAE"], rel=1e-9)  # Ti, Td equal at both points
    assert m["fgs1"]["overshoot"] > m["mfgs"]["overshoot"] + 10.0
    assert m["fgs1"]["rise_time"] < 0.5 * m["mfgs"]["rise_time"]


@pytest.mark.parametrize("case", CASES)
def test_sim_2_4_time_constant_rising_as_y_falls_fgs1_best_but_not_closer(case):
    """Sim. 2.4, "the case in which the process time constant increases as the process output y decreases" (step
    4 → 1): "the control quality of FGS1 for the setpoint tracking ... the best"; the laws "have much less
    difference".  FGS1 best REPRODUCED (smallest IAE of the scheduled laws: 48.0 / 40.1 / 43.4 against MFGS 55.1 /
    47.9 / 50.9); "much less difference" NOT: MFGS's IAE exceeds FGS1's by 7.1-7.8 against 3.9-4.6 on the step 1 → 4."""
    up, down = (direction_metrics("gs_sim2_4", case, mirrored=False, down=d) for d in (False, True))
    assert down["fgs1"]["IAE"] < min(down["mfgs"]["IAE"], down["fgs2"]["IAE"])
    gap = {name: m["mfgs"]["IAE"] - m["fgs1"]["IAE"] for name, m in (("up", up), ("down", down))}
    assert gap["down"] > gap["up"] > 0


@pytest.mark.parametrize("down", [False, True], ids=["y_rises", "y_falls"])
@pytest.mark.parametrize("case", CASES)
def test_sim_2_4_time_constant_falling_as_y_falls_mfgs_more_damped_fgs1_better(case, down):
    """Sim. 2.4, "the process time constant decreases as the process output y decreases" (mirrored_case*, step 4 → 1)
    and "increases as y increases" (step 1 → 4): MFGS's gain too small, "the setpoint step response for MFGS will be
    more, or much more, damped than ITAE.  Comparatively FGS1 and FGS2 are better."  REPRODUCED for MFGS and FGS1:
    MFGS rises in 13.5-21.0 s against ITAE's 8.7-14.8 s with less overshoot; FGS1's IAE is below MFGS's in all six
    (y falls: 49.8 / 38.7 / 43.0 against 53.2 / 42.0 / 46.1); FGS2's is not (53.6 / 42.3 / 46.7 when y falls)."""
    m = direction_metrics("gs_sim2_4", case, mirrored=True, down=down)
    assert m["mfgs"]["rise_time"] > 1.3 * m["itae"]["rise_time"]
    assert m["mfgs"]["overshoot"] < m["itae"]["overshoot"]
    assert m["fgs1"]["IAE"] < m["mfgs"]["IAE"]


@pytest.mark.parametrize("case", CASES)
def test_sim_2_5_dead_time_falling_with_y_overshoot_order_holds_laws_not_closer(case):
    """Sim. 2.5, "the case in which the process time delay decreases as the process output y decreases" (step 4 → 1):
    MFGS "the best again", the laws with "much less difference".  The overshoot order holds (MFGS 2.7 / 2.3 / 2.3 %,
    FGS2 11.2 / 8.5 / 8.9 %, FGS1 52.3 / 34.6 / 39.8 %) but FGS1 still overshoots 30-50 points more than MFGS (54, 37,
    51 up) and FGS2 has the smaller IAE (71.1 / 62.6 / 64.6 against 91.9 / 88.2 / 89.2): NOT REPRODUCED as stated."""
    m = direction_metrics("gs_sim2_5", case, mirrored=False, down=True)
    assert m["mfgs"]["overshoot"] < m["fgs2"]["overshoot"] < m["fgs1"]["overshoot"]
    assert m["fgs1"]["overshoot"] > m["mfgs"]["overshoot"] + 30.0
    assert m["fgs2"]["IAE"] < m["mfgs"]["IAE"]


@pytest.mark.parametrize("down", [False, True], ids=["y_rises", "y_falls"])
@pytest.mark.parametrize("case", CASES)
def test_sim_2_5_dead_time_rising_as_y_falls_fgs_overshoot_more(case, down):
    """Sim. 2.5, "the process time delay increases as the process output y decreases" (mirrored_case*, step 4 → 1) and
    "decreases as y increases" (step 1 → 4): "the setpoint step responses for FGS1 and FGS2 will be more, or much
    more, over-shot than MFGS".  REPRODUCED: y falls MFGS 17.8 / 14.6 / 15.9 %, FGS2 33.3 / 27.0 / 29.0 %, FGS1 87.9 /
    67.5 / 75.5 %; y rises 46.4 / 38.5 / 41.7, 84.0 / 70.3 / 75.3, 126.9 / 108.3 / 115.8 % (ITAE overshoots 19-53 %
    there too: the loop starts at τ ≈ 20 s)."""
    m = direction_metrics("gs_sim2_5", case, mirrored=True, down=down)
    assert m["mfgs"]["overshoot"] + 10.0 < m["fgs2"]["overshoot"] < m["fgs1"]["overshoot"] - 20.0


@pytest.mark.parametrize("schedule, stable_modes", [("SystemStructure.ssd", (1, 3)), ("scheduled_on_y.ssd", (1,))])
def test_ch5_large_disturbance_mode_2_10_is_not_the_one_that_goes_unstable(schedule, stable_modes):
    """Ch. 5, conclusion 1 (and §2.3.2, 1): with the set-point as scheduling variable, (2.10) "is more likely to become
    unstable than PID with the integral mode (2.11) or (2.12), since it reduces to PID with fixed controller parameters
    for disturbances" (ssp/gs_ch5_large_disturbance: Sim. 2.1's process and gains, r = 1, load step d = 6).
    Scheduled on the set-point every mode IS the same fixed PID and rejects d (y peaks at 1.94, last 150 s within
    0.002).  Scheduled on y, (2.10) settles (peak 2.52) and (2.11) = (2.12) oscillate without end (last 150 s
    peak-to-peak 3.1): rescaling the integral output, which holds -d, by Kc(y) closes a second loop through the
    schedule.  The range (next test, docs/gain_scheduling_ranges_tables.md): NOT REPRODUCED for d < 40."""
    folder = SSP / "gs_ch5_large_disturbance"
    tails = {}
    for mode in (1, 3):
        result = cosim.simulate(folder / schedule, parameter_sets=[folder / f"mode{mode}.ssv"])
        tail = result["time"] > 450.0
        tails[mode] = float(np.ptp(result["plant.y"][tail]))
    for mode, spread in tails.items():
        assert (spread < 0.1) is (mode in stable_modes)
    if schedule == "scheduled_on_y.ssd":
        assert tails[3] > 1.0


def large_disturbance_dies_out(schedule: str, mode: int, d: float) -> bool:
    """After the load step d at 50 s (ch. 5 scenario, 600 s): y's swing over 450-600 s under 0.01 or under 0.9 × its
    swing over 300-450 s (docs/gain_scheduling_ranges_report.py's rule)."""
    folder = SSP / "gs_ch5_large_disturbance"
    with tempfile.TemporaryDirectory() as temp:
        load = one_value(Path(temp), "load.amplitude", d)
        result = cosim.simulate(folder / schedule, parameter_sets=[folder / f"mode{mode}.ssv", load])
    t, y = result["time"], result["plant.y"]
    if not np.all(np.isfinite(y)):
        return False
    late, before = np.ptp(y[t > 450.0]), np.ptp(y[(t > 300.0) & (t <= 450.0)])
    return bool(late < 0.01 or late < 0.9 * before)


def test_ch5_large_disturbance_the_fixed_pid_diverges_from_d_40():
    """Ch. 5 (1) over the load step d (docs/gain_scheduling_ranges_tables.md: d = 2 … 60, bisection to 0.1): scheduled on
    the set-point, the fixed PID of y = 1 (Kc = 3.04) rejects the load up to d = 39.8 (its swing dying out ever more
    slowly: 3.99 → 0.16 at d = 39.5) and diverges from d = 40 (|y| 8345 by 600 s: y is driven above 7, where Kp = 2.5
    and Kc·Kp = 7.6); scheduled on y, (2.11) = (2.12) oscillate without end from d = 2.25 (2 settles), boundedly (peak
    35 at d = 40, 53 at 60), and (2.10) settles up to 60.  So the claim holds only for d ≥ 40, where the fixed PID
    diverges while the y-scheduled loops stay bounded; for 2.25 ≤ d < 40 the y-scheduled (2.11)/(2.12) are the
    unstable ones.  Here d = 39.5 and 40 (set-point), 2 and 2.5 ((2.12) on y)."""
    assert large_disturbance_dies_out("SystemStructure.ssd", 1, 39.5)
    assert not large_disturbance_dies_out("SystemStructure.ssd", 1, 40.0)
    assert large_disturbance_dies_out("scheduled_on_y.ssd", 3, 2.0)
    assert not large_disturbance_dies_out("scheduled_on_y.ssd", 3, 2.5)


@pytest.mark.parametrize("simulation", ["gs_sim2_3", "gs_sim2_4", "gs_sim2_5"])
@pytest.mark.parametrize("case", CASES)
def test_threshold_switching_is_worse_than_mfgs_at_intermediate_points(simulation, case):
    """§2.3.1: with a fixed threshold W* between the two operating points "usually we can not get
    good performance at intermediate operation points".  Measured here (setpoint 1 -> 4, W* at the
    midpoint): threshold switching overshoots 50-117 % against MFGS's 0-39 %, with a larger ITAE in
    every case of Simulations 2.3-2.5."""
    threshold = setpoint_metrics(simulation, f"case{case}", "threshold")
    mfgs = setpoint_metrics(simulation, f"case{case}", "mfgs")
    assert threshold["overshoot"] > mfgs["overshoot"] + 20.0
    assert threshold["ITAE"] > mfgs["ITAE"]
