"""Nested systems and system-level connectors (SSP 1.0), flattened by cosim.read.flatten.

The nested scenarios are ssp/pid_fopdt with its controller and plant moved into a
subsystem ``loop`` (and, two levels deep, ``loop`` inside ``outer``); the setpoint and
the load enter through system connectors, the plant output leaves through one and
is recorded as the root output ``y``.  They must give the samples of the flat
scenario, under paths relative to the root system.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.read import ssp
from cosim.cli import main
from cosim.errors import SetupError

SCENARIO = Path("ssp/pid_fopdt")
STOP = 200.0  # past the load step at t = 150 s
#: the load reaches the plant through two transformations: (2, 0.5) at the root, (-0.5, 0.1) in loop
OUTER_TF, INNER_TF = (2.0, 0.5), (-0.5, 0.1)
COMPOSED_TF = (-1.0, -0.15)  # -0.5 (2 x + 0.5) + 0.1

HEADER = ('<?xml version="1.0" encoding="UTF-8"?>\n'
          '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"'
          ' xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"'
          ' xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
          ' xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" version="1.0" name="nested">\n')
FOOTER = ('  <ssd:DefaultExperiment startTime="0" stopTime="300"><ssd:Annotations>'
          '<ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation stepSize="0.1"/></ssc:Annotation>'
          '</ssd:Annotations></ssd:DefaultExperiment>\n</ssd:SystemStructureDescription>\n')
REAL = "<ssc:Real/>"


def _connectors(*pairs: tuple[str, str]) -> str:
    return "<ssd:Connectors>" + "".join(f'<ssd:Connector name="{n}" kind="{k}">{REAL}</ssd:Connector>'
                                        for n, k in pairs) + "</ssd:Connectors>"


def _values(**values: float) -> str:
    body = "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v}"/></ssv:Parameter>' for n, v in values.items())
    return ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" '
            f'name="p"><ssv:Parameters>{body}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
            '</ssd:ParameterBinding></ssd:ParameterBindings>')


def _connection(a: str | None, ca: str, b: str | None, cb: str, tf: tuple[float, float] | None = None) -> str:
    start = f'startElement="{a}" ' if a else ""
    end = f'endElement="{b}" ' if b else ""
    inner = f'<ssc:LinearTransformation factor="{tf[0]}" offset="{tf[1]}"/>' if tf else ""
    return f'<ssd:Connection {start}startConnector="{ca}" {end}endConnector="{cb}">{inner}</ssd:Connection>'


def _component(name: str, fmu: str, connectors: str, bindings: str = "") -> str:
    return f'<ssd:Component name="{name}" source="resources/{fmu}.fmu">{connectors}{bindings}</ssd:Component>'


def _step(name: str, t_step: float, final: float) -> str:
    return _component(name, "Step", _connectors(("y", "output")), _values(t_step=t_step, initial=0, final=final))


LOOP = (  # the controller and the plant; plant.tau is bound at three levels, the root's value (4) wins
    '<ssd:System name="loop">' + _connectors(("r", "input"), ("d", "input"), ("y", "output"))
    + _values(**{"plant.tau": 5.0, "plant.K": 0.2})
    + "<ssd:Elements>"
    + _component("controller", "PID", _connectors(("r", "input"), ("y", "input"), ("u", "output"),
                                                  ("e", "output")),
                 '<ssd:ParameterBindings><ssd:ParameterBinding source="controller.ssv"/></ssd:ParameterBindings>')
    + _component("plant", "FOPDT", _connectors(("u", "input"), ("d", "input"), ("y", "output")),
                 _values(K=0.3, T=20, tau=6, y0=0))
    + "</ssd:Elements><ssd:Connections>"
    + _connection(None, "r", "controller", "r") + _connection("plant", "y", "controller", "y")
    + _connection("controller", "u", "plant", "u") + _connection(None, "d", "plant", "d", INNER_TF)
    + _connection("plant", "y", None, "y")
    + "</ssd:Connections></ssd:System>")


def _wrap(inner: str, inner_name: str, name: str) -> str:
    """A system holding ``inner``, passing r, d in and y out unchanged."""
    return (f'<ssd:System name="{name}">' + _connectors(("r", "input"), ("d", "input"), ("y", "output"))
            + f"<ssd:Elements>{inner}</ssd:Elements><ssd:Connections>"
            + _connection(None, "r", inner_name, "r") + _connection(None, "d", inner_name, "d")
            + _connection(inner_name, "y", None, "y") + "</ssd:Connections></ssd:System>")


def nested_ssd(levels: int = 1, *, root_connectors: str = _connectors(("y", "output")),
               root_elements: str | None = None, root_connections: str | None = None,
               root_bindings: str | None = None) -> str:
    """ssp/pid_fopdt with controller and plant in ``loop`` (inside ``outer`` when levels == 2)."""
    sub, sub_name = LOOP, "loop"
    if levels == 2:
        sub, sub_name = _wrap(LOOP, "loop", "outer"), "outer"
    path = "loop" if levels == 1 else "outer.loop"
    elements = root_elements if root_elements is not None else _step("setpoint", 10, 1) + _step("load", 150, -1)
    connections = root_connections if root_connections is not None else (
        _connection("setpoint", "y", sub_name, "r") + _connection("load", "y", sub_name, "d", OUTER_TF)
        + _connection(sub_name, "y", None, "y"))
    bindings = root_bindings if root_bindings is not None else _values(**{f"{path}.plant.tau": 4.0})
    return (HEADER + '  <ssd:System name="root">' + root_connectors + bindings
            + f"<ssd:Elements>{elements}{sub}</ssd:Elements><ssd:Connections>{connections}</ssd:Connections>"
            + "</ssd:System>\n" + FOOTER)


def write(folder: Path, text: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(SCENARIO / "controller.ssv", folder)
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


@pytest.fixture(scope="module")
def flat(built_fmus, tmp_path_factory) -> np.ndarray:
    """The flat scenario with the composed transformation on the load connection."""
    folder = tmp_path_factory.mktemp("flat") / "pid_fopdt"
    shutil.copytree(SCENARIO, folder)
    ssd = folder / "SystemStructure.ssd"
    old = '<ssd:Connection startElement="load" startConnector="y" endElement="plant" endConnector="d"/>'
    text = ssd.read_text()
    assert old in text
    ssd.write_text(text.replace(old, old[:-2] + '><ssc:LinearTransformation factor="{}" offset="{}"/>'
                                "</ssd:Connection>".format(*COMPOSED_TF)))
    return cosim.simulate(folder, stop_time=STOP)


@pytest.mark.parametrize("levels", [1, 2])
def test_nested_gives_the_flat_samples(flat, tmp_path, levels):
    folder = write(tmp_path / "nested", nested_ssd(levels))
    csv = tmp_path / "nested.csv"
    result = cosim.simulate(folder, stop_time=STOP, output=csv)
    path = "loop" if levels == 1 else "outer.loop"
    assert set(result.dtype.names) == {"time", "setpoint.y", "load.y", "y"} | {
        f"{path}.{n}" for n in ("controller.r", "controller.y", "controller.u", "controller.e", "plant.u",
                                "plant.d", "plant.y")}
    for name in flat.dtype.names:
        nested_name = name if name in ("time", "setpoint.y", "load.y") else f"{path}.{name}"
        np.testing.assert_allclose(result[nested_name], flat[name], rtol=0, atol=1e-12, err_msg=nested_name)
    np.testing.assert_array_equal(result["y"], result[f"{path}.plant.y"])
    assert np.ptp(result[f"{path}.plant.d"]) > 0.9  # the load step went through both transformations
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["root_system"] == "root"
    assert meta["parameters"][f"{path}.plant.tau"] == 4.0   # root binding beat loop's 5 and the component's 6
    assert meta["parameters"][f"{path}.plant.K"] == 0.2     # loop's binding beat the component's 0.3
    assert meta["system_outputs"] == {"y": f"{path}.plant.y"}


def test_flattened_routes_compose_the_transformations(built_fmus, tmp_path):
    folder = write(tmp_path / "n", nested_ssd(2))
    s = ssp.load(folder)
    route = next(c for c in s.connections if c.start_element == "load")
    assert "through system connector outer.d, outer.loop.d" in route.describe()
    with cosim.prepare(folder) as prepared:
        routes = {(r.src, r.src_var.name, r.dst, r.dst_var.name): r.transform for r in prepared.plan.routes}
    composed = routes[("load", "y", "outer.loop.plant", "d")]
    assert (composed.factor, composed.offset) == pytest.approx(COMPOSED_TF, abs=1e-15)
    assert routes[("setpoint", "y", "outer.loop.controller", "r")].identity
    assert routes[("outer.loop.plant", "y", "outer.loop.controller", "y")].identity
    assert len(routes) == 4


def test_parameter_set_names_a_dotted_component_path(built_fmus, tmp_path):
    folder = write(tmp_path / "n", nested_ssd(1))
    ps = tmp_path / "kc.ssv"
    ps.write_text('<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
                  'version="1.0" name="k"><ssv:Parameters><ssv:Parameter name="loop.controller.Kc">'
                  '<ssv:Real value="3.5"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    prepared = cosim.prepare(folder, parameter_sets=[ps])
    values = {f"{v.component}.{v.variable.name}": v.value for v in prepared.plan.start_values}
    prepared.close()
    assert values["loop.controller.Kc"] == 3.5
    ps.write_text(ps.read_text().replace("loop.controller.Kc", "loop.controler.Kc"))
    with pytest.raises(SetupError) as err:
        cosim.prepare(folder, parameter_sets=[ps])
    assert "kc.ssv" in str(err.value) and "'loop.controller'" in str(err.value)


def test_unknown_element_in_a_nested_connection_names_the_subsystem(built_fmus, tmp_path):
    text = nested_ssd(2).replace('startElement="plant" startConnector="y" endElement="controller"',
                                 'startElement="plant" startConnector="y" endElement="controler"')
    with pytest.raises(SetupError) as err:
        ssp.load(write(tmp_path / "n", text))
    msg = str(err.value)
    assert "unknown component 'controler' in system 'outer.loop'" in msg and "'controller'" in msg
    assert "SystemStructure.ssd" in msg and "line" in msg


def test_a_system_connector_with_two_drivers_is_refused(built_fmus, tmp_path):
    connections = (_connection("setpoint", "y", "loop", "r") + _connection("load", "y", "loop", "r")
                   + _connection("loop", "y", None, "y"))
    with pytest.raises(SetupError) as err:
        ssp.load(write(tmp_path / "n", nested_ssd(1, root_connections=connections)))
    assert "system connector 'loop.r' is driven by two connections" in str(err.value)


def _root_input_ssd(bindings: str, tf: tuple[float, float] | None = None) -> str:
    """The setpoint comes from the root's input connector r instead of a Step FMU."""
    return nested_ssd(1, root_connectors=_connectors(("r", "input"), ("y", "output")),
                      root_elements=_step("load", 150, -1), root_bindings=bindings,
                      root_connections=_connection(None, "r", "loop", "r", tf)
                      + _connection("load", "y", "loop", "d") + _connection("loop", "y", None, "y"))


