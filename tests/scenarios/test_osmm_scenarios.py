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
    TABLE2_VARIANTS,
    mfrls_margin,
    scheduling_bound,
    table2_mae,
    table2_orderings,
    table3_fuel,
    unbounded_pair_fuel,
    yearly_saving,
)

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
    assert ours["osmm"] == pytest.approx(46153, rel=2e-3)
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
    """Table 2 over PRBS seed pairs (2s+1, 2s+2), s = 0 … 3: local < global always, but MFRLS < local < global on
    both outputs for only some pairs (8 of 20 over the full study), with margins of −1.3 … +2.8 % against the
    paper's 26 %/38 % — the same for the literal ramp of (41) (14 of 20)."""
    for variant in ("continuous ramp (scenario)", "literal ramp of (41)"):
        rows = table2_seeds[variant]
        counts = table2_orderings(rows)
        assert counts["local < global (h1)"] == counts["local < global (h2)"] == len(rows), variant
        assert 0 < counts["MFRLS < local < global (h1 and h2)"] < len(rows), variant  # seed-dependent
        assert all(abs(mfrls_margin(r, j)) < 3.0 for r in rows for j in (0, 1)), variant  # never the paper's 26 %
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
