"""The rest of the FMI type system through real FMUs (issue 21, item 6), C FMUs compiled here
(tests/cfmus.py): FMI 2.0 Enumeration connectors exchanged as Integer and recorded, and
ssv:Enumeration bindings by item name; FMI 3.0 Float32, Int8, UInt16, Int64, UInt64 and
Enumeration exchanged and recorded, refused only where a value cannot be represented.
Each FMU run alone is compared with fmpy.simulate_fmu sample by sample."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from cosim.errors import RunError
from ssdgen import ssd_text, write_system

H, STOP = 0.1, 1.0

MODES2 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Modes2" guid="{9e0c0000-0000-4000-8000-000000000002}"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Modes2" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions><SimpleType name="Level"><Enumeration>
    <Item name="low" value="1"/><Item name="mid" value="2"/><Item name="high" value="3"/>
  </Enumeration></SimpleType></TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="mode" valueReference="0" causality="output" variability="discrete" initial="exact">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="set" valueReference="1" causality="input" variability="discrete">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="first" valueReference="2" causality="parameter" variability="fixed" initial="exact">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="echo" valueReference="3" causality="output" variability="discrete" initial="calculated">
      <Integer/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/><Unknown index="4" dependencies="2"/></Outputs>
  <InitialUnknowns><Unknown index="4" dependencies="2"/></InitialUnknowns></ModelStructure>
</fmiModelDescription>
"""
#: mode cycles through the items from ``first``, one per step; echo = 10·set
MODES2_BODY = """
static void start(S *s) { s->i[0] = 1; s->i[1] = 1; s->i[2] = 1; }
static void calculate(S *s) { s->i[3] = 10 * s->i[1]; if (s->i[62] == 0) s->i[0] = s->i[2]; }
static int step(S *s, double t, double h) { s->i[62] += 1; s->i[0] = (s->i[2] - 1 + s->i[62]) % 3 + 1; return 0; }
"""

TYPES3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Types3" instantiationToken="{9e0c0000-0000-4000-8000-000000000003}">
  <CoSimulation modelIdentifier="Types3" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions><EnumerationType name="Level">
    <Item name="low" value="1"/><Item name="mid" value="2"/><Item name="high" value="3"/>
  </EnumerationType></TypeDefinitions>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float32 name="f" valueReference="0" causality="output" variability="continuous"/>
    <Int8 name="i8" valueReference="1" causality="output" variability="discrete"/>
    <UInt16 name="u16" valueReference="2" causality="output" variability="discrete"/>
    <Int64 name="i64" valueReference="3" causality="output" variability="discrete"/>
    <UInt64 name="u64" valueReference="4" causality="output" variability="discrete"/>
    <Enumeration name="e" declaredType="Level" valueReference="5" causality="output" variability="discrete"/>
    <Float32 name="fin" valueReference="10" causality="input" variability="continuous" start="0"/>
    <Int8 name="i8in" valueReference="11" causality="input" variability="discrete" start="0"/>
    <Int64 name="i64in" valueReference="13" causality="input" variability="discrete" start="0"/>
    <Enumeration name="ein" declaredType="Level" valueReference="15" causality="input" variability="discrete" start="1"/>
    <Float32 name="fecho" valueReference="20" causality="output" variability="continuous"/>
    <Int64 name="sum" valueReference="21" causality="output" variability="discrete"/>
    <UInt64 name="scale" valueReference="30" causality="parameter" variability="fixed" start="1"/>
    <Enumeration name="level" declaredType="Level" valueReference="31" causality="parameter" variability="fixed" start="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="0" dependencies=""/><Output valueReference="1" dependencies=""/>
    <Output valueReference="2" dependencies=""/><Output valueReference="3" dependencies=""/>
    <Output valueReference="4" dependencies=""/><Output valueReference="5" dependencies=""/>
    <Output valueReference="20" dependencies="10"/><Output valueReference="21" dependencies="11 13 15"/>
  </ModelStructure>
</fmiModelDescription>
"""
#: k = steps taken: f = 0.1 k (Float32), i8 = k − 5, u16 = 1000 k, i64 = 100000 k, u64 = scale·k,
#: e = k mod 3 + 1; fecho = 2·fin, sum = i8in + i64in + ein + 10·level
TYPES3_BODY = """
static void start(S *s) { s->l[15] = 1; s->l[30] = 1; s->l[31] = 1; }
static void calculate(S *s) {
    long long k = s->l[62];
    s->f[0] = 0.1f * (float) k; s->l[1] = k - 5; s->l[2] = 1000 * k; s->l[3] = 100000 * k;
    s->l[4] = (long long) ((unsigned long long) s->l[30] * (unsigned long long) k); s->l[5] = k % 3 + 1;
    s->f[20] = 2.0f * s->f[10]; s->l[21] = s->l[11] + s->l[13] + s->l[15] + 10 * s->l[31]; }
