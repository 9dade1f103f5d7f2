"""SSP 1.0 parameter mappings (.ssm files and inline ssm:ParameterMapping), SSP 2.0 documents and
signal dictionaries, on small systems written as the standard's examples write them.

Each system is a Step FMU ``src`` (stepping at t = 0 to ``final``) feeding a Gain FMU ``g``
(``y = k * u``), the C twins of ours (tests/twin_fmus.py): the value the Gain really got is
read back from the results, ``g.y = k * final``.
"""
from __future__ import annotations

import shutil
import zipfile

import pytest

import cosim
from cosim.read import ssp
from cosim.cli import main
from cosim.errors import SetupError
from tablefmus import VARIABLES as TABLE_VARIABLES, build_tables_fmu

SSD_NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
          'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
          'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"')
SSV_NS = ('xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"')
SSM_NS = ('xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"')
STEP = "<ssd:Annotations><ssc:Annotation type=\"org.greyfmu.simulation\"><greyfmu:Simulation " \
       "xmlns:greyfmu=\"urn:greyfmu:ssp:simulation:1.0\" stepSize=\"0.1\"/></ssc:Annotation></ssd:Annotations>"


def ssd(system_bindings: str = "", gain_bindings: str = "", version: str = "1.0", real: str = "Real",
        inner: bool = False) -> str:
    """The SSD: src -> g at the root, or (``inner``) both inside subsystem ``sub``."""
    components = (
        '<ssd:Component name="src" source="resources/Step.fmu"><ssd:Connectors>'
        f'<ssd:Connector name="y" kind="output"><ssc:{real}/></ssd:Connector></ssd:Connectors>'
        '<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
        f'<ssv:ParameterSet version="{version}" name="step"><ssv:Parameters>'
        f'<ssv:Parameter name="t_step"><ssv:{real} value="0"/></ssv:Parameter>'
        f'<ssv:Parameter name="final"><ssv:{real} value="3"/></ssv:Parameter>'
        '</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>'
        '</ssd:Component>'
        '<ssd:Component name="g" source="resources/Gain.fmu"><ssd:Connectors>'
        f'<ssd:Connector name="u" kind="input"><ssc:{real}/></ssd:Connector>'
        f'<ssd:Connector name="y" kind="output"><ssc:{real}/></ssd:Connector></ssd:Connectors>'
        f'{gain_bindings}</ssd:Component>')
    links = ('<ssd:Connections><ssd:Connection startElement="src" startConnector="y" endElement="g" '
             'endConnector="u"/></ssd:Connections>')
    if inner:
        body = (f'<ssd:Elements><ssd:System name="sub"><ssd:Elements>{components}</ssd:Elements>{links}'
                '</ssd:System></ssd:Elements>')
    else:
        body = f"<ssd:Elements>{components}</ssd:Elements>{links}"
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {SSD_NS} '
            f'version="{version}" name="mapped"><ssd:System name="root">{system_bindings}{body}</ssd:System>'
            f'<ssd:DefaultExperiment startTime="0" stopTime="0.3">{STEP}</ssd:DefaultExperiment>'
            '</ssd:SystemStructureDescription>\n')


def ssv(params: dict[str, float], version: str = "1.0", kind: str = "Real", units: str = "") -> str:
    body = "".join(f'<ssv:Parameter name="{n}"><ssv:{kind} value="{v}"/></ssv:Parameter>' for n, v in params.items())
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet {SSV_NS} version="{version}" name="set">'
            f'<ssv:Parameters>{body}</ssv:Parameters>{units}</ssv:ParameterSet>\n')


def ssm(entries: str, version: str = "1.0") -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssm:ParameterMapping {SSM_NS} version="{version}">'
            f'{entries}</ssm:ParameterMapping>\n')


def binding(source: str = "", mapping: str = "", prefix: str = "", inline: str = "") -> str:
    attrs = (f' source="{source}"' if source else "") + (f' prefix="{prefix}"' if prefix else "")
    values = f"<ssd:ParameterValues>{inline}</ssd:ParameterValues>" if inline else ""
    return (f"<ssd:ParameterBindings><ssd:ParameterBinding{attrs}>{values}{mapping}</ssd:ParameterBinding>"
            "</ssd:ParameterBindings>")


@pytest.fixture(scope="module")
def fmus(twin_fmus):
    return {"Step.fmu": twin_fmus["Step"], "Gain.fmu": twin_fmus["Gain"]}


