"""LookupTable (the thesis's ch. 4 "Fcn Gen") as a class and as an FMU in the master."""
from __future__ import annotations

import numpy as np
import pytest

import cosim
from greyfmu.signals import LookupTable
from ssdgen import ssd_text, write_system


def test_interpolation_and_both_extrapolation_modes():
    table = LookupTable([58, 76, 101], [86, 109, 140])
    assert table.output(76) == 109 and table.output(67) == pytest.approx(97.5)
    assert table.output(111) == pytest.approx(140 + 31 / 25 * 10)
    held = LookupTable([58, 76, 101], [86, 109, 140], extrapolate=False)
    assert held.output(111) == 140 and held.output(0) == 86


@pytest.mark.parametrize("x, y, text", [([1, 1, 2], [0, 1, 2], "strictly increasing: x_1 = 1 is not below x_2 = 1"),
                                        ([1], [1], "at least two"), ([1, 2], [0, np.nan], "finite")])
def test_bad_tables_are_refused(x, y, text):
    with pytest.raises(ValueError, match=text):
        LookupTable(x, y)


def test_fcn_gen_fmu_follows_a_load_ramp_within_the_instant(tmp_path, built_fmus):
    """Ramp 58 -> 101 MW at 10 MW/s into the FMU's default table: the pressure setpoint is the
    table's value of the ramp at every sample (direct feedthrough settles in the same instant)."""
    comps = {"load": ("Ramp.fmu", {"y": "output"}), "fcn": ("LookupTable.fmu", {"u": "input", "y": "output"})}
    folder = write_system(tmp_path / "s", {"Ramp.fmu": built_fmus["Ramp"], "LookupTable.fmu": built_fmus["LookupTable"]},
                          ssd_text("fcn", comps, [("load", "y", "fcn", "u")], stop=6.0, step=0.5,
                                   parameters={"load": {"start_time": 1.0, "slope": 10.0, "initial": 58.0,
                                                        "final": 101.0}}))
    r = cosim.simulate(folder, use_providers=False)
    expected = np.interp(r["load.y"], [58, 76, 101], [86, 109, 140])
    np.testing.assert_allclose(r["fcn.y"], expected, atol=1e-12)
    assert r["fcn.y"][0] == 86 and r["fcn.y"][-1] == 140


def test_unsorted_table_fails_with_the_reason(tmp_path, built_fmus):
    comps = {"fcn": ("LookupTable.fmu", {"u": "input", "y": "output"})}
    folder = write_system(tmp_path / "s", {"LookupTable.fmu": built_fmus["LookupTable"]},
                          ssd_text("fcn", comps, [], parameters={"fcn": {"x_2": 50.0}}))
    with pytest.raises(cosim.RunError) as err:
        cosim.simulate(folder, use_providers=False)
    assert "x_1 = 58 is not below x_2 = 50" in str(err.value)
