"""Unit conversion: the unit math of cosim.model.units, the refusals, and runs through the master.

The end-to-end runs use two real pythonfmu FMUs built from tests/unitfmus/ (UnitSource:
y_i = a_i + b·t; UnitSink: v_i = u_i) whose variables get their units written into the model
description here, with UnitDefinitions as an exporting tool writes them, so the same two
builds serve every unit combination.  The sink's outputs are read back from the FMU, so they
show what the FMU received, in its own unit.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from pythonfmu.builder import FmuBuilder

from cosim.errors import SetupError
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from cosim.model.transforms import IDENTITY, Affine
from cosim.model.units import BUILTIN, conversion, make_unit
from testfmus import edited_copy

HERE = Path(__file__).parents[1] / "unitfmus"

#: UnitDefinitions the test FMUs declare (FMI 2.0 §2.2.2 BaseUnit attributes).
DEFINITIONS = {
    "degC": {"K": "1", "offset": "273.15"},
    "K": {"K": "1"},
    "kgf/cm2": {"kg": "1", "m": "-1", "s": "-2", "factor": "98066.5"},
    "MPa": {"kg": "1", "m": "-1", "s": "-2", "factor": "1e6"},
    "%": {"factor": "0.01"},
    "1": {},
    "s": {"s": "1"},
}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> dict[str, Path]:
    dest = tmp_path_factory.mktemp("unitfmus")
    return {s.stem: Path(FmuBuilder.build_FMU(s, dest=dest, needsExecutionTool="false"))
            for s in sorted(HERE.glob("*.py"))}


def with_units(fmu: Path, target: Path, units: dict[str, str], definitions: dict | None = None) -> Path:
    """Copy ``fmu`` to ``target`` with ``unit`` set on the named Real variables and a
    UnitDefinitions element declaring them (from ``definitions``, default `DEFINITIONS`)."""
    definitions = {**DEFINITIONS, **(definitions or {})}

    def edit(text: str) -> str:
        root = ElementTree.fromstring(text.encode("utf-8"))
        for sv in root.iter("ScalarVariable"):
            if sv.get("name") in units:
                sv.find("Real").set("unit", units[sv.get("name")])
        if units:
            unit_definitions = ElementTree.Element("UnitDefinitions")
            for name in sorted(set(units.values())):
                unit = ElementTree.SubElement(unit_definitions, "Unit", name=name)
                ElementTree.SubElement(unit, "BaseUnit", definitions[name])
            root.insert(list(root).index(root.find("CoSimulation")) + 1, unit_definitions)
        return ElementTree.tostring(root, encoding="unicode", xml_declaration=True)

    edited_copy(fmu, target, edit)
    return target


SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="units">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="src" source="resources/src.fmu">
        <ssd:Connectors>{src}</ssd:Connectors>{bindings}
      </ssd:Component>
      <ssd:Component name="dst" source="resources/dst.fmu">
        <ssd:Connectors>{dst}</ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>{connections}</ssd:Connections>
  </ssd:System>{units}
  <ssd:DefaultExperiment startTime="0" stopTime="1">
    <ssd:Annotations><ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation
      xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" stepSize="0.1"/></ssc:Annotation></ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def connector(name: str, kind: str, unit: str | None = None) -> str:
    real = f'<ssc:Real unit="{unit}"/>' if unit else "<ssc:Real/>"
    return f'<ssd:Connector name="{name}" kind="{kind}">{real}</ssd:Connector>'


def wire(out: str, inp: str, lt: tuple[float, float] | None = None, suppress: bool = False) -> str:
    attrs = ' suppressUnitConversion="true"' if suppress else ""
    body = f'<ssc:LinearTransformation factor="{lt[0]!r}" offset="{lt[1]!r}"/>' if lt else ""
    return (f'<ssd:Connection startElement="src" startConnector="{out}" endElement="dst" '
            f'endConnector="{inp}"{attrs}>{body}</ssd:Connection>')


def ssd_units(**units: dict) -> str:
    """An ssd:Units element: name -> BaseUnit attributes."""
    def base(attributes: dict) -> str:
        return " ".join(f'{k}="{v}"' for k, v in attributes.items())

    body = "".join(f'<ssc:Unit name="{n}"><ssc:BaseUnit {base(a)}/></ssc:Unit>' for n, a in units.items())
    return f"\n  <ssd:Units>{body}</ssd:Units>"


def parameter_set(values: dict[str, tuple[float, str | None]], units: str = "") -> str:
    """Inline ssd:ParameterBindings: name -> (value, unit or None)."""
    params = "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v!r}"' + (f' unit="{u}"' if u else "")
                     + "/></ssv:Parameter>" for n, (v, u) in values.items())
    return ('\n        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
            f'<ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>{params}</ssv:Parameters>{units}'
            '</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>')


def system(folder: Path, built: dict[str, Path], src_units: dict, dst_units: dict, connections: list[str], *,
           src_connectors: dict[str, str | None] | None = None, dst_connectors: dict[str, str | None] | None = None,
           units: str = "", bindings: str = "", src_definitions: dict | None = None) -> Path:
    """A scenario folder: src (UnitSource) wired to dst (UnitSink), the connectors' SSD units given
    by ``src_connectors``/``dst_connectors`` (name -> ssc:Real unit or None)."""
    resources = folder / "resources"
    with_units(built["UnitSource"], resources / "src.fmu", src_units, src_definitions)
    with_units(built["UnitSink"], resources / "dst.fmu", dst_units)
    src_connectors = src_connectors or {f"y{i}": None for i in (1, 2, 3)}
    dst_connectors = dst_connectors or {f"u{i}": None for i in (1, 2, 3)}
    text = SSD.format(
        src="".join(connector(n, "output", u) for n, u in src_connectors.items()),
        dst="".join(connector(n, "input", u) for n, u in dst_connectors.items())
        + "".join(connector(f"v{i}", "output") for i in (1, 2, 3)),
        connections="".join(connections), units=units, bindings=bindings)
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def simulate(folder: Path) -> tuple[np.ndarray, dict]:
    prepared = prepare(folder, use_providers=False)
    try:
        return run(prepared, output=folder / "result.csv")
    finally:
        prepared.close()


def assert_every_sample(actual: np.ndarray, expected: np.ndarray) -> None:
    assert len(actual) == 11
    np.testing.assert_allclose(actual, expected, rtol=1e-12, atol=1e-12)


# --------------------------------------------------------------------------- unit math

def unit(name: str):
    return BUILTIN[name]


def convert(value: float, src: str, dst: str) -> float:
    return conversion(unit(src), unit(dst)).apply(value)


def test_celsius_kelvin_fahrenheit_both_ways():
    assert convert(0.0, "degC", "K") == 273.15
    assert convert(373.15, "K", "degC") == pytest.approx(100.0, abs=1e-12)
    assert convert(212.0, "degF", "degC") == pytest.approx(100.0, abs=1e-12)
    assert convert(-40.0, "degC", "degF") == pytest.approx(-40.0, abs=1e-12)
    assert convert(32.0, "degF", "K") == pytest.approx(273.15, abs=1e-12)
    assert convert(convert(36.6, "degC", "degF"), "degF", "degC") == pytest.approx(36.6, abs=1e-12)


def test_pressure_percent_and_process_units():
    assert conversion(unit("kgf/cm2"), unit("MPa")) == Affine(pytest.approx(0.0980665, rel=1e-15), 0.0)
    assert conversion(unit("kgf/cm²"), unit("kgf/cm2")) == IDENTITY
    assert convert(1.0, "MPa", "kgf/cm2") == pytest.approx(1 / 0.0980665, rel=1e-15)
    assert convert(1.0, "bar", "kPa") == pytest.approx(100.0, rel=1e-15)
    assert convert(50.0, "%", "1") == pytest.approx(0.5, rel=1e-15)
    assert convert(0.25, "1", "%") == pytest.approx(25.0, rel=1e-15)
    assert convert(36.0, "t/h", "kg/s") == pytest.approx(10.0, rel=1e-15)
    assert convert(2.0, "h", "min") == pytest.approx(120.0, rel=1e-15)
    assert convert(0.16, "MW", "kW") == pytest.approx(160.0, rel=1e-15)


def test_conversion_then_linear_transformation_compose_into_one_affine_map():
    composed = conversion(unit("degC"), unit("K")).then(Affine(2.0, 1.0))   # SSP: convert first, then factor·x + offset
    assert isinstance(composed, Affine) and composed.apply(25.0) == pytest.approx(2.0 * (25.0 + 273.15) + 1.0, rel=1e-15)
    assert IDENTITY.then(Affine(3.0, -1.0)) == Affine(3.0, -1.0)


def test_different_dimensions_are_refused_naming_both_units_and_dimensions():
    with pytest.raises(SetupError) as e:
        conversion(unit("degC"), unit("MPa"))
    assert "'degC' (K)" in str(e.value) and "'MPa' (kg·m^-1·s^-2)" in str(e.value)
    with pytest.raises(SetupError, match=r"'%' \(1\).*'s' \(s\)"):
        conversion(unit("%"), unit("s"))
    assert make_unit("rate", factor=0.01, s=-1).dimension == "s^-1"


# --------------------------------------------------------------------------- runs through the master

PROCESS = ({"y1": "degC", "y2": "kgf/cm2", "y3": "%", "a1": "degC", "a2": "kgf/cm2", "a3": "%"},
           {"u1": "K", "u2": "MPa", "u3": "1", "v1": "K", "v2": "MPa", "v3": "1"})


def test_connections_convert_celsius_pressure_and_percent_at_every_sample(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1"), wire("y2", "u2"), wire("y3", "u3")])
    r, meta = simulate(folder)
    for i, (a, b) in enumerate(((1.0, 273.15), (98066.5 / 1e6, 0.0), (0.01, 0.0)), start=1):
        assert_every_sample(r[f"dst.u{i}"], a * r[f"src.y{i}"] + b)
        assert_every_sample(r[f"dst.v{i}"], a * r[f"src.y{i}"] + b)   # what the FMU received, read back
    assert_every_sample(r["src.y1"], 20.0 + r["time"])                # recorded in the FMU's own unit
    assert meta["units"]["src.y2"] == "kgf/cm2" and meta["units"]["dst.u2"] == "MPa"
    assert json.loads((folder / "result.json").read_text())["units"]["dst.v1"] == "K"


def test_linear_transformation_applies_after_the_conversion_and_alone_when_suppressed(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS,
                    [wire("y1", "u1", lt=(2.0, 1.0)), wire("y2", "u2", lt=(1e-6, 0.0), suppress=True),
                     wire("y3", "u3", suppress=True)])
    r, _ = simulate(folder)
    assert_every_sample(r["dst.v1"], 2.0 * (r["src.y1"] + 273.15) + 1.0)
    assert_every_sample(r["dst.v2"], 1e-6 * r["src.y2"])
    assert_every_sample(r["dst.v3"], r["src.y3"])


def test_a_unit_missing_on_one_end_or_the_same_on_both_is_not_converted(tmp_path, built):
    folder = system(tmp_path, built, {"y1": "degC", "y2": "%"}, {"u2": "%", "v2": "%"},
                    [wire("y1", "u1"), wire("y2", "u2"), wire("y3", "u3")])
    r, meta = simulate(folder)
    for i in (1, 2, 3):
        assert_every_sample(r[f"dst.v{i}"], r[f"src.y{i}"])
    assert meta["units"]["dst.u1"] is None and meta["units"]["src.y1"] == "degC"


def test_ssd_connector_unit_is_a_view_of_the_fmu_variable(tmp_path, built):
    """src.y1 is in degC in the FMU, the SSD connector shows it in K; dst.u1 is in K.  With
    suppressUnitConversion the LinearTransformation works on the connectors' values (K here),
    so the view's conversion still applies.  dst's connector u2 shows an MPa input in bar; the
    unit comes from the built-in table (neither file defines bar)."""
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1", lt=(1.0, -273.15), suppress=True),
                                                wire("y2", "u2"), wire("y3", "u3")],
                    src_connectors={"y1": "K", "y2": None, "y3": None},
                    dst_connectors={"u1": None, "u2": "bar", "u3": None})
    r, meta = simulate(folder)
    assert_every_sample(r["dst.v1"], r["src.y1"])              # degC -> view K, -273.15 -> K input
    assert_every_sample(r["dst.v2"], 0.0980665 * r["src.y2"])  # kgf/cm2 -> bar -> MPa
    assert meta["units"]["src.y1"] == "degC"                    # recorded in the FMU's unit, not the view's


def test_ssd_connector_unit_gives_a_unit_to_a_variable_without_one(tmp_path, built):
    folder = system(tmp_path, built, {}, {"u1": "K", "v1": "K"}, [wire("y1", "u1")],
                    src_connectors={"y1": "degC"}, dst_connectors={"u1": None})
    r, meta = simulate(folder)
    assert_every_sample(r["dst.v1"], r["src.y1"] + 273.15)
    assert meta["units"]["src.y1"] == "degC"                    # the unit the SSD gives it


def test_parameter_values_are_converted_to_the_variables_unit(tmp_path, built):
    """a1 (degC) given in K, a2 (kgf/cm2) in MPa inline in the SSD, a3 (%) in a custom unit of the
    parameter set's own ssv:Units; b (no unit) given in s is set as it is."""
    bindings = parameter_set({"a1": (300.0, "K"), "a2": (1.0, "MPa"), "a3": (0.5, "permille"), "b": (2.0, "s")},
                             units='<ssv:Units><ssc:Unit name="permille"><ssc:BaseUnit factor="0.001"/></ssc:Unit>'
                                   '</ssv:Units>')
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")], bindings=bindings)
    r, meta = simulate(folder)
    assert meta["parameters"]["src.a1"] == pytest.approx(300.0 - 273.15, abs=1e-12)
    assert_every_sample(r["src.y1"], 300.0 - 273.15 + 2.0 * r["time"])
    assert_every_sample(r["src.y2"], 1e6 / 98066.5 + 2.0 * r["time"])
    assert_every_sample(r["src.y3"], 0.05 + 2.0 * r["time"])


