"""Bell–Åström boiler-turbine plant (recovered-models.md §1) and its actuators (thesis (4.2b))."""
from __future__ import annotations

import numpy as np
import pytest

import cosim
from greyfmu.plants.boiler_turbine import (BoilerTurbine, derivatives, drum_level, equilibrium,
                                           scheduled_pressure)
from ssdgen import ssd_text, write_system

# recovered-models.md §1, linearisation at x0 = (108, 66.65, 428), u0 = (0.34, 0.69, 0.433), inputs 0..1
A = np.array([[-0.00251, 0, 0], [0.06942, -0.1, 0], [-0.00669, 0, 0]])
B = np.array([[0.9, -0.34904, -0.15], [0, 14.15548, 0], [0, -1.39765, 1.65882]])
C3 = np.array([0.00634, 0, 0.00471])
D3 = np.array([0.25328, 0.51240, -0.01397])


@pytest.mark.parametrize("load, pressure", [(58.0, 86.0), (76.0, 109.0), (101.0, 140.0)])
def test_thesis_operating_points_are_equilibria_with_the_governor_near_75(load, pressure):
    """Thesis ch. 4 table: 58/76/101 MW at 86/109/140 kgf/cm², "keeps the governor opening at about 75 %"."""
    op = equilibrium(load)
    assert op.P == pressure
    assert np.max(np.abs(derivatives(op.state, op.valves))) < 1e-6
    assert op.governor == pytest.approx(75.0, abs=0.25)


def test_nominal_point_and_linearisation_match_section_1():
    op = equilibrium(66.65, pressure=108.0)
    assert (op.fuel, op.governor, op.feedwater) == pytest.approx((34.02, 69.00, 43.58), abs=0.01)
    x0, v0 = np.array([108.0, 66.65, 428.0]), np.array([34.0, 69.0, 43.3])
    eps = 1e-4
    jac_x = np.column_stack([(derivatives(x0 + dx, v0) - derivatives(x0 - dx, v0)) / (2 * eps)
                             for dx in np.eye(3) * eps])
    jac_v = np.column_stack([(derivatives(x0, v0 + dv) - derivatives(x0, v0 - dv)) / (2 * eps)
                             for dv in np.eye(3) * eps]) * 100   # per unit valve opening, as §1
    level_x = [(drum_level(x0 + dx, v0) - drum_level(x0 - dx, v0)) / (2 * eps) / 1000 for dx in np.eye(3) * eps]
    level_v = [(drum_level(x0, v0 + dv) - drum_level(x0, v0 - dv)) / (2 * eps) / 10 for dv in np.eye(3) * eps]
    for ours, printed in ((jac_x, A), (jac_v, B), (np.array(level_x), C3), (np.array(level_v), D3)):
        big = np.abs(printed) > 0
        np.testing.assert_allclose(ours[big], printed[big], rtol=5e-3)   # 3 significant digits
        np.testing.assert_allclose(ours[~big], 0.0, atol=1e-12)


def test_fcn_gen_interpolates_the_thesis_table():
    assert scheduled_pressure(67.0) == pytest.approx(86 + 23 * 9 / 18)
    assert scheduled_pressure(88.5) == pytest.approx(109 + 31 / 2)


def test_unreachable_level_is_refused():
    with pytest.raises(ValueError, match="cannot be held at 101 MW"):
        equilibrium(101.0, level=-100.0)


def test_actuators_obey_the_thesis_rate_limits():
    unit = BoilerTurbine(equilibrium(76.0))
    start = unit.valves
    unit.advance(0.0, 10.0, (100.0, 0.0, 100.0))
    assert unit.valves == pytest.approx((start[0] + 7.0, start[1] - 20.0, start[2] + 50.0))
    unit.advance(10.0, 100.0, (-5.0, 150.0, 60.0))
    assert unit.valves == pytest.approx((0.0, 100.0, 60.0))       # clipped to 0..100 %


def test_result_does_not_depend_on_the_communication_step():
    runs = {}
    for h in (0.1, 1.0, 5.0):
        unit = BoilerTurbine(equilibrium(76.0))
        for k in range(int(round(200 / h))):
            unit.advance(k * h, h, (45.0, 70.0, 52.0), d=2.0)
        runs[h] = unit.x.copy()
    assert np.max(np.abs(runs[0.1] - runs[5.0])) < 1e-6
    assert np.max(np.abs(runs[0.1] - equilibrium(76.0).state)) > 1.0       # it did move


def test_fmu_holds_equilibrium_and_answers_a_fuel_step(tmp_path, built_fmus):
    comps = {"fuel": ("Step.fmu", {"y": "output"}),
             "unit": ("BoilerTurbine.fmu", {"fuel_disturbance": "input", "P": "output", "E": "output",
                                            "L": "output"})}
    folder = write_system(tmp_path / "bt", {"Step.fmu": built_fmus["Step"],
                                            "BoilerTurbine.fmu": built_fmus["BoilerTurbine"]},
                          ssd_text("bt", comps, [("fuel", "y", "unit", "fuel_disturbance")], stop=300.0, step=0.5,
                                   parameters={"fuel": {"t_step": 100.0, "initial": 0.0, "final": 5.0}}))
    r = cosim.simulate(folder, use_providers=False)
    before = r["time"] <= 100
    assert np.ptp(r["unit.P"][before]) < 1e-9 and r["unit.P"][0] == 109.0 and r["unit.L"][0] == pytest.approx(-100)
    # 5 % more fuel at fixed valves: dP/dt = 0.009 * 5 = 0.045 kgf/cm²/s at first
    i = np.searchsorted(r["time"], 110.0)
    assert (r["unit.P"][i] - 109.0) / 10.0 == pytest.approx(0.045, rel=0.05)
