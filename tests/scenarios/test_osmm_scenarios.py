"""Scenario tests of issue 8 through real FMUs and cosim: Table 2 (MFRLS) and Table 3 (header experiment).

Paper: Pan, Shen & Luh (2012), seed 003, §5.  Where our reconstruction does not reproduce the
paper, the test records the number we get (docs/osmm_gpc.md says why).
"""

import numpy as np
import pytest

import cosim

PAPER_TABLE2 = {"global_frls": (0.0523, 0.0260), "local_frls": (0.0236, 0.0204), "mfrls": (0.0174, 0.0126)}
OURS_TABLE2 = {"global_frls": (0.1074, 0.0990), "local_frls": (0.0680, 0.0724), "mfrls": (0.0668, 0.0722)}
PAPER_TABLE3 = {"gpc_12": 40525.0, "gpc_13": 40475.0, "osmm": 39825.0}  # kg per 2500 s


@pytest.fixture(scope="module")
def mfrls_run(built_fmus):
    return cosim.simulate("ssp/osmm_mfrls", stop_time=1500, step_size=1.0)


def test_table2_mae_ordering(mfrls_run):
    mae = {name: (mfrls_run[f"{name}.mae1"][-1], mfrls_run[f"{name}.mae2"][-1]) for name in PAPER_TABLE2}
    for name, (h1, h2) in OURS_TABLE2.items():
        assert mae[name] == pytest.approx((h1, h2), abs=1e-3)  # recorded values (Table 2's are from its own model)
    for j in (0, 1):  # Table 2's ordering: MFRLS < local FRLS < global FRLS, on both outputs
        assert mae["mfrls"][j] < mae["local_frls"][j] < mae["global_frls"][j]


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