static int step(S *s, double t, double h) { s->l[62] += 1; return 0; }
"""


@pytest.fixture(scope="module")
def typed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("types")
    return {"Modes2": build_c_fmu(tmp, "Modes2", MODES2, MODES2_BODY, "2.0"),
            "Types3": build_c_fmu(tmp, "Types3", TYPES3, TYPES3_BODY, "3.0")}


def _compare_alone(tmp_path, fmu, name: str, outputs: list[str], start_values: dict, ssd_values: dict, edit=None):
    """The FMU alone in cosim, sample by sample against fmpy.simulate_fmu."""
    comps = {"m": (fmu.name, {o: "output" for o in outputs})}
    text = ssd_text(name, comps, [], stop=STOP, step=H, parameters={"m": ssd_values} if ssd_values else None)
    folder = write_system(tmp_path / f"{name}_alone", {fmu.name: fmu}, edit(text) if edit else text)
    ours = cosim.simulate(folder)
    ref = fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=H, output=outputs, start_values=start_values)
    assert len(ours) == len(ref) == 11
    for o in outputs:
        np.testing.assert_array_equal(ours[f"m.{o}"], ref[o], err_msg=o)
    return ours


ENUM_VALUE = ('<ssv:Parameter name="{name}"><ssv:Enumeration value="{item}"/></ssv:Parameter>')


def _bind_enumeration(text: str, component: str, name: str, item: str) -> str:
    """Add an ssv:Enumeration binding (by item name) to the component's inline parameter set."""
    marker = f'<ssd:Component name="{component}"'
    head, tail = text.split(marker, 1)
    tail = tail.replace("</ssv:Parameters>", ENUM_VALUE.format(name=name, item=item) + "</ssv:Parameters>", 1)
    return head + marker + tail


def test_fmi2_enumeration_exchanged_recorded_and_bound_by_item_name(tmp_path, typed):
    fmu = typed["Modes2"]
    bind = lambda text: _bind_enumeration(text, "m", "first", "mid")
    alone = _compare_alone(tmp_path, fmu, "modes", ["mode", "echo"], {"first": 2, "set": 3}, {"set": 3}, edit=bind)
    np.testing.assert_array_equal(alone["m.mode"][:4], [2, 3, 1, 2])     # from 'mid' = 2, cycling
    comps = {"a": ("Modes2.fmu", {"mode": "output"}), "b": ("Modes2.fmu", {"set": "input", "echo": "output"})}
    text = ssd_text("modes", comps, [("a", "mode", "b", "set")], stop=STOP, step=H, parameters={"a": {"set": 1}})
    text = text.replace('<ssd:Connector name="mode" kind="output"/>',
                        '<ssd:Connector name="mode" kind="output"><ssc:Enumeration name="Level"/></ssd:Connector>')
    res = cosim.simulate(write_system(tmp_path / "pair", {"Modes2.fmu": fmu}, _bind_enumeration(text, "a", "first", "high")))
    np.testing.assert_array_equal(res["a.mode"][:4], [3, 1, 2, 3])
    np.testing.assert_array_equal(res["b.set"], res["a.mode"])
    np.testing.assert_array_equal(res["b.echo"], 10 * res["a.mode"])


def test_an_unknown_enumeration_item_is_refused(tmp_path, typed):
    fmu = typed["Modes2"]
    text = _bind_enumeration(ssd_text("modes", {"m": ("Modes2.fmu", {"mode": "output"})}, [], stop=STOP, step=H,
                                      parameters={"m": {"set": 1}}), "m", "first", "medium")
    with pytest.raises(cosim.SetupError, match=r"'medium' is not an item of Level \(items: low, mid, high\)"):
        cosim.simulate(write_system(tmp_path / "bad", {"Modes2.fmu": fmu}, text))


OUTPUTS3 = ["f", "i8", "u16", "i64", "u64", "e"]


def test_fmi3_types_alone_equal_fmpy(tmp_path, typed):
    fmu = typed["Types3"]
    bind = lambda text: _bind_enumeration(text, "m", "level", "high")
    ours = _compare_alone(tmp_path, fmu, "types", OUTPUTS3 + ["sum"], {"scale": 7, "level": 3}, {"scale": 7},
                          edit=bind)
    k = np.arange(11)
    np.testing.assert_array_equal(ours["m.f"], (np.float32(0.1) * k.astype(np.float32)).astype(np.float64))
    np.testing.assert_array_equal(ours["m.i8"], k - 5)
    np.testing.assert_array_equal(ours["m.u64"], 7 * k)
    np.testing.assert_array_equal(ours["m.sum"], 1 + 30)