def _system(tmp_path, fmus, text: str, **files: str):
    folder = tmp_path / "sys"
    (folder / "resources").mkdir(parents=True)
    for name, path in fmus.items():
        shutil.copy(path, folder / "resources" / name)
    (folder / "SystemStructure.ssd").write_text(text)
    for name, content in files.items():
        (folder / name.replace("__", ".")).write_text(content)
    return folder


def _gain_output(folder) -> float:
    return float(cosim.simulate(folder)["g.y"][-1])


def test_ssm_file_renames_the_parameter_set(tmp_path, fmus):
    """A .ssv for another naming scheme, applied to the Gain through a .ssm file (SSP 1.0 §5.2.3):
    only the mapped value is applied, under its target name."""
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding(
        "gain.ssv", '<ssd:ParameterMapping source="gain.ssm"/>')),
        gain__ssv=ssv({"Gain_Factor": 2.5, "Unmapped": 7.0}),
        gain__ssm=ssm('<ssm:MappingEntry source="" target="k"/><ssm:MappingEntry source="Gain_Factor" target="k"/>'))
    assert _gain_output(folder) == pytest.approx(3 * 2.5)  # the empty source (OMSimulator's templates) maps nothing
    assert main(["validate", str(folder)]) == 0
    prepared = cosim.prepare(folder)
    origin = {s.variable.name: s.origin for s in prepared.plan.start_values if s.component == "g"}["k"]
    prepared.close()
    assert "gain.ssv:2, mapped by ssm:MappingEntry 'Gain_Factor' -> 'k'" in origin and "gain.ssm, line 2" in origin


def test_unmapped_names_are_not_applied(tmp_path, fmus):
    """Without the mapping, 'Unmapped' would be refused as unknown; with it, it is not applied at all."""
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv")), gain__ssv=ssv({"Unmapped": 7.0}))
    with pytest.raises(SetupError, match="Unmapped"):
        cosim.simulate(folder)


def test_inline_mapping_with_linear_transformation(tmp_path, fmus):
    inline = ('<ssd:ParameterMapping><ssm:ParameterMapping version="1.0"><ssm:MappingEntry source="gain_percent" '
              'target="k"><ssc:LinearTransformation factor="0.01" offset="0.5"/></ssm:MappingEntry>'
              '</ssm:ParameterMapping></ssd:ParameterMapping>')
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv", inline)),
                     gain__ssv=ssv({"gain_percent": 150.0}))
    assert _gain_output(folder) == pytest.approx(3 * (0.01 * 150 + 0.5))


def test_one_source_to_two_targets_with_prefix_at_system_level(tmp_path, fmus):
    """A system-level binding with prefix 'g.': the prefix is prepended to the source names before
    the mapping (SSP 1.0 ParameterBinding prefix), so entries name 'g.gain'; one source may map to
    two targets."""
    mapping = ('<ssd:ParameterMapping><ssm:ParameterMapping version="1.0">'
               '<ssm:MappingEntry source="g.gain" target="g.k"/>'
               '<ssm:MappingEntry source="g.gain" target="src.final"/>'
               '</ssm:ParameterMapping></ssd:ParameterMapping>')
    folder = _system(tmp_path, fmus, ssd(system_bindings=binding("sys.ssv", mapping, prefix="g.")),
                     sys__ssv=ssv({"gain": 4.0}))
    assert _gain_output(folder) == pytest.approx(4.0 * 4.0)


