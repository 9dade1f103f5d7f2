"""The master on FMUs nobody on this project wrote: OpenModelica exports shipped by gemseo-fmu."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest

import cosim
from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system

SUB = {"s1": ("MassSpringSubSystem1.fmu", {"x2": "input", "x1": "output", "v1": "output"}),
       "s2": ("MassSpringSubSystem2.fmu", {"x1": "input", "x2": "output", "v2": "output"})}
WIRES = [("s1", "x1", "s2", "x1"), ("s2", "x2", "s1", "x2")]


@pytest.fixture(scope="module")
def gemseo():
    return gemseo_fmu_dir()


@pytest.fixture
def mass_spring(tmp_path, gemseo):
    fmus = {f: gemseo / f for f, _ in SUB.values()}
    return write_system(tmp_path / "ms", fmus, ssd_text("massspring", SUB, WIRES, stop=2.0, step=0.001))


def test_coupled_halves_equal_the_monolithic_system(mass_spring, gemseo):
    """Both halves integrate with explicit Euler at the communication step (OpenModelica CS export);
    Jacobi coupling of two Euler steps is the Euler step of the whole system, so the coupled run must
    equal the monolithic MassSpringSystem.fmu run by fmpy at the same step, sample by sample."""
    ref = fmpy.simulate_fmu(str(gemseo / "MassSpringSystem.fmu"), stop_time=2.0, output_interval=0.001,
                            output=["x1", "x2", "v1", "v2"])
    res = cosim.simulate(mass_spring)
    assert len(res) == len(ref) == 2001
    np.testing.assert_allclose(res["time"], ref["time"], rtol=0, atol=1e-12)
    for ours, theirs in (("s1.x1", "x1"), ("s2.x2", "x2"), ("s1.v1", "v1"), ("s2.v2", "v2")):
        np.testing.assert_allclose(res[ours], ref[theirs], rtol=1e-12, atol=1e-12)
    # the initial output of each half reaches the other's input before the first step
    assert res["s1.x2"][0] == res["s2.x2"][0] == 1.0


def test_gauss_seidel_is_a_different_but_consistent_coupling(mass_spring, gemseo):
    ref = fmpy.simulate_fmu(str(gemseo / "MassSpringSystem.fmu"), stop_time=2.0, output_interval=0.001,
                            output=["x1"])
    res = cosim.simulate(mass_spring, algorithm="gauss-seidel")
    err = np.max(np.abs(res["s1.x1"] - ref["x1"]))
    assert 0 < err < 1e-3      # it differs (s2 sees s1's new x1), by O(h)
    halved = cosim.simulate(mass_spring, algorithm="gauss-seidel", step_size=0.0005)
    ref2 = fmpy.simulate_fmu(str(gemseo / "MassSpringSystem.fmu"), stop_time=2.0, output_interval=0.0005,
                             output=["x1"])
    assert np.max(np.abs(halved["s1.x1"] - ref2["x1"])) < 0.6 * err


def test_add_wired_into_a_loop_is_an_algebraic_loop(tmp_path, gemseo):
    """y_a = y_b + 1, y_b = y_a + 0 has no solution: the loop iteration (cosim.run.loops: the sweeps,
    Newton, the sweeps again) fails at initialisation, naming every variable on the loop (before
    issue 21 it was refused unrun)."""
    comps = {"a": ("add.fmu", {"u1": "input", "u2": "input", "y": "output"}),
             "b": ("add.fmu", {"u1": "input", "u2": "input", "y": "output"})}
    folder = write_system(tmp_path / "loop", {"add.fmu": gemseo / "add.fmu"},
                          ssd_text("loop", comps, [("a", "y", "b", "u1"), ("b", "y", "a", "u1")],
                                   parameters={"a": {"u2": 1.0}}))
    with pytest.raises(cosim.RunError) as err:
        cosim.simulate(folder)
    text = str(err.value)
    assert "algebraic loop did not converge at t = 0" in text
    assert "Newton's method did not pass the sweep test" in text     # tried, then the fixed point
    for name in ("a.y", "b.u1", "b.y", "a.u1"):
        assert name in text


def test_add_in_a_chain_settles_within_the_instant(tmp_path, gemseo):
    """Direct feedthrough without a loop: a ramp through two adders arrives at the same instant."""
    comps = {"r": ("ramp.fmu", {"out": "output"}),
             "a": ("add.fmu", {"u1": "input", "u2": "input", "y": "output"}),
             "b": ("add.fmu", {"u1": "input", "u2": "input", "y": "output"})}
    folder = write_system(tmp_path / "chain", {"add.fmu": gemseo / "add.fmu", "ramp.fmu": gemseo / "ramp.fmu"},
                          ssd_text("chain", comps, [("r", "out", "a", "u1"), ("a", "y", "b", "u1")],
                                   stop=1.0, step=0.1, parameters={"b": {"u2": 0.5}}))
    res = cosim.simulate(folder)
    np.testing.assert_allclose(res["b.y"], res["r.out"] + 0.5, atol=1e-12)
    assert res["r.out"][-1] == pytest.approx(1.0)