def test_parameter_set_file_value_with_unit(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")])
    ssv = tmp_path / "hot.ssv"
    ssv.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet version="1.0" name="hot" '
                   'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
                   'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"><ssv:Parameters>'
                   '<ssv:Parameter name="src.a1"><ssv:Real value="212" unit="degF"/></ssv:Parameter>'
                   '</ssv:Parameters></ssv:ParameterSet>\n')
    prepared = prepare(folder, parameter_sets=[ssv], use_providers=False)
    try:
        values = {f"{s.component}.{s.variable.name}": s.value for s in prepared.plan.start_values}
    finally:
        prepared.close()
    assert values["src.a1"] == pytest.approx(100.0, abs=1e-12)


def test_ssd_units_define_a_unit_for_connectors(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y2", "u2")],
                    dst_connectors={"u2": "mbar"},
                    units=ssd_units(mbar={"kg": 1, "m": -1, "s": -2, "factor": 100}))
    r, _ = simulate(folder)
    assert_every_sample(r["dst.v2"], 0.0980665 * r["src.y2"])


# --------------------------------------------------------------------------- refusals

def refused(folder: Path) -> str:
    with pytest.raises(SetupError) as e:
        prepare(folder, use_providers=False).close()
    return str(e.value)


def test_connection_between_different_dimensions_is_refused(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u2")])
    text = refused(folder)
    assert "SystemStructure.ssd" in text and "connection src.y1 -> dst.u2" in text and "variable 'u2'" in text
    assert "'degC' (K)" in text and "'MPa' (kg·m^-1·s^-2)" in text and "suppressUnitConversion" in text


def test_suppressed_conversion_accepts_different_dimensions(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u2", lt=(0.5, 0.0), suppress=True)])
    r, _ = simulate(folder)
    assert_every_sample(r["dst.v2"], 0.5 * r["src.y1"])


def test_ssd_connector_of_another_dimension_is_refused(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")],
                    src_connectors={"y1": "MPa", "y2": None, "y3": None})
    text = refused(folder)
    assert "ssd:Connector 'y1' of component 'src'" in text and "variable 'y1'" in text
    assert "'MPa'" in text and "'degC'" in text and "dimensions differ" in text


def test_parameter_value_of_another_dimension_is_refused(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")], bindings=parameter_set({"a1": (1.0, "bar")}))
    text = refused(folder)
    assert "ssv:Parameter 'a1'" in text and "variable 'a1'" in text
    assert "'bar' (kg·m^-1·s^-2)" in text and "'degC' (K)" in text


def test_ssd_and_fmu_defining_a_unit_differently_are_refused_naming_both_files(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")], units=ssd_units(degC={"K": 1, "offset": 273}))
    text = refused(folder)
    assert "unit 'degC' is defined differently" in text
    assert str(folder / "SystemStructure.ssd") in text and "src.fmu" in text
    assert "273.15" in text and "273" in text


def test_two_fmus_defining_the_same_unit_name_differently_are_refused(tmp_path, built):
    folder = system(tmp_path, built, {"y3": "%"}, {"u3": "%", "v3": "%"}, [wire("y3", "u3")],
                    src_definitions={"%": {"factor": "1"}})
    text = refused(folder)
    assert "unit '%' is defined differently in src.fmu" in text and "dst.fmu" in text


def test_an_undefined_unit_is_refused(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")],
                    src_connectors={"y1": "furlong", "y2": None, "y3": None})
    text = refused(folder)
    assert "unit 'furlong' is not defined" in text and "ssd:Units" in text


def test_builtin_factors_are_the_documented_ones():
    """Each built-in factor against its definition (SI Brochure / NIST SP 811), independently typed."""
    expected = {"degF": (5 / 9, 255.3722222222222), "kgf/cm2": (98066.5, 0.0), "bar": (1e5, 0.0),
                "t/h": (1 / 3.6, 0.0), "min": (60.0, 0.0), "MW": (1e6, 0.0), "%": (0.01, 0.0)}
    for name, (factor, offset) in expected.items():
        assert math.isclose(BUILTIN[name].factor, factor, rel_tol=1e-15), name
        assert math.isclose(BUILTIN[name].offset, offset, rel_tol=1e-15, abs_tol=0.0), name


def test_units_demo_scenario_converts_between_our_fmus(built_fmus):
    """ssp/units_demo: BoilerTurbine (kgf/cm2, MW, mm, %) read in MPa, kW and m, driven by a
    fraction, the step time given in min — no LinearTransformation in the SSD."""
    prepared = prepare("ssp/units_demo")
    try:
        r, meta = run(prepared)
    finally:
        prepared.close()
    assert meta["parameters"]["disturbance.t_step"] == pytest.approx(30.0, rel=1e-15)
    np.testing.assert_allclose(r["boiler.fuel_disturbance"], 100.0 * r["disturbance.y"], rtol=1e-12, atol=1e-12)
    assert r["boiler.fuel_disturbance"][-1] == pytest.approx(5.0, rel=1e-12)
    for gain, source, factor in (("pressure", "P", 0.0980665), ("power", "E", 1000.0), ("level", "L", 1e-3)):
        np.testing.assert_allclose(r[f"{gain}.y"], factor * r[f"boiler.{source}"], rtol=1e-12, atol=1e-12)
    assert r["boiler.P"][0] == 109.0 and np.ptp(r["boiler.P"][r["time"] <= 30.0]) < 1e-9
    assert r["boiler.P"][-1] > 110.0                                      # the fuel step did arrive, as 5 %
    assert meta["units"]["boiler.P"] == "kgf/cm2" and meta["units"]["pressure.y"] == "MPa"


def test_units_demo_parameter_set_in_kw_m_and_fractions_holds_58_mw(built_fmus):
    """operating_point.ssv: load0 in kW, L0 in m, valve positions as fractions (its own ssv:Units);
    converted, they are the 58 MW equilibrium at 86 kgf/cm2 (thesis ch. 4 table)."""
    prepared = prepare("ssp/units_demo", stop_time=30.0, parameter_sets=["ssp/units_demo/operating_point.ssv"])
    try:
        r, meta = run(prepared)
    finally:
        prepared.close()
    p = meta["parameters"]
    assert (p["boiler.load0"], p["boiler.L0"]) == (pytest.approx(58.0, rel=1e-15), pytest.approx(-100.0, rel=1e-15))
    assert p["boiler.fuel"] == pytest.approx(28.908403, rel=1e-15)
    assert r["boiler.P"][0] == pytest.approx(86.0, abs=1e-6) and np.ptp(r["boiler.P"]) < 1e-6
    assert r["pressure.y"][0] == pytest.approx(86.0 * 0.0980665, abs=1e-6)


def test_a_unit_with_factor_zero_is_refused(tmp_path, built):
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")], units=ssd_units(nothing={"factor": 0}))
    text = refused(folder)
    assert "ssc:Unit 'nothing'" in text and "non-zero" in text


def test_parameter_set_and_ssd_defining_a_unit_differently_are_refused(tmp_path, built):
    local = '<ssv:Units><ssc:Unit name="mbar"><ssc:BaseUnit kg="1" m="-1" s="-2" factor="1000"/></ssc:Unit></ssv:Units>'
    folder = system(tmp_path, built, *PROCESS, [wire("y1", "u1")],
                    bindings=parameter_set({"a2": (5.0, "mbar")}, units=local),
                    units=ssd_units(mbar={"kg": 1, "m": -1, "s": -2, "factor": 100}))
    text = refused(folder)
    assert "unit 'mbar' is defined differently" in text and "ssv:Parameter 'a2'" in text
    assert "100·kg·m^-1·s^-2" in text and "1000·kg·m^-1·s^-2" in text