def test_outer_mapped_binding_overrides_inner_inline_value(tmp_path, fmus):
    """Nested systems: the root's mapped binding beats the inline value on the Gain inside 'sub'
    (SSP 1.0: bindings at a higher hierarchy level take precedence)."""
    inner = binding(inline='<ssv:ParameterSet version="1.0" name="i"><ssv:Parameters><ssv:Parameter name="k">'
                           '<ssv:Real value="9"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    outer = binding("outer.ssv", '<ssd:ParameterMapping source="outer.ssm"/>')
    text = ssd(system_bindings=outer, gain_bindings=inner, inner=True)
    folder = _system(tmp_path, fmus, text, outer__ssv=ssv({"K": 0.5}),
                     outer__ssm=ssm('<ssm:MappingEntry source="K" target="sub.g.k"/>'))
    assert float(cosim.simulate(folder)["sub.g.y"][-1]) == pytest.approx(3 * 0.5)
    (folder / "outer.ssm").write_text(ssm(""))  # an empty mapping applies nothing: the inner value stays
    assert float(cosim.simulate(folder)["sub.g.y"][-1]) == pytest.approx(3 * 9.0)


def test_linear_transformation_follows_the_unit_conversion(tmp_path, fmus):
    """SSP 1.0 MappingEntry: units are converted first, then the LinearTransformation; with
    suppressUnitConversion the transformation replaces the conversion."""
    units = ('<ssv:Units><ssc:Unit name="ms"><ssc:BaseUnit s="1" factor="0.001"/></ssc:Unit></ssv:Units>')
    pset = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<ssv:ParameterSet {SSV_NS} version="1.0" name="set"><ssv:Parameters><ssv:Parameter name="delay">'
            f'<ssv:Real value="500" unit="ms"/></ssv:Parameter></ssv:Parameters>{units}</ssv:ParameterSet>\n')

    def start(suppress: str) -> float:
        entry = (f'<ssm:MappingEntry source="delay" target="src.t_step"{suppress}>'
                 '<ssc:LinearTransformation factor="2" offset="0.25"/></ssm:MappingEntry>')
        folder = _system(tmp_path / ("suppressed" if suppress else "converted"), fmus, ssd(system_bindings=binding("set.ssv", '<ssd:ParameterMapping source="m.ssm"/>')),
                         set__ssv=pset, m__ssm=ssm(entry))
        prepared = cosim.prepare(folder)
        try:
            return {(s.component, s.variable.name): s.value for s in prepared.plan.start_values}[("src", "t_step")]
        finally:
            prepared.close()

    assert start("") == pytest.approx(2 * 0.5 + 0.25)  # 500 ms -> 0.5 s, then 2x + 0.25
    assert start(' suppressUnitConversion="true"') == pytest.approx(2 * 500 + 0.25)


def test_mapped_value_with_a_unit_for_a_system_connector(tmp_path, fmus):
    """A mapped value given in ms for the root's undriven input connector 'r' (unit s) feeding g.u:
    converted to the connector's unit first, then the LinearTransformation (SSP 1.0 MappingEntry)."""
    units = '<ssd:Units><ssc:Unit name="s"><ssc:BaseUnit s="1"/></ssc:Unit>' \
            '<ssc:Unit name="ms"><ssc:BaseUnit s="1" factor="0.001"/></ssc:Unit></ssd:Units>'
    mapping = ('<ssd:ParameterMapping><ssm:ParameterMapping version="1.0"><ssm:MappingEntry source="delay" '
               'target="r"><ssc:LinearTransformation factor="2" offset="0.25"/></ssm:MappingEntry>'
               '</ssm:ParameterMapping></ssd:ParameterMapping>')
    pset = ('<ssv:ParameterSet version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="delay">'
            '<ssv:Real value="500" unit="ms"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    text = ssd(system_bindings='<ssd:Connectors><ssd:Connector name="r" kind="input"><ssc:Real unit="s"/>'
                               '</ssd:Connector></ssd:Connectors>' + binding(mapping=mapping, inline=pset))
    text = text.replace('startElement="src" startConnector="y"', 'startConnector="r"')
    text = text.replace("<ssd:DefaultExperiment", units + "<ssd:DefaultExperiment")
    assert _gain_output(_system(tmp_path, fmus, text)) == pytest.approx(2 * 0.5 + 0.25)
    unitless = _system(tmp_path / "unitless", fmus, text.replace('<ssc:Real unit="s"/>', "<ssc:Real/>"))
    with pytest.raises(SetupError, match="system connector 'r' declares no unit") as err:
        cosim.simulate(unitless)
    assert "mapped by ssm:MappingEntry 'delay' -> 'r'" in str(err.value)


def test_integer_mapping_transformation_to_a_real_variable(tmp_path, fmus):
    """An ssv:Integer through an ssc:IntegerMappingTransformation to the Gain's Real k (an Integer
    value is accepted for a Real variable)."""
    table = ('<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="5"/>'
             '<ssc:MapEntry source="2" target="6"/></ssc:IntegerMappingTransformation>')
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv", '<ssd:ParameterMapping source="g.ssm"/>')),
                     gain__ssv=ssv({"mode": 2}, kind="Integer"),
                     g__ssm=ssm(f'<ssm:MappingEntry source="mode" target="k">{table}</ssm:MappingEntry>'))
    assert _gain_output(folder) == pytest.approx(3 * 6)


