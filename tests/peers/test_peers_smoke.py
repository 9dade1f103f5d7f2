"""Smoke test of the peer masters (libcosim, fmpy.ssp) and the benchmark floor on the
gemseo-fmu MassSpring pair, and of the SSD subset each peer honours (docs/peers.md).

Tolerances are the measured differences with some margin (fmpy 0.3.32, libcosimpy 0.0.6
/ libcosim 0.11.2, gemseo-fmu 3.1.1, h = 1 ms, 10 000 steps).
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import peers  # noqa: E402

_spec = importlib.util.spec_from_file_location(
    "greyfmu_benchmarks_floor", Path(__file__).resolve().parents[2] / "benchmarks" / "floor.py")
floor = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(floor)

H, T = 1e-3, 10.0
N = round(T / H)
OUTPUTS = ["sub1.x1", "sub1.v1", "sub2.x2", "sub2.v2"]
INPUTS = ["sub1.x2", "sub2.x1"]
SIGNALS = OUTPUTS + INPUTS
MONO = {"sub1.x1": "x1", "sub1.v1": "v1", "sub2.x2": "x2", "sub2.v2": "v2"}


def _fmus(params=None):
    d, params = peers.gemseo_fmu_dir(), params or {}
    return [(comp, str(d / model), params.get(comp, {})) for comp, model in peers.MASS_SPRING_FMUS.items()]


def _floor(t_stop, initial_inputs="outputs", params=None):
    connections = [(se, sc, ee, ec) for se, sc, ee, ec in peers.MASS_SPRING_CONNECTIONS]
    elapsed, n, res = floor.run_floor(_fmus(params), connections, 0.0, t_stop, H, SIGNALS,
                                      initial_inputs=initial_inputs)
    assert n == round(t_stop / H) and len(res) == n + 1
    return res


def _maxdiff(a, b, cols):
    return max(float(np.abs(a[c] - b[c]).max()) for c in cols)


@pytest.fixture(scope="module")
def ssp(tmp_path_factory):
    return peers.write_mass_spring_ssp(tmp_path_factory.mktemp("ssp") / "MassSpring.ssp")


@pytest.fixture(scope="module")
def runs(ssp):
    from fmpy import simulate_fmu

    mono = simulate_fmu(str(peers.gemseo_fmu_dir() / "MassSpringSystem.fmu"), fmi_type="CoSimulation",
                        start_time=0.0, stop_time=T, step_size=H, output_interval=H,
                        output=list(MONO.values()))
    return {
        "libcosim": peers.run_libcosim(ssp, 0.0, T, H, SIGNALS),
        "fmpy": peers.run_fmpy_ssp(ssp, 0.0, T, H, SIGNALS),
        "floor": _floor(T),
        "floor_zero": _floor(T, initial_inputs="zero"),
        "mono": mono,
    }


def test_shapes_and_time_stamps(runs):
    grid = H * np.arange(N + 1)
    # libcosim and the floor: rows at t_0..t_N, t_0 = start holds the initialized state
    assert len(runs["libcosim"]) == len(runs["floor"]) == N + 1
    assert np.abs(runs["libcosim"]["time"] - grid).max() < 1e-12
    assert np.abs(runs["floor"]["time"] - grid).max() < 1e-12
    # fmpy.ssp: N rows stamped with the step's start t_0..t_{N-1} (accumulated t += h)
    assert len(runs["fmpy"]) == N
    assert np.abs(runs["fmpy"]["time"] - grid[:-1]).max() < 1e-9


def test_floor_equals_libcosim(runs):
    # both Jacobi, both propagate initial outputs to inputs before the first step, same
    # communication points; measured max |diff| 6.3e-15 (last-bit noise of t + h)
    assert _maxdiff(runs["floor"], runs["libcosim"], SIGNALS) < 1e-12


def test_floor_with_zero_inputs_equals_fmpy_ssp(runs):
    fm, fl = runs["fmpy"], runs["floor_zero"][1:]  # fmpy row k = state after step k+1
    # fmpy passes an accumulated t (t += h) and a constant h, the floor t_k = k*h and
    # h_k = t_{k+1} - t_k: the FMU's Euler step (t + h) - t differs in the last bit,
    # measured max |diff| 1.7e-12 after 10 000 steps (1.6e-15 with equal time arguments)
    assert _maxdiff(fm, fl, OUTPUTS) < 1e-10
    # fmpy's input connectors hold the value copied after the step = source output at t_{k+1}
    assert np.array_equal(fm["sub1.x2"], fm["sub2.x2"]) and np.array_equal(fm["sub2.x1"], fm["sub1.x1"])
    # first step ran with x2 = 0 in sub1: v1' = -k1*x1 + k2*(x2 - x1) = 0, so v1 stays 1
    assert fm["sub1.v1"][0] == 1.0
    assert runs["libcosim"]["sub1.v1"][1] == pytest.approx(1.001, abs=1e-15)


def test_coupled_equals_monolithic(runs):
    """The OpenModelica CS exports take one explicit Euler step per fmi2DoStep, from
    states and inputs at t_k.  Jacobi hands each half the other half's output at t_k, so
    the coupled scheme is algebraically the monolithic explicit Euler scheme: the coupling
    error is zero here, measured max |diff| 6.3e-15 over 10 s at h = 1 ms."""
    mono, lc = runs["mono"], runs["libcosim"]
    assert len(mono) == N + 1 and np.abs(mono["time"] - lc["time"]).max() < 1e-12
    for ours, theirs in MONO.items():
        assert np.abs(lc[ours] - mono[theirs]).max() < 1e-12
    # fmpy.ssp's 0.0 start of every connector is a one-step disturbance of size ~h:
    # measured max |diff| vs monolithic 1.0e-3 (v1), 7.9e-4 (x2)
    fm = runs["fmpy"]
    err = max(float(np.abs(fm[ours] - mono[theirs][1:]).max()) for ours, theirs in MONO.items())
    assert 1e-4 < err < 2e-3


def test_libcosim_observers_agree(ssp):
    series = peers.run_libcosim(ssp, 0.0, 0.05, H, SIGNALS)
    polled = peers.run_libcosim(ssp, 0.0, 0.05, H, SIGNALS, observer="last_value")
    for c in SIGNALS:
        assert np.array_equal(series[c], polled[c])


# --- SSD subset ------------------------------------------------------------------------

PARAMS = {"sub1": {"k1": 4.0}, "sub2": {"m2": 2.0}}  # inputs with start values


@pytest.mark.parametrize("via", ["inline", "ssv"])
def test_parameter_bindings(tmp_path, via):
    ssp = peers.write_mass_spring_ssp(tmp_path / "p.ssp", params=PARAMS, params_via=via)
    t_stop = 0.1
    with_params, without = _floor(t_stop, params=PARAMS), _floor(t_stop)
    assert _maxdiff(with_params, without, OUTPUTS) > 1e-4
    # libcosim applies component ParameterBindings (inputs and parameters) ...
    assert _maxdiff(peers.run_libcosim(ssp, 0.0, t_stop, H, SIGNALS), with_params, SIGNALS) < 1e-12
    # ... fmpy.ssp parses them but never applies them
    fm = peers.run_fmpy_ssp(ssp, 0.0, t_stop, H, OUTPUTS)
    assert _maxdiff(fm, _floor(t_stop, initial_inputs="zero")[1:], OUTPUTS) < 1e-12


def test_linear_transformation(tmp_path):
    ssp = peers.write_mass_spring_ssp(tmp_path / "lt.ssp", transform=(2.0, 0.5))  # on sub1.x1 -> sub2.x1
    lc = peers.run_libcosim(ssp, 0.0, 0.1, H, SIGNALS)
    # libcosim: applied, also to the initial value propagated before the first step
    assert lc["sub2.x1"][0] == 0.5 and lc["sub1.x1"][0] == 0.0
    assert np.abs(lc["sub2.x1"][1:] - (2.0 * lc["sub1.x1"][:-1] + 0.5)).max() < 1e-15
    assert lc["sub2.v2"][1] == pytest.approx(-1.5e-3, abs=1e-15)  # v2' = -x2 + (x1 - x2) = -1.5
    # fmpy.ssp: ignored (it only looks for ssd:LinearTransformation, and never applies it)
    fm = peers.run_fmpy_ssp(ssp, 0.0, 0.1, H, SIGNALS)
    assert np.array_equal(fm["sub2.x1"], fm["sub1.x1"])


def test_connector_type_is_required_by_libcosim(tmp_path):
    ssp = peers.write_mass_spring_ssp(tmp_path / "untyped.ssp", connector_types=False)
    with pytest.raises(RuntimeError, match="A valid connector type was not found"):
        peers.run_libcosim(ssp, 0.0, 0.01, H, OUTPUTS)
    assert len(peers.run_fmpy_ssp(ssp, 0.0, 0.01, H, OUTPUTS)) == 10
