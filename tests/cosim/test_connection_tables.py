"""SSP 1.0 mapping transformations on connections (SystemStructureCommon.xsd GTransformationChoice:
ssc:BooleanMappingTransformation, ssc:IntegerMappingTransformation,
ssc:EnumerationMappingTransformation as children of ssd:Connection), written as the standard
writes them, between two ``Tables`` C FMUs (tests/tablefmus.py): ``a``'s outputs change at every
step, ``b`` echoes its inputs, so ``b``'s echoes show the mapped values."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import cosim
from cosim.cli import main
from cosim.errors import RunError, SetupError
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from tablefmus import LEVELS, VARIABLES, build_tables_fmu

NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
      'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"')
STEP = ('<ssd:Annotations><ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation '
        'xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" stepSize="0.1"/></ssc:Annotation></ssd:Annotations>')

INTEGER = ('<ssc:IntegerMappingTransformation>'
           + "".join(f'<ssc:MapEntry source="{n}" target="{10 * n}"/>' for n in range(1, 5))
           + '</ssc:IntegerMappingTransformation>')
BOOLEAN = ('<ssc:BooleanMappingTransformation><ssc:MapEntry source="false" target="true"/>'
           '<ssc:MapEntry source="true" target="false"/></ssc:BooleanMappingTransformation>')
ENUMERATION = ('<ssc:EnumerationMappingTransformation><ssc:MapEntry source="low" target="high"/>'
               '<ssc:MapEntry source="mid" target="low"/><ssc:MapEntry source="high" target="mid"/>'
               '</ssc:EnumerationMappingTransformation>')


def _connectors() -> str:
    """Every input and output connector of Tables, typed (Enumerations naming their type ``Level``)."""
    return "".join(f'<ssd:Connector name="{name}" kind="{causality}"><ssc:{kind}'
                   + (' name="Level"/>' if kind == "Enumeration" else "/>") + "</ssd:Connector>"
                   for name, _, kind, causality in VARIABLES if causality != "parameter")


def _end(kind: str, path: str) -> str:
    """``startElement``/``startConnector`` (``kind`` "start") of ``element.connector``, or of a
    connector of the enclosing system (no element)."""
    element, connector = path.rsplit(".", 1) if "." in path else ("", path)
    return (f' {kind}Element="{element}"' if element else "") + f' {kind}Connector="{connector}"'


def _connection(start: str, end: str, transformation: str) -> str:
    return f"<ssd:Connection{_end('start', start)}{_end('end', end)}>{transformation}</ssd:Connection>"


def _component(name: str) -> str:
    return (f'<ssd:Component name="{name}" source="resources/Tables.fmu"><ssd:Connectors>{_connectors()}'
            '</ssd:Connectors></ssd:Component>')


def _ssd(body: str) -> str:
    items = "".join(f'<ssc:Item name="{n}" value="{v}"/>' for n, v in LEVELS.items())
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {NS} version="1.0" '
            f'name="tables"><ssd:System name="root">{body}</ssd:System>'
            f'<ssd:Enumerations><ssc:Enumeration name="Level">{items}</ssc:Enumeration></ssd:Enumerations>'
            f'<ssd:DefaultExperiment startTime="0" stopTime="0.3">{STEP}</ssd:DefaultExperiment>'
            '</ssd:SystemStructureDescription>\n')


def flat_ssd(integer: str = INTEGER, boolean: str = BOOLEAN, enumeration: str = ENUMERATION) -> str:
    links = (_connection("a.n", "b.n_in", integer) + _connection("a.flag", "b.flag_in", boolean)
             + _connection("a.mode", "b.mode_in", enumeration))
    return _ssd(f"<ssd:Elements>{_component('a')}{_component('b')}</ssd:Elements>"
                f"<ssd:Connections>{links}</ssd:Connections>")


@pytest.fixture(scope="module")
def tables_fmu(tmp_path_factory):
    return build_tables_fmu(tmp_path_factory.mktemp("tables"))


def _system(tmp_path, fmu, text: str):
    folder = tmp_path / "sys"
    (folder / "resources").mkdir(parents=True, exist_ok=True)
    shutil.copy(fmu, folder / "resources" / "Tables.fmu")
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def _run(folder, kernel: str):
    prepared = prepare(folder)
    try:
        return run(prepared, kernel=kernel, journal=False)
    finally:
        prepared.close()


#: a.n = 1 + k, a.flag = k odd, a.mode = k mod 3 + 1 (low, mid, high, low) at the 4 points
N, FLAG, MODE = [1, 2, 3, 4], [0, 1, 0, 1], [1, 2, 3, 1]


def test_integer_boolean_enumeration_tables_on_connections(tmp_path, tables_fmu):
    """Each table maps the value on its connection; the Enumeration one by item name (low → high,
    mid → low, high → mid).  The compiled loop maps them itself (issue 40: it handed every table
    to Python), the same values as the Python loop."""
    folder = _system(tmp_path, tables_fmu, flat_ssd())
    res, meta = _run(folder, "auto")
    assert list(res["a.n"]) == N and list(res["a.flag"]) == FLAG and list(res["a.mode"]) == MODE
    assert list(res["b.n_echo"]) == [10 * n for n in N]
    assert list(res["b.flag_echo"]) == [1 - f for f in FLAG]
    assert list(res["b.mode_echo"]) == [{1: 3, 2: 1, 3: 2}[m] for m in MODE]
    assert meta["kernel"] == "native" and "python_operations" not in meta, meta.get("python_operations")
    assert meta["transforms"]["a.n -> b.n_in"] == "map(a.n; 1→10, 2→20, 3→30, 4→40)"
    for kernel in ("python", "native"):
        other, _ = _run(folder, kernel)
        for name in res.dtype.names:
            np.testing.assert_array_equal(other[name], res[name], err_msg=name)


def test_tables_compose_through_a_system_connector(tmp_path, tables_fmu):
    """a.n → sub.nin (n + 1) → b.n_in (10·value): the tables of the two connections composed,
    in the order of the path."""
    first = ('<ssc:IntegerMappingTransformation>'
             + "".join(f'<ssc:MapEntry source="{n}" target="{n + 1}"/>' for n in range(1, 5))
             + '</ssc:IntegerMappingTransformation>')
    second = ('<ssc:IntegerMappingTransformation>'
              + "".join(f'<ssc:MapEntry source="{n}" target="{10 * n}"/>' for n in range(2, 6))
              + '</ssc:IntegerMappingTransformation>')
    sub = ('<ssd:System name="sub"><ssd:Connectors><ssd:Connector name="nin" kind="input"><ssc:Integer/>'
           f'</ssd:Connector></ssd:Connectors><ssd:Elements>{_component("b")}</ssd:Elements>'
           f'<ssd:Connections>{_connection("nin", "b.n_in", second)}</ssd:Connections></ssd:System>')
    text = _ssd(f"<ssd:Elements>{_component('a')}{sub}</ssd:Elements>"
                f"<ssd:Connections>{_connection('a.n', 'sub.nin', first)}</ssd:Connections>")
    res = cosim.simulate(_system(tmp_path, tables_fmu, text))
    assert list(res["sub.b.n_echo"]) == [10 * (n + 1) for n in N]


@pytest.mark.parametrize("kernel", ["python", "native"])
def test_a_value_no_map_entry_names_stops_the_run(tmp_path, tables_fmu, kernel):
    """a.n = 3 at t = 0.2 has no MapEntry: the run ends there, naming the transformation and the
    value, in both interpreters (the compiled loop finds it and hands the route to Python)."""
    partial = ('<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="10"/>'
               '<ssc:MapEntry source="2" target="20"/></ssc:IntegerMappingTransformation>')
    folder = _system(tmp_path, tables_fmu, flat_ssd(integer=partial))
    with pytest.raises(RunError, match=r"connection a.n -> b.n_in: a.n = 3 at t = 0.2 is not a source value of "
                                       r"ssc:IntegerMappingTransformation \(line 2\) \(its sources: 1, 2\)") as err:
        cosim.simulate(folder, kernel=kernel)
    assert err.value.time == pytest.approx(0.2)
    assert list(err.value.result["b.n_echo"]) == [10, 20]


@pytest.mark.parametrize("change, message", [
    (dict(integer=BOOLEAN), "ssc:BooleanMappingTransformation applies to Boolean connections; a.n -> b.n_in is "
                            "Integer"),
    (dict(boolean=INTEGER), "ssc:IntegerMappingTransformation applies to Integer and Enumeration connections; "
                            "a.flag -> b.flag_in is Boolean"),
    (dict(integer=ENUMERATION), "ssc:EnumerationMappingTransformation maps item names; a.n is Integer"),
    (dict(enumeration=ENUMERATION.replace('"mid"', '"medium"')),
     "ssc:MapEntry 'medium' -> 'low': 'medium' is not an item of a.mode's type Level (items: low, mid, high)"),
])
def test_table_errors_name_the_connection_and_transformation(tmp_path, tables_fmu, capsys, change, message):
    folder = _system(tmp_path, tables_fmu, flat_ssd(**change))
    assert main(["validate", str(folder)]) == 2
    err = capsys.readouterr().err
    assert message in err and "SystemStructure.ssd" in err and "MappingTransformation (line 2)" in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("kernel", ["python", "native"])
def test_a_table_on_the_way_to_a_root_output_connector_maps_its_column(tmp_path, tables_fmu, kernel):
    """The root output ``out`` records a.n through the table (issue 40: refused, the recorded
    columns knew factor and offset only); a Boolean one through its table too."""
    text = _ssd('<ssd:Connectors><ssd:Connector name="out" kind="output"><ssc:Integer/></ssd:Connector>'
                '<ssd:Connector name="flag" kind="output"><ssc:Boolean/></ssd:Connector>'
                f'</ssd:Connectors><ssd:Elements>{_component("a")}</ssd:Elements>'
                f'<ssd:Connections>{_connection("a.n", "out", INTEGER)}{_connection("a.flag", "flag", BOOLEAN)}'
                '</ssd:Connections>')
    res, meta = _run(_system(tmp_path, tables_fmu, text), kernel)
    assert list(res["out"]) == [10 * n for n in N] and list(res["flag"]) == [1 - f for f in FLAG]
    assert meta["system_outputs"] == {"out": "map(a.n; 1→10, 2→20, 3→30, 4→40)",
                                      "flag": "map(a.flag; false→true, true→false)"}


def test_a_value_a_root_output_table_does_not_name_is_nan_with_a_warning(tmp_path, tables_fmu):
    partial = ('<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="10"/>'
               '<ssc:MapEntry source="2" target="20"/></ssc:IntegerMappingTransformation>')
    text = _ssd('<ssd:Connectors><ssd:Connector name="out" kind="output"><ssc:Integer/></ssd:Connector>'
                f'</ssd:Connectors><ssd:Elements>{_component("a")}</ssd:Elements>'
                f'<ssd:Connections>{_connection("a.n", "out", partial)}</ssd:Connections>')
    with pytest.warns(RuntimeWarning, match="root output connector 'out': map"):
        res, _ = _run(_system(tmp_path, tables_fmu, text), "auto")
    assert list(res["out"][:2]) == [10, 20] and np.isnan(res["out"][2:]).all()


def test_a_table_after_a_system_connector_given_a_value(tmp_path, tables_fmu):
    """The value 2 given to the open connector ``nin`` reaches b.n_in through the table (20; issue
    40: refused), and an input table's column naming ``nin`` does too (1, 2, 3 -> 10, 20, 30)."""
    binding = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
               '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
               'version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="nin"><ssv:Integer value="2"/>'
               '</ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>'
               '</ssd:ParameterBindings>')
    text = _ssd('<ssd:Connectors><ssd:Connector name="nin" kind="input"><ssc:Integer/></ssd:Connector>'
                f'</ssd:Connectors>{binding}<ssd:Elements>{_component("b")}</ssd:Elements>'
                f'<ssd:Connections>{_connection("nin", "b.n_in", INTEGER)}</ssd:Connections>')
    folder = _system(tmp_path, tables_fmu, text)
    res, _ = _run(folder, "auto")
    assert set(res["b.n_echo"]) == {20}
    table = tmp_path / "in.csv"
    table.write_text("time,nin\n0,1\n0.1,2\n0.2,3\n0.3,3\n")
    res = cosim.simulate_fmu(folder, input_file=table)
    assert list(res["b.n_echo"]) == [10, 10, 20, 30]   # an echo shows the input set at the point before
    table.write_text("time,nin\n0,1\n0.1,7\n")
    with pytest.raises(SetupError, match=r"7 reaches b.n_in through map\(x; 1→10, 2→20, 3→30, 4→40\), which "
                                         r"names no target for it"):
        cosim.simulate_fmu(folder, input_file=table)
