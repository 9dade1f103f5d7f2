"""Root-system output connectors that no component output drives (issue 30).

SSP 1.0 (SystemStructureDescription, Connectors) does not require a system's connector to be
connected, and OMSimulator's testsuite ships such SSDs (importParameterMapping: the root
output ``Output_cref`` with no connection).  `cosim.read.flatten` accepts them, `cosim.plan.build`
records each as a constant column, its ParameterBinding value or NaN, with one warning naming
the file, the connector and its line, and the run's metadata lists them.  A root output that
a connection drives is recorded as before.  The system: a C FMU whose output is the time,
``clock.t``, recorded as the root output ``t_out``.
"""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu, fmi2_description
from cosim.cli import main
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from ssdgen import write_system

CLOCK_BODY = ("static void start(S *s) {}\n"
              "static void calculate(S *s) { s->r[0] = s->time; }\n"
              "static int step(S *s, double t, double h) { return 0; }\n")

HEADER = ('<?xml version="1.0" encoding="UTF-8"?>\n'
          '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"\n'
          '  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"\n'
          '  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"\n'
          '  xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" version="1.0" name="undriven">\n'
          '  <ssd:System name="root">\n')


def ssd(undriven: bool) -> str:
    """``t_out`` driven by clock.t; with ``undriven``, also ``held`` (a ParameterBinding gives it
    2.5), ``free`` (no value) and ``via``, fed only by the undriven output of subsystem ``sub``."""
    extra = ('      <ssd:Connector name="held" kind="output"><ssc:Real/></ssd:Connector>\n'
             '      <ssd:Connector name="free" kind="output"><ssc:Real/></ssd:Connector>\n'
             '      <ssd:Connector name="via" kind="output"><ssc:Real/></ssd:Connector>\n') if undriven else ""
    binding = ('    <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
               '<ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>'
               '<ssv:Parameter name="held"><ssv:Real value="2.5"/></ssv:Parameter>'
               '</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>'
               '</ssd:ParameterBindings>\n') if undriven else ""
    sub = ('      <ssd:System name="sub"><ssd:Connectors><ssd:Connector name="y" kind="output"><ssc:Real/>'
           '</ssd:Connector></ssd:Connectors></ssd:System>\n') if undriven else ""
    via = '      <ssd:Connection startElement="sub" startConnector="y" endConnector="via"/>\n' if undriven else ""
    return (HEADER
            + '    <ssd:Connectors>\n'
            + '      <ssd:Connector name="t_out" kind="output"><ssc:Real/></ssd:Connector>\n'
            + extra + '    </ssd:Connectors>\n' + binding
            + '    <ssd:Elements>\n'
            + '      <ssd:Component name="clock" source="resources/Clock.fmu"><ssd:Connectors>'
            + '<ssd:Connector name="t" kind="output"/></ssd:Connectors></ssd:Component>\n' + sub
            + '    </ssd:Elements>\n    <ssd:Connections>\n'
            + '      <ssd:Connection startElement="clock" startConnector="t" endConnector="t_out"/>\n' + via
            + '    </ssd:Connections>\n  </ssd:System>\n'
            + '  <ssd:DefaultExperiment startTime="0" stopTime="1"><ssd:Annotations>'
            + '<ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation stepSize="0.25"/></ssc:Annotation>'
            + '</ssd:Annotations></ssd:DefaultExperiment>\n</ssd:SystemStructureDescription>\n')


@pytest.fixture(scope="module")
def clock(tmp_path_factory):
    description = fmi2_description("Clock", [("t", 0, "output", None)], {},
                                   "{7a0c0030-0000-4000-8000-000000000030}")
    return build_c_fmu(tmp_path_factory.mktemp("clock"), "Clock", description, CLOCK_BODY)


