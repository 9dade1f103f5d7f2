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
from typefmus import BYTES3, BYTES3_BODY, MODES2, MODES2_BODY, OUTPUTS3, TYPES3, TYPES3_BODY


H, STOP = 0.1, 1.0


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


@pytest.mark.parametrize("pair", ["types3", "bytes3"])
def test_converted_and_binary_exchange_runs_the_same_in_both_interpreters(tmp_path, typed, pair):
    """The gets and sets through the master's FMI 3.0 conversion, and a Binary's get, route and
    set, are made by Python within the compiled loop: the same samples as the Python interpreter."""
    if pair == "types3":
        comps = {"a": ("Types3.fmu", {o: "output" for o in OUTPUTS3}),
                 "b": ("Types3.fmu", {"fin": "input", "i8in": "input", "i64in": "input", "ein": "input",
                                      "fecho": "output", "sum": "output"})}
        wires = [("a", "f", "b", "fin"), ("a", "i8", "b", "i8in"), ("a", "i64", "b", "i64in"), ("a", "e", "b", "ein")]
        fmus = {"Types3.fmu": typed["Types3"]}
    else:
        comps = {"a": ("Bytes3.fmu", {"blob": "output"}),
                 "b": ("Bytes3.fmu", {"bin": "input", "length": "output", "checksum": "output"})}
        wires = [("a", "blob", "b", "bin")]
        fmus = {"Bytes3.fmu": build_c_fmu(tmp_path / "fmu", "Bytes3", BYTES3, BYTES3_BODY, "3.0")}
    folder = write_system(tmp_path / pair, fmus, ssd_text(pair, comps, wires, stop=STOP, step=H))
    python = cosim.simulate(folder, kernel="python")
    native = cosim.simulate(folder, kernel="native")
    assert len(python) == len(native) == 11
    for name in python.dtype.names:
        np.testing.assert_array_equal(python[name], native[name], err_msg=name)
