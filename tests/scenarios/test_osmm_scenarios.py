"""Scenario tests of issue 8 through real FMUs and cosim: Table 2 (MFRLS) and Table 3 (header experiment).

Paper: Pan, Shen & Luh (2012), seed 003, §5.  Where our reconstruction does not reproduce the
paper, the test records the number we get (docs/osmm_gpc.md says why).
"""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from greyfmu.plants import HeaderParameters

DOCS = Path(__file__).resolve().parents[2] / "docs"
sys.path.insert(0, str(DOCS))
from osmm_report import (  # noqa: E402
    RELAXED_BOUNDS,
    HEADER_SCENARIO,
    TABLE2_VARIANTS,
    estimation_errors,
    header_metrics,
    mfrls_margin,
    run_with,
    switching,
    scheduling_bound,
    table2_mae,
    table2_orderings,
    table3_fuel,
    unbounded_pair_fuel,
    yearly_saving,
)
from osmm_settings_report import SETTINGS, fig_5d, merits, transients_won  # noqa: E402

sys.path.remove(str(DOCS))

PAPER_TABLE2 = {"global_frls": (0.0523, 0.0260), "local_frls": (0.0236, 0.0204), "mfrls": (0.0174, 0.0126)}
OURS_TABLE2 = {"global_frls": (0.1074, 0.0990), "local_frls": (0.0680, 0.0724), "mfrls": (0.0668, 0.0722)}
PAPER_TABLE3 = {"gpc_12": 40525.0, "gpc_13": 40475.0, "osmm": 39825.0}  # kg per 2500 s


@pytest.fixture(scope="module")
def mfrls_run(built_fmus):
    return cosim.simulate("ssp/osmm_mfrls", stop_time=1500, step_size=1.0)


def test_table2_mae_pinned_seeds_recorded(mfrls_run):
    """The scenario's own PRBS seeds (1, 2): the recorded MAE (43) of each estimator (Table 2's are from its own
    model).  Whether Table 2's ordering holds depends on the seeds: test_table2_ordering_over_seed_pairs."""
    mae = {name: (mfrls_run[f"{name}.mae1"][-1], mfrls_run[f"{name}.mae2"][-1]) for name in PAPER_TABLE2}
    for name, (h1, h2) in OURS_TABLE2.items():
        assert mae[name] == pytest.approx((h1, h2), abs=1e-3)


@pytest.fixture(scope="module")
def header_runs(built_fmus):
    runs = {}
    for name, sets in {"osmm": [], "gpc_12": ["ssp/osmm_header/gpc_12.ssv"], "gpc_13": ["ssp/osmm_header/gpc_13.ssv"]}.items():
        runs[name] = cosim.simulate("ssp/osmm_header", stop_time=4500, step_size=1.0, parameter_sets=sets)
    return runs


def fuel(run):
    t = run["time"]
    window = t >= 2000
    return float(np.trapezoid(run["header.fuel"][window], t[window]))


def test_header_experiment_constraints_and_band(header_runs):
    for name, run in header_runs.items():
        window = run["time"] >= 2000
        for y in ("header.y1", "header.y2"):
            assert np.all(np.isfinite(run[y]))
            assert np.max(np.abs(run[y][window] - 8.75)) < 0.55, (name, y)  # stated band: ±0.55 MPa
            assert abs(run[y][run["time"] <= 2000][-1] - 8.75) < 1e-6  # steady state before the first step
        M = np.column_stack([run[f"controller.u{i}"] for i in (1, 2, 3)])
        assert np.all(M >= 0.3 - 1e-9) and np.all(M <= 1.2 + 1e-9)  # (35): M_min ≤ M ≤ M_max
        assert np.all(np.abs(np.diff(M[::10], axis=0)) <= 0.05 + 1e-9)  # (35): |ΔM| ≤ ΔM_max per 10-s sample
    for name, held in (("gpc_12", 2), ("gpc_13", 1)):
        assert np.all(header_runs[name][f"controller.u{held + 1}"] == 0.75)  # the unselected boiler holds


def test_table3_fuel_recorded(header_runs):
    """Table 3: OSMM-GPC burns 1.6–1.7 % less than the fixed pairs.  Ours does NOT (recorded, see docs)."""
    ours = {name: fuel(run) for name, run in header_runs.items()}
    assert ours["gpc_12"] == pytest.approx(45892, rel=2e-3)
    assert ours["gpc_13"] == pytest.approx(46008, rel=2e-3)
    assert ours["osmm"] == pytest.approx(46036, rel=2e-3)  # (31) as printed; 46153 with the gain form
    switches = np.flatnonzero(np.diff(header_runs["osmm"]["controller.active_group"]))
    assert len(switches) > 0  # OSMM did re-schedule the boilers