def tables_ssd(bindings: str) -> str:
    """One ``Tables`` FMU (tests/tablefmus.py) ``m``, its connectors declared, with ``bindings``."""
    connectors = "".join(f'<ssd:Connector name="{name}" kind="{causality}"><ssc:{kind}'
                         + (' name="Level"/>' if kind == "Enumeration" else "/>") + "</ssd:Connector>"
                         for name, _, kind, causality in TABLE_VARIABLES if causality != "input")
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {SSD_NS} version="1.0" '
            'name="tables"><ssd:System name="root"><ssd:Elements>'
            f'<ssd:Component name="m" source="resources/Tables.fmu"><ssd:Connectors>{connectors}</ssd:Connectors>'
            f'{bindings}</ssd:Component></ssd:Elements></ssd:System>'
            '<ssd:Enumerations><ssc:Enumeration name="Level"><ssc:Item name="low" value="1"/>'
            '<ssc:Item name="mid" value="2"/><ssc:Item name="high" value="3"/></ssc:Enumeration></ssd:Enumerations>'
            f'<ssd:DefaultExperiment startTime="0" stopTime="0.3">{STEP}</ssd:DefaultExperiment>'
            '</ssd:SystemStructureDescription>\n')


#: a parameter set in another tool's names and values (Mode 1/2, Enabled, Speed slow/fast) and the
#: .ssm that maps it onto Tables' count, on and level, as SSP 1.0 writes mapping tables
OTHER_TOOL_SSV = (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet {SSV_NS} version="1.0" name="other">'
                  '<ssv:Parameters>'
                  '<ssv:Parameter name="Mode"><ssv:Integer value="{mode}"/></ssv:Parameter>'
                  '<ssv:Parameter name="Enabled"><ssv:Boolean value="{enabled}"/></ssv:Parameter>'
                  '<ssv:Parameter name="Speed"><ssv:Enumeration value="{speed}"/></ssv:Parameter>'
                  '</ssv:Parameters></ssv:ParameterSet>\n')
TABLES_SSM = ssm(
    '<ssm:MappingEntry source="Mode" target="count"><ssc:IntegerMappingTransformation>'
    '<ssc:MapEntry source="1" target="10"/><ssc:MapEntry source="2" target="20"/>'
    '</ssc:IntegerMappingTransformation></ssm:MappingEntry>'
    '<ssm:MappingEntry source="Enabled" target="on"><ssc:BooleanMappingTransformation>'
    '<ssc:MapEntry source="true" target="false"/><ssc:MapEntry source="false" target="true"/>'
    '</ssc:BooleanMappingTransformation></ssm:MappingEntry>'
    '<ssm:MappingEntry source="Speed" target="level"><ssc:EnumerationMappingTransformation>'
    '<ssc:MapEntry source="slow" target="low"/><ssc:MapEntry source="fast" target="high"/>'
    '</ssc:EnumerationMappingTransformation></ssm:MappingEntry>')


@pytest.fixture(scope="module")
def tables_fmu(tmp_path_factory):
    return build_tables_fmu(tmp_path_factory.mktemp("tables"))


def _tables_system(tmp_path, fmu, **values) -> object:
    folder = tmp_path / "tables"
    (folder / "resources").mkdir(parents=True, exist_ok=True)
    shutil.copy(fmu, folder / "resources" / "Tables.fmu")
    (folder / "SystemStructure.ssd").write_text(tables_ssd(binding("other.ssv",
                                                 '<ssd:ParameterMapping source="tables.ssm"/>')))
    (folder / "other.ssv").write_text(OTHER_TOOL_SSV.format(**values))
    (folder / "tables.ssm").write_text(TABLES_SSM)
    return folder


@pytest.mark.parametrize("mode, enabled, speed, count, on, level", [
    (2, "true", "fast", 20, 0, 3),
    (1, "false", "slow", 10, 1, 1),
])
def test_integer_boolean_enumeration_tables_reach_the_fmu(tmp_path, tables_fmu, mode, enabled, speed, count, on,
                                                          level):
    """SSP 1.0 ssc:IntegerMappingTransformation, ssc:BooleanMappingTransformation and
    ssc:EnumerationMappingTransformation (by item name) in a .ssm: the FMU reports the mapped
    values of its Integer, Boolean and Enumeration parameters."""
    res = cosim.simulate(_tables_system(tmp_path, tables_fmu, mode=mode, enabled=enabled, speed=speed))
    assert list(res["m.count_out"]) == [count] * 4
    assert list(res["m.on_out"]) == [on] * 4
    assert list(res["m.level_out"]) == [level] * 4
    assert list(res["m.n"]) == [count + k for k in range(4)]