def line_of(text: str, needle: str) -> int:
    """The 1-based line of ``text`` holding ``needle``."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_validate_accepts_undriven_root_outputs_with_one_warning_each(clock, tmp_path, capsys):
    folder = write_system(tmp_path / "s", {"Clock.fmu": clock}, ssd(True))
    assert main(["validate", str(folder)]) == 0
    err = capsys.readouterr().err
    text, ssd_file = ssd(True), str(folder / "SystemStructure.ssd")
    line = {name: line_of(text, f'name="{name}"') for name in ("held", "free", "via")}
    warned = [line for line in err.splitlines() if line.startswith("cosim: warning:")]
    assert len(warned) == 3, err
    held, free, via = warned
    assert held.startswith(f"cosim: warning: {ssd_file}, ssd:Connector 'held' of the root system "
                           f"(line {line['held']}), variable 'held'")
    assert f"the value 2.5 from {ssd_file}:{line_of(text, '<ssv:Parameter')} in every row" in held
    assert f"'free' of the root system (line {line['free']})" in free and "NaN" in free
    assert f"'via' of the root system (line {line['via']})" in via
    assert "fed only by 'sub.y', which no connection drives" in via
    assert "t_out" not in err


def test_run_writes_the_value_or_nan_in_every_row_and_names_them_in_the_metadata(clock, tmp_path, capsys):
    folder = write_system(tmp_path / "s", {"Clock.fmu": clock}, ssd(True))
    out = tmp_path / "r.csv"
    assert main(["run", str(folder), "-o", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err.count("cosim: warning:") == 3
    result = np.genfromtxt(out, delimiter=",", names=True)
    assert result.dtype.names == ("time", "clockt", "t_out", "held", "free", "via")
    assert len(result) == 5
    np.testing.assert_array_equal(result["t_out"], result["time"])
    np.testing.assert_array_equal(result["held"], np.full(5, 2.5))
    assert np.isnan(result["free"]).all() and np.isnan(result["via"]).all()
    meta = json.loads(out.with_suffix(".json").read_text())
    text = ssd(True)
    assert meta["undriven_system_outputs"] == {
        "held": {"line": line_of(text, 'name="held"'), "value": 2.5,
                 "origin": f"s/SystemStructure.ssd:{line_of(text, '<ssv:Parameter')}"},
        "free": {"line": line_of(text, 'name="free"'), "value": None, "origin": None},
        "via": {"line": line_of(text, 'name="via"'), "value": None, "origin": None}}
    assert meta["system_outputs"]["t_out"] == "clock.t"


def test_a_start_value_on_the_command_line_replaces_the_binding_and_warns_once(clock, tmp_path, capsys):
    folder = write_system(tmp_path / "s", {"Clock.fmu": clock}, ssd(True))
    out = tmp_path / "r.csv"
    assert main(["run", str(folder), "-o", str(out), "--quiet", "--start-value", "held=7"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "'held'" in line]
    assert len(warned) == 1 and "the value 7 from --start-value" in warned[0]
    np.testing.assert_array_equal(np.genfromtxt(out, delimiter=",", names=True)["held"], np.full(5, 7.0))
    assert json.loads(out.with_suffix(".json").read_text())["undriven_system_outputs"]["held"]["origin"] \
        == "--start-value"


def test_a_driven_root_output_is_recorded_as_before_without_warning(clock, tmp_path):
    folder = write_system(tmp_path / "s", {"Clock.fmu": clock}, ssd(False))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails the test
        prepared = prepare(folder)
        try:
            result, meta = run(prepared)
        finally:
            prepared.close()
    assert result.dtype.names == ("time", "clock.t", "t_out")
    np.testing.assert_array_equal(result["t_out"], [0.0, 0.25, 0.5, 0.75, 1.0])
    assert "undriven_system_outputs" not in meta
    assert meta["system_outputs"] == {"t_out": "clock.t"}


def test_a_root_output_fed_by_an_undriven_system_input_is_still_refused(clock, tmp_path):
    text = ssd(False).replace('<ssd:Connector name="t_out" kind="output"><ssc:Real/></ssd:Connector>',
                              '<ssd:Connector name="t_out" kind="output"><ssc:Real/></ssd:Connector>'
                              '<ssd:Connector name="r" kind="input"><ssc:Real/></ssd:Connector>'
                              '<ssd:Connector name="echo" kind="output"><ssc:Real/></ssd:Connector>')
    text = text.replace("    </ssd:Connections>", '<ssd:Connection startConnector="r" endConnector="echo"/>'
                                                   "</ssd:Connections>")
    with pytest.raises(cosim.SetupError, match="root output connector 'echo' is fed by 'r', which no component"):
        cosim.prepare(write_system(tmp_path / "s", {"Clock.fmu": clock}, text))