# --- issue 15: the tables under seed spread (docs/osmm_tables.md has all 20 seeds; these are the first ones)

FULL_SEEDS = os.environ.get("GREYFMU_SEEDS") == "full"
"""GREYFMU_SEEDS=full: Table 2's ordering over 40 seed pairs (s = 0 … 39, about 2 min more) instead of 8."""
TABLE2_ORDERING_HOLDS = (0, 1, 5, 8, 9, 12, 13, 15, 24, 25, 26, 29, 30, 33)
"""The s of the seed pairs (2s + 1, 2s + 2), s < 40, where MFRLS < local < global holds on both outputs (measured):
8 of s = 0 … 19 (docs/osmm_tables.md), 6 of the fresh s = 20 … 39."""
SUBSET = {"continuous ramp (scenario)": range(40 if FULL_SEEDS else 8), "literal ramp of (41)": range(4),
          "raw-firing μ_m (MFRLS dominance = 1)": range(2)}


def is_table2_ordered(row: dict[str, tuple[float, float]]) -> bool:
    """Table 2's ordering MFRLS < local FRLS < global FRLS on both outputs h1, h2."""
    return all(row["mfrls"][j] < row["local_frls"][j] < row["global_frls"][j] for j in (0, 1))


@pytest.fixture(scope="module")
def table2_seeds(built_fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("table2")
    return {variant: [table2_mae(TABLE2_VARIANTS[variant], seed, folder) for seed in seeds] for variant, seeds in SUBSET.items()}


def test_table2_ordering_depends_on_the_seed_and_mfrls_margin_is_small(table2_seeds):
    """Table 2 over PRBS seed pairs (2s+1, 2s+2), s = 0 … 7: local < global (on at least 90 % of the 40 pairs of
    GREYFMU_SEEDS=full: 38 (h1), 37 (h2)), but MFRLS < local < global on
    both outputs for only some pairs (8 of 20 over the full study), with margins of −1.3 … +2.8 % (s < 20) and
    −1.9 … +4.1 % (fresh s = 20 … 39) against the paper's 26 %/38 % — the same for the literal ramp of (41) (14 of 20)."""
    for variant in ("continuous ramp (scenario)", "literal ramp of (41)"):
        rows = table2_seeds[variant]
        counts = table2_orderings(rows)
        # local < global on every pair of the default subset; 38 and 37 of the 40 pairs of GREYFMU_SEEDS=full
        assert min(counts["local < global (h1)"], counts["local < global (h2)"]) >= 0.9 * len(rows), variant
        assert 0 < counts["MFRLS < local < global (h1 and h2)"] < len(rows), variant  # seed-dependent
        assert all(abs(mfrls_margin(r, j)) < 5.0 for r in rows for j in (0, 1)), variant  # never the paper's 26 %
    continuous, literal = table2_seeds["continuous ramp (scenario)"][:4], table2_seeds["literal ramp of (41)"]
    assert table2_orderings(continuous)["MFRLS < local < global (h1 and h2)"] == 2  # s = 0, 1 (docs/osmm_tables.md)
    for name in ("global_frls", "local_frls", "mfrls"):  # the literal ramp (c down to 0.25) is easier to track
        assert np.mean([r[name][0] for r in literal]) < np.mean([r[name][0] for r in continuous])


def test_table2_ordering_over_seed_pairs(table2_seeds):
    """Table 2's ordering MFRLS < local FRLS < global FRLS (both outputs) over PRBS seed pairs: NOT REPRODUCED over
    seeds — it holds in a minority (3 of s = 0 … 7; with GREYFMU_SEEDS=full 8 of s = 0 … 19 and 6 of s = 20 … 39).
    The test asserts the measured set of seeds where it holds, so a change to the estimators changes the set."""
    rows = table2_seeds["continuous ramp (scenario)"]
    holds = tuple(s for s, row in enumerate(rows) if is_table2_ordered(row))
    assert holds == tuple(s for s in TABLE2_ORDERING_HOLDS if s < len(rows))
    assert 0 < len(holds) < len(rows) / 2  # a minority: "not reproduced over seeds"
    if FULL_SEEDS:
        assert sum(s < 20 for s in holds) == 8 and sum(s >= 20 for s in holds) == 6


def test_raw_firing_mixing_weight_does_not_make_mfrls_global_frls(table2_seeds):
    """The raw maximum firing as μ_m is mostly tiny, yet MFRLS is not global FRLS (pinned seeds: 0.0699/0.0767
    against 0.1074/0.0990; over 20 pairs 0.0885/0.0854 against 0.1053/0.1003, closer to local FRLS's
    0.0874/0.0848): a weight w gives the gain wCφ/(1 + wφᵀCφ), nearly the full update while wφᵀCφ ≫ 1."""
    raw = table2_seeds["raw-firing μ_m (MFRLS dominance = 1)"]
    assert raw[0]["mfrls"] == pytest.approx((0.0699, 0.0767), abs=1e-3)
    for r in raw:
        for j in (0, 1):
            assert r["mfrls"][j] < 0.9 * r["global_frls"][j]
            assert abs(r["mfrls"][j] - r["local_frls"][j]) < abs(r["mfrls"][j] - r["global_frls"][j])


@pytest.fixture(scope="module")
def table3_seeds(built_fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("table3")
    return [table3_fuel({}, 1, folder)]


def test_table3_over_identification_seeds_osmm_never_lowest(header_runs, table3_seeds):
    """Table 3 over identification seeds 0 and 1 (20 in docs/osmm_tables.md: OSMM lowest in 0, below (1,3) in 7):
    the fixed pair (1,2) burns least, and pair (1,3) burns within 0.1 % of the steady-state fuel that the segment
    balances force on it (46044 kg), so the differences are transients and (1,2)'s saturation."""
    rows = [{name: fuel(run) for name, run in header_runs.items()}, *table3_seeds]
    steady_13, least = scheduling_bound(HeaderParameters())
    assert steady_13 - least < 10.0  # no scheduler can save more than a few kg in this header
    for r in rows:
        assert r["gpc_12"] < min(r["osmm"], r["gpc_13"])
        assert r["gpc_13"] == pytest.approx(steady_13, rel=1e-3)
        assert yearly_saving(r["osmm"], r["gpc_13"]) < 2100.0  # t/year; the paper's 8199 is never approached


def test_pair_12_burns_least_because_it_cannot_hold_the_pressures(header_runs, built_fmus, tmp_path):
    """After the valve-2 step pair (1,2) needs B2 at 0.067 p.u. (< M_min) and B1 above 1.5 p.u. (> M_max = 1.2):
    it saturates and leaves both pressures off the set-point.  Without the bounds it holds them and burns the
    steady (1,2) fuel, still below (1,3) in our header (B2 the least efficient boiler); with a B2 of η_max 0.90
    the fixed pairs' steady fuel takes the paper's order (1,3) < (1,2)."""
    run = header_runs["gpc_12"]
    end = run["time"] >= 4400
    assert np.all(np.abs(run["header.y1"][end] - 8.75) > 0.02) and np.all(np.abs(run["header.y2"][end] - 8.75) > 0.02)
    assert run["controller.u1"][end].min() == pytest.approx(1.2)
    relaxed = table3_fuel(RELAXED_BOUNDS, 0, tmp_path, ("gpc_12", "gpc_13"))
    assert relaxed["gpc_12"] < relaxed["gpc_13"]
    assert relaxed["gpc_12"] == pytest.approx(unbounded_pair_fuel(HeaderParameters(), (0, 1)), rel=2e-3)
    better_b2 = HeaderParameters(eta_max=(0.92, 0.90, 0.90))
    assert unbounded_pair_fuel(better_b2, (0, 2)) < unbounded_pair_fuel(better_b2, (0, 1))


# --- issue 31: Fig. 5(d)'s scheduling, Fig. 5(b)/(c)'s transients, §5.1's unmeasured claims -------------------

SCHEDULING_SEEDS = range(20) if FULL_SEEDS else range(2)
"""Identification seeds of the scheduling verdict (GREYFMU_SEEDS=full: all 20 of docs/osmm_tables.md)."""
ESTIMATION_SEEDS = range(20) if FULL_SEEDS else range(2)
"""PRBS seed pairs (2s + 1, 2s + 2) of the §5.1 verdicts."""
ONE_SWITCH_SEEDS = (0,)
"""Identification seeds s < 20 where the OSMM-GPC (31 as printed) switches exactly once after its first sample (measured)."""
BOILER_1_SEEDS = (0, 5, 7, 12, 15, 17, 18, 19)
"""… and where boiler 1 is in the active group all through 2000–4500 s (measured: 8 of 20)."""
CHANGE_BETTER_SEEDS = ((0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 17, 18, 19),
                       (0, 1, 2, 3, 4, 5, 6, 8, 9, 10, 11, 12, 13, 14, 15, 17, 18, 19))
"""PRBS seed pairs s < 20 where MFRLS's MAE of h1 (h2) in the 50 steps after an input switch is below local FRLS's (18, 18 of 20)."""


def test_fig_5d_printed_31_switches_once_and_keeps_boiler_1(header_runs, tmp_path):
    """Fig. 5(d) / §5.2: one switch, boilers 1 and 3 before it, 1 and 2 after ("boiler 1 had the highest efficiency
    all along").  With (31) as printed, Σ A_j(1)/Σ B_jl(1) (now the default), our OSMM-GPC does exactly that
    (seed 0): one switch, (1,3) → (1,2) at 3721 s, after the valve-2 step; (2,3) never active.  With the
    unit-consistent gain form we used before it switches 16 times after its first sample (17 counting that one) and
    (2,3) — without boiler 1 — is active 58 % of 2000–4500 s: our scheduler had departed from the paper's rule."""
    count, times, share = switching(header_runs["osmm"])
    assert count == 1 and times[0][1] == 1 and 3500 < times[0][0] < 4000
    assert share[3] == 0.0 and share[2] > 0.5
    gain = run_with(HEADER_SCENARIO, {"controller.efficiency": 0}, tmp_path, stop_time=4500)
    count, _, share = switching(gain)
    assert count == 16 and share[3] == pytest.approx(0.58, abs=0.01)


def test_fig_5d_over_identification_seeds(tmp_path):
    """Fig. 5(d)'s pattern over identification seeds (31 as printed): exactly one switch on 1 of 20 seeds (s = 0),
    boiler 1 in the group throughout on 8 of 20; switches median 3.5 [0 … 56] (docs/osmm_tables.md).  Not reproduced
    over seeds: which group the identified models favour depends on the identification run.  The first seeds here."""
    runs = [switching(run_with(HEADER_SCENARIO, {"controller.identification_seed": s}, tmp_path, stop_time=4500))
            for s in SCHEDULING_SEEDS]
    one = tuple(s for s, (count, _, _) in zip(SCHEDULING_SEEDS, runs) if count == 1)
    boiler_1 = tuple(s for s, (_, _, share) in zip(SCHEDULING_SEEDS, runs) if share[3] == 0.0)
    assert one == tuple(s for s in ONE_SWITCH_SEEDS if s in SCHEDULING_SEEDS)
    assert boiler_1 == tuple(s for s in BOILER_1_SEEDS if s in SCHEDULING_SEEDS)
    if FULL_SEEDS:
        assert len(one) == 1 and len(boiler_1) == 8


STUDY_FULL = os.environ.get("GREYFMU_STUDY") == "full"
"""GREYFMU_STUDY=full re-runs docs/osmm_settings_tables.md: 7 controller settings × 10 identification seeds (+ the fixed
pairs on 3), 112 runs of 4500 s."""
FIG_5D_HELD = {setting: (1 if setting.startswith("Ts = 10 s") else 0) for setting in SETTINGS}
"""Seeds of 0 … 9 with Fig. 5(d)'s pattern per setting (docs/osmm_settings_tables.md): seed 0 at the docs' default only."""


def test_fig_5d_single_switch_on_seed_0_depends_on_the_controller_settings(header_runs, tmp_path):
    """Fig. 5(d): one switch, (1,3) → (1,2), boiler 1 throughout.  The paper gives no sample time, weights or horizon;
    on identification seed 0 the pattern appears at docs/osmm_gpc.md's Ts = 10 s, Q = 1, N2 = 20 (one switch at 3721 s)
    and in none of the six settings one step away: Ts = 5 s 2 switches, Ts = 20 s none, Q = 0.1 4, Q = 10 2, N2 = 10 3,
    N2 = 40 8 (docs/osmm_settings_tables.md).  Over seeds 0 … 9 of each setting: 1 of 70.  NOT REPRODUCED over seeds or settings;
    "the paper evidently used (31) as printed" does not follow from seed 0.  Default: the scenario and Ts = 20 s on
    seed 0; GREYFMU_STUDY=full: every setting over seeds 0 … 9."""
    assert fig_5d(merits(header_runs["osmm"]))
    if not STUDY_FULL:
        assert switching(run_with(HEADER_SCENARIO, {"controller.Ts": 20.0}, tmp_path, stop_time=4500))[0] == 0
        return
    for setting, held in FIG_5D_HELD.items():
        runs = [merits(run_with(HEADER_SCENARIO, {**SETTINGS[setting], "controller.identification_seed": s}, tmp_path,
                                stop_time=4500)) for s in range(10)]
        assert sum(fig_5d(m) for m in runs) == held, setting


def test_section_5_2_new_stable_state_long_before_700_steps(header_runs):
    """§5.2: "after about 700 steps running under the pressure control, the PUUH arrived at a new stable state" (after
    the valve-1 step at 2050 s).  Settling of P_m2 and P_m4 into ±0.02 MPa (the docs' band) and ±1 % (0.0875 MPa): at
    the docs' settings, seed 0, 259-401 s and 230-295 s over the three controls; over the seven settings and seeds 0 … 2
    at most 554 s and 435 s (docs/osmm_settings_tables.md).  "About 700" = within ±10 % (630-770 steps, docs/judging.md):
    NOT REPRODUCED — every loop settles in 60 % of the time or less."""
    settle = [merits(run)[f"{name} step 1 band {band}"][1] for run in header_runs.values()
              for name in ("P_m2", "P_m4") for band in (0.02, 0.0875)]
    assert max(settle) < 0.9 * 700 and min(settle) > 150.0


def test_fig_5bc_osmm_transient_against_the_fixed_pairs(header_runs):
    """Fig. 5(b)/(c): "OSMM-GPC control had less overshoot and shorter regulating time than the other two ways".
    Seed 0, largest deviation from 8.75 MPa / settling into ±0.02 MPa before the next event (docs/osmm_tables.md).
    After the valve-1 step OSMM runs (1,3) and equals it: P_m2 0.493 MPa / 278 s against (1,2)'s 0.482 MPa / 269 s
    (worse), P_m4 0.425 / 401 s against 0.432 / 262 s.  After the valve-2 step its switch to (1,2) settles both
    pressures (233 s, 262 s) while neither fixed pair settles before 4500 s, with the same deviations (within
    0.01 MPa).  Verdict: partly — shorter regulating time after the second step only; not less overshoot."""
    m = {name: header_metrics(run) for name, run in header_runs.items()}
    assert m["osmm"][0] == pytest.approx(m["gpc_13"][0], abs=1e-6)  # 1st step: OSMM is the (1,3) loop
    assert m["osmm"][0][0] > m["gpc_12"][0][0] and m["osmm"][0][1] > m["gpc_12"][0][1]  # P_m2: (1,2) better
    for k in (2, 3):  # 2nd step, P_m2 and P_m4
        assert m["osmm"][k][1] < 300.0 < 900.0 < min(m["gpc_12"][k][1], m["gpc_13"][k][1])
        assert abs(m["osmm"][k][0] - min(m["gpc_12"][k][0], m["gpc_13"][k][0])) < 0.01


def test_section_5_1_ts_model_without_online_estimation_has_major_errors(tmp_path):
    """§5.1: "there are major errors between the outputs of the TS model without online estimation and the
    theoretical model".  The Table 1 TS model with no update (C(0) = 1e-12 I) has MAE 3.26 / 3.67 (seed pair (1, 2))
    against 0.067–0.107 for the on-line estimators: at least 18.6 times larger on every seed pair (20/20 with
    GREYFMU_SEEDS=full).  Reproduced."""
    rows = [estimation_errors(s, tmp_path) for s in ESTIMATION_SEEDS]
    assert rows[0]["frozen"][:2] == pytest.approx((3.2613, 3.6732), abs=1e-3)
    major = sum(all(r["frozen"][j] > 15 * r[name][j] for name in ("global_frls", "local_frls", "mfrls") for j in (0, 1))
                for r in rows)
    assert major == len(rows)


def test_section_5_1_mfrls_advantage_under_large_input_changes(tmp_path):
    """§5.1: "when the input has a large change … MFRLS shows great advantage over the local FRLS".  MAE in the 50
    steps after a PRBS switch (0.45 ↔ 1.0): MFRLS below local FRLS on 18/20 seed pairs for h1 and for h2, margin
    median +2.2 % [−1.6 … +7.3] / +1.4 % [−1.7 … +5.4]; elsewhere +0.1 % (12/20) / −0.3 % (8/20).  Verdict: the
    advantage is where the paper says (after large changes), but small, not "great"."""
    rows = [estimation_errors(s, tmp_path) for s in ESTIMATION_SEEDS]
    better = {j: tuple(s for s, r in zip(ESTIMATION_SEEDS, rows) if r["mfrls"][2 + j] < r["local_frls"][2 + j]) for j in (0, 1)}
    for j in (0, 1):
        assert better[j] == tuple(s for s in CHANGE_BETTER_SEEDS[j] if s in ESTIMATION_SEEDS), j
    if FULL_SEEDS:
        assert len(better[0]) == len(better[1]) == 18