@pytest.mark.parametrize("values, message", [
    ({"mode": 3, "enabled": "true", "speed": "fast"},
     "ssm:MappingEntry 'Mode' -> 'count' (line 2), variable 'Mode': the value 3 of 'Mode'"),
    ({"mode": 1, "enabled": "true", "speed": "medium"},
     "ssm:MappingEntry 'Speed' -> 'level' (line 2), variable 'Speed': the value 'medium' of 'Speed'"),
])
def test_a_value_no_map_entry_names_is_refused(tmp_path, tables_fmu, capsys, values, message):
    folder = _tables_system(tmp_path, tables_fmu, **values)
    assert main(["run", str(folder), "-q"]) == 2
    err = capsys.readouterr().err
    assert "tables.ssm" in err and message in err and "is not a source of the ssc:" in err
    assert "Traceback" not in err


def test_boolean_and_enumeration_tables_as_read(tmp_path):
    """Boolean and Enumeration tables as read: the mapped values replace the values of the set."""
    (tmp_path / "b.ssv").write_text(
        f'<ssv:ParameterSet {SSV_NS} version="1.0" name="b"><ssv:Parameters>'
        '<ssv:Parameter name="on"><ssv:Boolean value="true"/></ssv:Parameter>'
        '<ssv:Parameter name="mode"><ssv:Enumeration value="fast"/></ssv:Parameter>'
        '</ssv:Parameters></ssv:ParameterSet>')
    (tmp_path / "b.ssm").write_text(ssm(
        '<ssm:MappingEntry source="on" target="c.enabled"><ssc:BooleanMappingTransformation>'
        '<ssc:MapEntry source="true" target="false"/></ssc:BooleanMappingTransformation></ssm:MappingEntry>'
        '<ssm:MappingEntry source="mode" target="c.mode"><ssc:EnumerationMappingTransformation>'
        '<ssc:MapEntry source="fast" target="Quick"/></ssc:EnumerationMappingTransformation></ssm:MappingEntry>'))
    text = (f'<ssd:SystemStructureDescription {SSD_NS} version="1.0" name="x"><ssd:System name="root">'
            + binding("b.ssv", '<ssd:ParameterMapping source="b.ssm"/>')
            + '</ssd:System></ssd:SystemStructureDescription>')
    (tmp_path / "SystemStructure.ssd").write_text(text)
    raw = ssp.read(tmp_path)
    assert [(p.name, p.value) for p in raw.root.parameters] == [("c.enabled", False), ("c.mode", "Quick")]


@pytest.mark.parametrize("entry, message", [
    ('<ssm:MappingEntry source="Gain" target="k"/>', "source 'Gain' is not a parameter"),
    ('<ssm:MappingEntry source="gain" target="k"/><ssm:MappingEntry source="gain" target="k"/>',
     "two mapping entries map to 'k'"),
    ('<ssm:MappingEntry source="gain" target="k"><ssc:BooleanMappingTransformation><ssc:MapEntry source="true" '
     'target="false"/></ssc:BooleanMappingTransformation></ssm:MappingEntry>',
     "ssc:BooleanMappingTransformation applies to ssv:Boolean values; 'gain' is an ssv:Real"),
    ('<ssm:MappingEntry source="gain" target="kk"/>', "kk"),
])
def test_mapping_errors_name_file_element_and_variable(tmp_path, fmus, capsys, entry, message):
    mapped = ssd(gain_bindings=binding("gain.ssv", '<ssd:ParameterMapping source="g.ssm"/>'))
    folder = _system(tmp_path, fmus, mapped, gain__ssv=ssv({"gain": 2.0}), g__ssm=ssm(entry))
    assert main(["run", str(folder), "-q"]) == 2
    err = capsys.readouterr().err
    assert message in err and ("g.ssm" in err or "gain.ssv" in err) and "MappingEntry" in err
    assert "Traceback" not in err


def test_mapping_source_is_confined_to_the_archive(tmp_path, fmus):
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv",
                     '<ssd:ParameterMapping source="../outside.ssm"/>')), gain__ssv=ssv({"gain": 2.0}))
    (tmp_path / "outside.ssm").write_text(ssm('<ssm:MappingEntry source="gain" target="k"/>'))
    archive = tmp_path / "a.ssp"
    with zipfile.ZipFile(archive, "w") as z:
        for f in folder.rglob("*"):
            z.write(f, f.relative_to(folder).as_posix())
    with pytest.raises(SetupError) as err:
        ssp.load(archive)
    assert "outside the .ssp archive" in str(err.value) and "ssd:ParameterMapping (line" in str(err.value)