def test_fmi3_types_exchanged_between_fmus(tmp_path, typed):
    fmu = typed["Types3"]
    comps = {"a": ("Types3.fmu", {o: "output" for o in OUTPUTS3}),
             "b": ("Types3.fmu", {"fin": "input", "i8in": "input", "i64in": "input", "ein": "input",
                                  "fecho": "output", "sum": "output"})}
    wires = [("a", "f", "b", "fin"), ("a", "i8", "b", "i8in"), ("a", "i64", "b", "i64in"), ("a", "e", "b", "ein")]
    res = cosim.simulate(write_system(tmp_path / "pair3", {"Types3.fmu": fmu},
                                      ssd_text("types", comps, wires, stop=STOP, step=H)))
    np.testing.assert_array_equal(res["b.fin"], res["a.f"])
    np.testing.assert_array_equal(res["b.fecho"], (2 * res["a.f"].astype(np.float32)).astype(np.float64))
    np.testing.assert_array_equal(res["b.sum"], res["a.i8"] + res["a.i64"] + res["a.e"] + 10)
    assert res["b.sum"][-1] == 5 + 1_000_000 + 2 + 10


def test_values_that_do_not_fit_are_refused_naming_the_variable(tmp_path, typed):
    fmu = typed["Types3"]
    # UInt16 1000 into an Int8 input
    comps = {"a": ("Types3.fmu", {"u16": "output"}), "b": ("Types3.fmu", {"i8in": "input"})}
    folder = write_system(tmp_path / "narrow", {"Types3.fmu": fmu},
                          ssd_text("narrow", comps, [("a", "u16", "b", "i8in")], stop=STOP, step=H))
    with pytest.raises(RunError, match=r"the Integer value 1000 cannot be represented as Int8 i8in"):
        cosim.simulate(folder)
    # a UInt64 beyond 32 bits, read (scale·k = 3e9 at k = 3)
    comps = {"a": ("Types3.fmu", {"u64": "output"})}
    folder = write_system(tmp_path / "wide", {"Types3.fmu": fmu},
                          ssd_text("wide", comps, [], stop=STOP, step=H, parameters={"a": {"scale": 1_000_000_000}}))
    with pytest.raises(RunError, match=r"UInt64 u64 = 3000000000 cannot be represented in the master's 32-bit"):
        cosim.simulate(folder)


BYTES3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Bytes3" instantiationToken="{9e0c0000-0000-4000-8000-000000000004}">
  <CoSimulation modelIdentifier="Bytes3" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Binary name="blob" valueReference="40" causality="output" variability="discrete"/>
    <Binary name="bin" valueReference="41" causality="input" variability="discrete"><Start value=""/></Binary>
    <Int32 name="length" valueReference="42" causality="output" variability="discrete"/>
    <Int32 name="checksum" valueReference="43" causality="output" variability="discrete"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="40" dependencies=""/><Output valueReference="42" dependencies="41"/>
    <Output valueReference="43" dependencies="41"/>
  </ModelStructure>
</fmiModelDescription>
"""
#: blob = k bytes of value k + 1 (k = steps taken, at most 16); length and checksum (the byte sum) of bin
BYTES3_BODY = """
static void start(S *s) {}
static void calculate(S *s) {
    int k = s->i[62] < 16 ? s->i[62] : 16;
    s->nbytes[40] = k; for (int j = 0; j < k; j++) s->bytes[40][j] = (unsigned char) (k + 1);
    s->i[42] = (int) s->nbytes[41]; int sum = 0; for (size_t j = 0; j < s->nbytes[41]; j++) sum += s->bytes[41][j];
    s->i[43] = sum; }
static int step(S *s, double t, double h) { s->i[62] += 1; return 0; }
"""


def test_fmi3_binary_is_exchanged_not_recorded(tmp_path):
    """a.blob (k bytes of k + 1 after k steps) reaches b.bin at the same instant (b's length and
    checksum depend on it); the Binary connectors are not result columns."""
    fmu = build_c_fmu(tmp_path / "fmu", "Bytes3", BYTES3, BYTES3_BODY, "3.0")
    comps = {"a": ("Bytes3.fmu", {"blob": "output"}),
             "b": ("Bytes3.fmu", {"bin": "input", "length": "output", "checksum": "output"})}
    res = cosim.simulate(write_system(tmp_path / "bytes", {"Bytes3.fmu": fmu},
                                      ssd_text("bytes", comps, [("a", "blob", "b", "bin")], stop=STOP, step=H)))
    k = np.arange(11)
    assert set(res.dtype.names) == {"time", "b.length", "b.checksum"}
    np.testing.assert_array_equal(res["b.length"], k)
    np.testing.assert_array_equal(res["b.checksum"], k * (k + 1))
    alone = fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=H, output=["length", "checksum"])
    np.testing.assert_array_equal(alone["length"], 0)      # unconnected, bin keeps its empty start value
