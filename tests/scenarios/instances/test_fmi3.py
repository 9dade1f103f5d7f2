"""FMI 3.0 Co-Simulation FMUs in the same system as FMI 2.0 ones (cosim.run.instances.fmi3).

Real FMUs only: gemseo-fmu's FMU3Model.fmu (PythonFMU3), our PID3 (fmus/fmi3, pythonfmu3),
the FMI 2.0 FMUs of fmus/, and the test-only FMUs of tests/fmus (Labels: String ports,
BoolSource) and tests/fmus/fmi3 (Echo3: Int32, Boolean, String, an input array).
Expected values are computed here from each FMU's documented behaviour.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import RunError, SetupError
from cosim.sweep import sweep
from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus, build_test_fmus3, edited_copy

H = 0.1


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, built_fmus):
    tmp = tmp_path_factory.mktemp("fmi3fmus")
    found = {name: built_fmus[name] for name in ("Step", "Gain", "FirstOrderFilter")}
    found.update(build_test_fmus(tmp / "fmi2"))
    found.update(build_test_fmus3(tmp / "fmi3"))
    found["FMU3Model"] = gemseo_fmu_dir() / "FMU3Model.fmu"
    return found


def _system(tmp_path: Path, fmus: dict, components: dict, connections: list, edit=None, **kw) -> Path:
    text = ssd_text("fmi3", components, connections, **kw)
    if edit is not None:
        text = edit(text)
    files = {f: fmus[Path(f).stem] for f, _ in components.values()}
    return write_system(tmp_path / "sys", files, text)


# --------------------------------------------------------------------------- runs

def test_fmu3model_between_fmi2_fmus(tmp_path, fmus):
    """FMU3Model (its fmu3_model.py): on exiting initialisation output = 3 + increment·input,
    then each step output += increment and vector = roll(vector, 1) from [0, 1, 2, 3, 4].
    Our Step feeds its Float64 input, BoolSource its Boolean input; its output and the
    array element vector[2] (1-based: the value 1 at first) drive FMI 2.0 Gains."""
    comps = {
        "s": ("Step.fmu", {"y": "output"}),
        "bs": ("BoolSource.fmu", {"on": "output"}),
        "m": ("FMU3Model.fmu", {"input": "input", "boolean": "input", "output": "output", "vector[2]": "output"}),
        "g": ("Gain.fmu", {"u": "input", "y": "output"}),
        "g2": ("Gain.fmu", {"u": "input", "y": "output"}),
    }
    conns = [("s", "y", "m", "input"), ("bs", "on", "m", "boolean"), ("m", "output", "g", "u"),
             ("m", "vector[2]", "g2", "u")]
    params = {"s": {"t_step": 0.25, "initial": 2.0, "final": 7.0}, "m": {"increment": 0.5},
              "g": {"k": 3.0}, "g2": {"k": -2.0}}
    typed = lambda text: text.replace('<ssd:Connector name="input" kind="input"/>',  # ssc:Real names a Float64
                                      '<ssd:Connector name="input" kind="input"><ssc:Real/></ssd:Connector>')
    folder = _system(tmp_path, fmus, comps, conns, edit=typed, stop=1.2, step=H, parameters=params)
    r = cosim.simulate(folder)
    k = np.arange(len(r))
    np.testing.assert_allclose(r["time"], k * H, atol=1e-12)
    output = 3.0 + 0.5 * 2.0 + 0.5 * k            # the input counts only at initialisation
    vector2 = np.array([0.0, 1.0, 2.0, 3.0, 4.0])[(1 - k) % 5]
    np.testing.assert_array_equal(r["m.output"], output)
    np.testing.assert_array_equal(r["g.y"], 3.0 * output)
    np.testing.assert_array_equal(r["m.vector[2]"], vector2)
    np.testing.assert_array_equal(r["g2.y"], -2.0 * vector2)
    np.testing.assert_array_equal(r["m.input"], np.where(r["time"] >= 0.25, 7.0, 2.0))
    np.testing.assert_array_equal(r["m.boolean"], r["bs.on"])
    assert r["bs.on"][0] == 0 and r["bs.on"][-1] == 1


def test_int32_boolean_string_and_array_elements_reach_an_fmi3_fmu(tmp_path, fmus):
    """Echo3 computes twice = 2 n, negated = not b, shout = s.upper(), total = v[1] + 10 v[2] +
    100 v[3]; Labels (FMI 2.0) sends label = 'low' then 'high' from t = 0.5 and returns
    length = len(text).  Strings are not recorded, so they are checked through lengths."""
    comps = {
        "lab": ("Labels.fmu", {"label": "output"}),
        "bs": ("BoolSource.fmu", {"on": "output"}),
        "s": ("Step.fmu", {"y": "output"}),
        "s2": ("Step.fmu", {"y": "output"}),
        "e": ("Echo3.fmu", {"s": "input", "b": "input", "v[2]": "input", "v[3]": "input",
                            "shout": "output", "negated": "output", "total": "output"}),
        "lab2": ("Labels.fmu", {"text": "input", "length": "output"}),
        "e2": ("Echo3.fmu", {"n": "input", "twice": "output"}),
        "g": ("Gain.fmu", {"u": "input", "y": "output"}),
    }
    conns = [("lab", "label", "e", "s"), ("e", "shout", "lab2", "text"), ("lab2", "length", "e2", "n"),
             ("bs", "on", "e", "b"), ("s", "y", "e", "v[2]"), ("s2", "y", "e", "v[3]"), ("e", "total", "g", "u")]
    params = {"s": {"t_step": 0.3, "initial": 1.0, "final": 2.0}, "s2": {"t_step": 0.7, "initial": 5.0, "final": -1.0},
              "g": {"k": 0.5}}
    folder = _system(tmp_path, fmus, comps, conns, stop=1.2, step=H, parameters=params)
    for algorithm in ("jacobi", "gauss-seidel"):
        r = cosim.simulate(folder, algorithm=algorithm)
        t = r["time"]
        length = np.where(t >= 0.5 - 1e-9, 4, 3)          # "HIGH" / "LOW"
        np.testing.assert_array_equal(r["lab2.length"], length)
        np.testing.assert_array_equal(r["e2.twice"], 2 * length)
        np.testing.assert_array_equal(r["e.negated"], 1 - r["bs.on"])
        v2, v3 = np.where(t >= 0.3 - 1e-9, 2.0, 1.0), np.where(t >= 0.7 - 1e-9, -1.0, 5.0)
        np.testing.assert_array_equal(r["e.total"], 10 * v2 + 100 * v3)
        np.testing.assert_array_equal(r["g.y"], 0.5 * (10 * v2 + 100 * v3))
        assert not any("shout" in name or name.endswith(".s") for name in r.dtype.names)


def test_string_connection_between_fmi2_fmus(tmp_path, fmus):
    comps = {"a": ("Labels.fmu", {"label": "output"}), "b": ("Labels.fmu", {"text": "input", "length": "output"})}
    folder = _system(tmp_path, fmus, comps, [("a", "label", "b", "text")], stop=1.0, step=0.25)
    r = cosim.simulate(folder)
    np.testing.assert_array_equal(r["b.length"], [3, 3, 4, 4, 4])   # "low" before 0.5, then "high"
    # strings are not recorded: neither plotted nor usable as a sweep metric (refused up front)
    prepared = cosim.prepare(folder)
    try:
        assert prepared.plan.recorded() == (["b.length"], [])
        assert "a.label" not in r.dtype.names and "b.text" not in r.dtype.names
    finally:
        prepared.close()
    with pytest.raises(SetupError, match="no recorded signal 'a.label'"):
        sweep(folder, {}, metrics=["b.length:a.label"], output=tmp_path / "sweep", executor="serial")


def _pid_loop(tmp_path: Path, controller_fmu: str) -> Path:
    folder = tmp_path / controller_fmu
    shutil.copytree("ssp/pid_fopdt", folder)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace("resources/PID.fmu", f"resources/{controller_fmu}"))
    return folder


@pytest.mark.parametrize("start, stop, step", [(0.0, 300.0, 0.1), (2.55, 60.05, 0.25)])
def test_fmi3_pid_equals_the_fmi2_pid_in_the_loop(tmp_path, start, stop, step):
    """Our PID built for FMI 3.0 (fmus/fmi3/PID3.py, made on demand by the FMU provider) against
    the FMI 2.0 FOPDT plant: every sample equals the all-FMI-2.0 loop ssp/pid_fopdt.  A start
    time off the sample grid (Ts = 0.1 s, steps of 0.25 s: two or three samples per step, by
    phase) checks the sample clock, which pythonfmu3 FMUs learn only from the first step."""
    run = dict(start_time=start, stop_time=stop, step_size=step)
    ours = cosim.simulate(_pid_loop(tmp_path, "PID3.fmu"), **run)
    reference = cosim.simulate(_pid_loop(tmp_path, "PID.fmu"), **run)
    assert ours.dtype.names == reference.dtype.names and len(ours) == round((stop - start) / step) + 1
    for name in reference.dtype.names:
        np.testing.assert_allclose(ours[name], reference[name], rtol=0, atol=1e-12, err_msg=name)
    assert np.ptp(reference["controller.u"]) > 1.0    # the loop did something


def test_pid3_is_a_valid_fmi3_fmu_with_true_dependencies():
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from greyfmu.build import build_fmus

    fmu = build_fmus(["PID3"])[0]
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu), validate=True)
    assert md.fmiVersion == "3.0" and md.coSimulation.canHandleVariableCommunicationStepSize
    assert {o.variable.name: o.dependencies for o in md.outputs} == {"u": [], "e": []}


def test_terminate_simulation_records_the_step_that_asked(tmp_path, fmus):
    """Echo3 sets terminateSimulation in fmi3DoStep once n < 0 (here n = -1 from the start), with
    status OK: that step completed, so its communication point is recorded, as fmpy records it
    (issue 21, item 2), and the metadata says why the run ended."""
    import fmpy

    comps = {"e": ("Echo3.fmu", {"n": "input", "twice": "output"})}
    folder = _system(tmp_path, fmus, comps, [], stop=1.0, step=H, parameters={"e": {"n": -1}})
    out = tmp_path / "o.csv"
    r = cosim.simulate(folder, output=out)
    reference = fmpy.simulate_fmu(str(fmus["Echo3"]), stop_time=1.0, output_interval=H, start_values={"n": -1},
                                  output=["twice"])
    np.testing.assert_allclose(r["time"], reference["time"], atol=1e-12)
    np.testing.assert_array_equal(r["time"], [0.0, H])
    np.testing.assert_array_equal(r["e.twice"], reference["twice"])
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "terminated"
    assert "fmi3DoStep returned OK with terminateSimulation = true at t = 0.1" in meta["message"]


def test_fmi3_fmu_log_explains_a_failure(tmp_path):
    """pythonfmu3 logs through FMI 3.0's logMessage callback: the message reaches the RunError; the
    FMU's loader answers the slave's exception with fmi3Error (pythonfmu3: fmi3Fatal, issue 41)."""
    bad = tmp_path / "bad.ssv"
    bad.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv='
                   '"http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="bad">'
                   '<ssv:Parameters><ssv:Parameter name="controller.Ts"><ssv:Real value="-1"/></ssv:Parameter>'
                   '</ssv:Parameters></ssv:ParameterSet>\n')
    with pytest.raises(RunError) as error:
        cosim.simulate(_pid_loop(tmp_path, "PID3.fmu"), stop_time=1.0, parameter_sets=[bad])
    text = str(error.value)
    assert "component 'controller' (PID3.fmu)" in text and "fmi3Get returned Error at t = 0" in text
    assert "sample time Ts must be a finite number > 0, got -1.0" in text


# --------------------------------------------------------------------------- refusals

def _refused(tmp_path, fmus, components, connections=(), **kw) -> str:
    folder = _system(tmp_path, fmus, components, list(connections), **kw)
    with pytest.raises(SetupError) as error:
        cosim.prepare(folder)
    return str(error.value)


@pytest.mark.parametrize("connector", ["int64", "enumeration"])
def test_fmi3_int64_and_enumeration_connectors_are_accepted(tmp_path, fmus, connector):
    """Refused before issue 21 (item 6); exchanged as Integer now (tests/cosim/test_fmi_types.py)."""
    folder = _system(tmp_path, fmus, {"m": ("FMU3Model.fmu", {connector: "input"})}, [])
    cosim.prepare(folder).close()


def test_whole_array_connector_is_one_connector_per_element(tmp_path, fmus):
    """Refused before issue 41; now made element by element (tests/cosim/test_arrays.py)."""
    folder = _system(tmp_path, fmus, {"m": ("FMU3Model.fmu", {"vector": "output"})}, [])
    prepared = cosim.prepare(folder)
    try:
        assert prepared.plan.columns == tuple(f"m.vector[{i}]" for i in range(1, 6))
    finally:
        prepared.close()


@pytest.mark.parametrize("connector", ["vector[0]", "vector[6]", "vector[x]"])
def test_out_of_range_element_is_refused_with_the_array_size(tmp_path, fmus, connector):
    err = _refused(tmp_path, fmus, {"m": ("FMU3Model.fmu", {connector: "output"})})
    assert "an array of 5 values" in err and "vector[1] .. vector[5]" in err and connector in err


def test_int32_output_to_real_input_is_refused(tmp_path, fmus):
    comps = {"e": ("Echo3.fmu", {"twice": "output"}), "g": ("Gain.fmu", {"u": "input"})}
    err = _refused(tmp_path, fmus, comps, [("e", "twice", "g", "u")])
    assert "Int32 output e.twice wired to Real input g.u" in err


def test_declared_connector_type_must_match_the_fmi3_type(tmp_path, fmus):
    retype = lambda text: text.replace('<ssd:Connector name="input" kind="input"/>',
                                       '<ssd:Connector name="input" kind="input"><ssc:Integer/></ssd:Connector>')
    folder = _system(tmp_path, fmus, {"m": ("FMU3Model.fmu", {"input": "input"})}, [], edit=retype)
    with pytest.raises(SetupError, match="declared as Integer but the FMU FMU3Model.fmu declares Float64"):
        cosim.prepare(folder)


@pytest.mark.parametrize("fmu, variable, message", [
    ("Echo3.fmu", "v", "arrays and their elements cannot be given values by this master (v is an array)"),
])
def test_array_parameters_are_refused(tmp_path, fmus, fmu, variable, message):
    err = _refused(tmp_path, fmus, {"c": (fmu, {})}, parameters={"c": {variable: 1}})
    assert message in err and f"ssv:Parameter '{variable}'" in err