def test_ssm_inside_an_archive_and_packed(tmp_path, fmus):
    """A .ssm member of an .ssp is read, and `cosim pack` packs the .ssm files beside the SSD."""
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv", '<ssd:ParameterMapping source="g.ssm"/>')),
                     gain__ssv=ssv({"gain": 2.0}), g__ssm=ssm('<ssm:MappingEntry source="gain" target="k"/>'))
    packed = tmp_path / "packed.ssp"
    assert main(["pack", str(folder), "-o", str(packed)]) == 0
    assert "g.ssm" in zipfile.ZipFile(packed).namelist()
    assert float(cosim.simulate(packed)["g.y"][-1]) == pytest.approx(6.0)


# --------------------------------------------------------------------------- SSP 2.0

def test_ssp2_system_with_fmi3_types(tmp_path, fmus):
    """An SSD in SSP 2.0 form (version="2.0", the SSP1 namespaces SSP 2.0 keeps, ssc:Float64
    connectors, ssv:Float64 values) with an SSP 2.0 .ssv and .ssm runs as its 1.0 equivalent."""
    folder = _system(tmp_path, fmus, ssd(gain_bindings=binding("gain.ssv", '<ssd:ParameterMapping source="g.ssm"/>'),
                                         version="2.0", real="Float64"),
                     gain__ssv=ssv({"gain": 1.5}, version="2.0", kind="Float64"),
                     g__ssm=ssm('<ssm:MappingEntry source="gain" target="k"/>', version="2.0"))
    assert _gain_output(folder) == pytest.approx(4.5)
    assert main(["validate", str(folder)]) == 0