def test_an_undriven_root_input_is_refused(built_fmus, tmp_path, capsys):
    folder = write(tmp_path / "n", _root_input_ssd(""))
    assert main(["validate", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "system connector 'r' (kind input) has no driver and no value; it feeds loop.controller.r" in err
    assert "SystemStructure.ssd" in err and "ParameterBinding" in err


@pytest.mark.parametrize("text", [
    _root_input_ssd(_values(r=0.7)),
    _root_input_ssd(_values(r=0.2), tf=(2.0, 0.3)),  # the value goes through the transformation
    # loop.r left open at the root and given its value on loop, by its name there
    _root_input_ssd("").replace(_connection(None, "r", "loop", "r"), "").replace(
        '<ssv:Parameter name="plant.tau">', '<ssv:Parameter name="r"><ssv:Real value="0.7"/></ssv:Parameter>'
        '<ssv:Parameter name="plant.tau">'),
], ids=["root", "transformed", "on-the-subsystem"])
def test_an_open_connector_with_a_value_is_a_constant_input(built_fmus, tmp_path, text):
    folder = write(tmp_path / "n", text)
    result = cosim.simulate(folder, stop_time=20.0)
    np.testing.assert_allclose(result["loop.controller.r"], 0.7, rtol=0, atol=1e-15)
    assert result["y"][-1] > 0.3  # the loop follows the constant setpoint


def test_info_shows_the_hierarchy(built_fmus, tmp_path, capsys):
    folder = write(tmp_path / "n", nested_ssd(2))
    assert main(["info", str(folder)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    start = lines.index("hierarchy (names are paths relative to the root system 'root'):")
    assert lines[start + 1:start + 9] == [
        "  root (system: output y)", "    setpoint", "    load",
        "    outer (system: input r, input d, output y)",
        "      outer.loop (system: input r, input d, output y)",
        "        outer.loop.controller", "        outer.loop.plant",
        "  recorded: y = outer.loop.plant.y"]
    assert "  load.y -> outer.loop.plant.d = -1*load.y - 0.15" in lines


def test_pack_keeps_the_nested_ssd_and_reloads(built_fmus, tmp_path):
    folder = write(tmp_path / "n", nested_ssd(1))
    archive = tmp_path / "nested.ssp"
    assert main(["pack", str(folder), "-o", str(archive)]) == 0
    packed = ssp.load(archive)
    try:
        # as written, but for the type attribute pack adds to every Component (issue 21, for OMSimulator)
        from lxml import etree
        tree = etree.parse(str(packed.ssd_file))
        added = tree.getroot().findall(".//{*}Component[@type='application/x-fmu-sharedlibrary']")
        assert len(added) == 4
        for component in added:
            del component.attrib["type"]
        original = etree.parse(str(folder / "SystemStructure.ssd"))
        assert etree.tostring(tree, method="c14n") == etree.tostring(original, method="c14n")
        assert list(packed.components) == ["setpoint", "load", "loop.controller", "loop.plant"]
    finally:
        packed.close()
    a = cosim.simulate(archive, stop_time=20.0)
    b = cosim.simulate(folder, stop_time=20.0)
    assert a.dtype.names == b.dtype.names
    for name in a.dtype.names:
        np.testing.assert_array_equal(a[name], b[name])


@pytest.mark.parametrize("change, message", [
    (lambda t: t.replace('<ssd:Connector name="d" kind="input">', '<ssd:Connector name="d" kind="inout">', 1),
     "system connectors of kind 'inout' are not supported"),
    (lambda t: t.replace('<ssv:Parameter name="loop.plant.tau">', '<ssv:Parameter name="loop.r"><ssv:Real value="1"/>'
                         '</ssv:Parameter><ssv:Parameter name="loop.plant.tau">'),
     "'loop.r' is a system connector driven by a connection; it cannot also be given a value"),
    (lambda t: t.replace(_connection("setpoint", "y", "loop", "r"), _connection("setpoint", "y", "loop", "y")),
     "both ends send (setpoint.y and loop.y)"),
])
def test_system_connector_misuse_is_refused(built_fmus, tmp_path, change, message):
    text = nested_ssd(1)
    changed = change(text)
    assert changed != text
    with pytest.raises(SetupError) as err:
        cosim.prepare(write(tmp_path / "n", changed))
    assert message in str(err.value) and "SystemStructure.ssd" in str(err.value)


def test_a_nested_output_feeding_nothing_is_harmless(built_fmus, tmp_path):
    """Like an unconnected component output: loop.y is driven but the root does not use it."""
    text = nested_ssd(1, root_connectors="",
                      root_connections=_connection("setpoint", "y", "loop", "r")
                      + _connection("load", "y", "loop", "d", OUTER_TF))
    prepared = cosim.prepare(write(tmp_path / "n", text))
    try:
        assert len(prepared.plan.routes) == 4 and not prepared.plan.system_outputs
    finally:
        prepared.close()