def test_ssp1_file_with_ssp2_parameter_sets(tmp_path, fmus):
    """A 1.0 SSD whose inline parameter set and .ssv are SSP 2.0 (as a reference system mixes them)."""
    inline = ('<ssv:ParameterSet version="2.0" name="i"><ssv:Parameters><ssv:Parameter name="k">'
              '<ssv:Float32 value="0.25"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    text = ssd(gain_bindings=binding(inline=inline), system_bindings=binding("sys.ssv"))
    folder = _system(tmp_path, fmus, text, sys__ssv=ssv({"src.final": 8}, version="2.0", kind="Int32"))
    assert _gain_output(folder) == pytest.approx(8 * 0.25)


def test_ssp2_types_are_refused_in_a_1_0_document(tmp_path):
    (tmp_path / "p.ssv").write_text(ssv({"k": 1.0}, kind="Float64"))
    with pytest.raises(SetupError) as err:
        ssp.read_ssv(tmp_path / "p.ssv")
    assert "does not conform to the SSP 1.0 schema" in str(err.value) and "Float64" in str(err.value)


def test_ssp2_features_that_cannot_run_are_refused_by_element(tmp_path, fmus):
    text = ssd(version="2.0").replace('<ssd:Connector name="u" kind="input">',
                                      '<ssd:Connector name="u" kind="structuralParameter">')
    folder = _system(tmp_path, fmus, text)
    with pytest.raises(SetupError) as err:
        ssp.load(folder)
    message = str(err.value)
    assert "SSP 2.0 content this master cannot run" in message and "structuralParameter" in message
    assert "line 2: Element 'ssd:Connector', attribute 'kind'" in message and "SystemStructure.ssd" in message


# --------------------------------------------------------------------------- signal dictionaries

SSB_NS = ('xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssb="http://ssp-standard.org/SSP1/SystemStructureSignalDictionary"')
ENTRIES = '<ssb:DictionaryEntry name="sig"><ssc:Real/></ssb:DictionaryEntry>'


def bus_ssd(dictionary: str, inner: bool = False, writer: str = "sig", extra_link: str = "") -> str:
    """src.y -> reference 'w' (entry sig) ... reference 'r' (entry sig) -> g.u; the dictionary 'bus'
    declared at the root, the components and references at the root or (``inner``) in 'sub'."""
    refs = ('<ssd:SignalDictionaryReference name="w" dictionary="bus"><ssd:Connectors><ssd:Connector '
            f'name="{writer}" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:SignalDictionaryReference>'
            '<ssd:SignalDictionaryReference name="r" dictionary="bus"/>')
    text = ssd(inner=inner).replace('<ssd:Connection startElement="src" startConnector="y" endElement="g" '
                                    'endConnector="u"/>',
                                    f'<ssd:Connection startElement="src" startConnector="y" endElement="w" '
                                    f'endConnector="{writer}"/><ssd:Connection startElement="r" startConnector="sig" '
                                    f'endElement="g" endConnector="u"/>{extra_link}')
    text = text.replace('<ssd:Component name="src"', refs + '<ssd:Component name="src"')
    dictionaries = f"<ssd:SignalDictionaries>{dictionary}</ssd:SignalDictionaries>"
    marker = "</ssd:System></ssd:Elements>" if inner else "</ssd:Connections>"
    return text.replace(marker, marker + dictionaries, 1)


def test_signal_dictionary_inline_carries_a_signal(tmp_path, fmus):
    """SSP 1.0 §5.3.3: the Step writes entry 'sig' through reference 'w', the Gain reads it through 'r'."""
    inline = f'<ssd:SignalDictionary name="bus"><ssb:SignalDictionary {SSB_NS} version="1.0">{ENTRIES}' \
             '</ssb:SignalDictionary></ssd:SignalDictionary>'
    folder = _system(tmp_path, fmus, bus_ssd(inline))
    assert _gain_output(folder) == pytest.approx(3.0)
    assert main(["validate", str(folder)]) == 0


def test_signal_dictionary_from_ssb_found_in_an_enclosing_system(tmp_path, fmus):
    """References inside subsystem 'sub' find the dictionary of the root (lookup outwards); the
    dictionary is an .ssb file in SSP 2.0 form."""
    folder = _system(tmp_path, fmus, bus_ssd('<ssd:SignalDictionary name="bus" source="bus.ssb"/>', inner=True),
                     bus__ssb=f'<ssb:SignalDictionary {SSB_NS} version="2.0">'
                              '<ssb:DictionaryEntry name="sig"><ssc:Float64/></ssb:DictionaryEntry>'
                              '</ssb:SignalDictionary>')
    assert float(cosim.simulate(folder)["sub.g.y"][-1]) == pytest.approx(3.0)
    packed = tmp_path / "bus.ssp"
    assert main(["pack", str(folder), "-o", str(packed)]) == 0
    assert "bus.ssb" in zipfile.ZipFile(packed).namelist()
    assert float(cosim.simulate(packed)["sub.g.y"][-1]) == pytest.approx(3.0)


def test_signal_dictionary_reader_with_a_linear_transformation(tmp_path, fmus):
    """The connection from the dictionary to the reader keeps its LinearTransformation (composed
    along the chain src -> bus.sig -> g)."""
    inline = f'<ssd:SignalDictionary name="bus"><ssb:SignalDictionary {SSB_NS} version="1.0">{ENTRIES}' \
             '</ssb:SignalDictionary></ssd:SignalDictionary>'
    text = bus_ssd(inline).replace('endElement="g" endConnector="u"/>', 'endElement="g" endConnector="u">'
                                   '<ssc:LinearTransformation factor="2" offset="1"/></ssd:Connection>')
    assert _gain_output(_system(tmp_path, fmus, text)) == pytest.approx(2 * 3.0 + 1)


@pytest.mark.parametrize("change, message", [
    (lambda t: t.replace('dictionary="bus"/>', 'dictionary="bsu"/>'),
     "ssd:SignalDictionaryReference 'r' (line 2) in the root system 'root': no signal dictionary 'bsu'"),
    (lambda t: t.replace('startElement="r" startConnector="sig"', 'startElement="r" startConnector="sgi"'),
     "has no entry 'sgi'"),
    (lambda t: t.replace("</ssb:SignalDictionary>", '<ssb:Units><ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit>'
                         '</ssb:Units></ssb:SignalDictionary>'),
     "ssb:Units (line 2): units declared in a signal dictionary are not supported"),
    (lambda t: t.replace("</ssd:Connections>", '<ssd:Connection startElement="g" startConnector="y" endElement="w" '
                         'endConnector="sig"/></ssd:Connections>'),
     "system connector 'bus.sig' is driven by two connections"),
])
def test_signal_dictionary_errors_name_the_element(tmp_path, fmus, capsys, change, message):
    inline = f'<ssd:SignalDictionary name="bus"><ssb:SignalDictionary {SSB_NS} version="1.0">{ENTRIES}' \
             '</ssb:SignalDictionary></ssd:SignalDictionary>'
    folder = _system(tmp_path, fmus, change(bus_ssd(inline)))
    assert main(["validate", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "SystemStructure.ssd" in err and message in err and "Traceback" not in err


def _component_based(tmp_path, fmus, source: str, member: str = "resources/gain.ssv"):
    """The Gain's FMU carrying ``member`` (an .ssv), bound as SSP 1.0 §5.3.3 writes it:
    ``source`` relative to the component's FMU (``sourceBase="component"``)."""
    text = ssd(gain_bindings='<ssd:ParameterBindings><ssd:ParameterBinding sourceBase="component" '
               f'source="{source}"/></ssd:ParameterBindings>')
    folder = _system(tmp_path, fmus, text)
    with zipfile.ZipFile(folder / "resources" / "Gain.fmu", "a") as z:
        z.writestr(member, ssv({"k": 4.5}))
    (folder / "resources" / "gain.ssv").write_text(ssv({"k": 99.0}))   # beside the FMU: never the one read
    return folder


def test_a_component_based_binding_reads_the_ssv_inside_the_fmu(tmp_path, fmus):
    folder = _component_based(tmp_path, fmus, "resources/gain.ssv")
    assert _gain_output(folder) == pytest.approx(3 * 4.5)
    prepared = cosim.prepare(folder)
    origin = {s.variable.name: s.origin for s in prepared.plan.start_values if s.component == "g"}["k"]
    prepared.close()
    assert "Gain.fmu!/resources/gain.ssv" in origin


@pytest.mark.parametrize("source, message", [
    ("../gain.ssv", "escapes the archive"),
    ("/etc/passwd", "absolute path"),
    ("resources/other.ssv", "is not a file in the archive"),
])
def test_a_component_based_source_outside_the_fmu_is_refused(tmp_path, fmus, capsys, source, message):
    folder = _component_based(tmp_path, fmus, source)
    assert main(["validate", str(folder)]) == 2
    err = capsys.readouterr().err
    assert message in err and "SystemStructure.ssd" in err and "ssd:ParameterBinding (line" in err


def test_a_component_based_binding_on_a_system_is_refused(tmp_path, fmus, capsys):
    folder = _system(tmp_path, fmus, ssd(system_bindings='<ssd:ParameterBindings><ssd:ParameterBinding '
                                         'sourceBase="component" source="x.ssv"/></ssd:ParameterBindings>'))
    assert main(["validate", str(folder)]) == 2
    assert "sourceBase='component' needs a source and a component" in capsys.readouterr().err


INLINE_K = ('<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="i"><ssv:Parameters>'
            '<ssv:Parameter name="k"><ssv:Real value="2"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>'
            '</ssd:ParameterValues></ssd:ParameterBinding>')
INSIDE_K = ('<ssd:ParameterBinding sourceBase="component" source="resources/gain.ssv"><ssd:ParameterMapping>'
            f'<ssm:ParameterMapping {SSM_NS} version="1.0"><ssm:MappingEntry source="gain" target="k"/>'
            '</ssm:ParameterMapping></ssd:ParameterMapping></ssd:ParameterBinding>')


@pytest.mark.parametrize("bindings, k", [(INLINE_K + INSIDE_K, 4.5), (INSIDE_K + INLINE_K, 2.0)])
def test_a_component_based_binding_of_an_fmu_found_through_fmu_dir(tmp_path, fmus, capsys, monkeypatch, bindings, k):
    """The FMU is not beside the SSD but in a --fmu-dir folder: the .ssv is read from the FMU
    found there (once located), mapped, in its place among the component's bindings (later wins).
    The FMU providers are switched off: GainInside is no FMU of theirs (and greyfmu's needs pythonfmu)."""
    monkeypatch.setattr(cosim.read.resources, "providers", lambda: ([], []))
    text = ssd(gain_bindings=f"<ssd:ParameterBindings>{bindings}</ssd:ParameterBindings>")
    folder = _system(tmp_path, {"Step.fmu": fmus["Step.fmu"]}, text.replace("resources/Gain.fmu",
                                                                            "resources/GainInside.fmu"))
    elsewhere = tmp_path / "fmus"
    elsewhere.mkdir()
    shutil.copy(fmus["Gain.fmu"], elsewhere / "GainInside.fmu")
    with zipfile.ZipFile(elsewhere / "GainInside.fmu", "a") as z:
        z.writestr("resources/gain.ssv", ssv({"gain": 4.5}))
    assert float(cosim.simulate(folder, fmu_dirs=[elsewhere])["g.y"][-1]) == pytest.approx(3 * k)
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "-q", "--fmu-dir", str(elsewhere), "-o", str(out)]) == 0, capsys.readouterr().err
    with pytest.raises(SetupError, match="the FMU file 'resources/GainInside.fmu' was not found"):
        cosim.simulate(folder)
