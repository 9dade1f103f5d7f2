"""Units on the connectors of nested systems, converted hop by hop (cosim.model.structure.Hop, cosim.plan.routing).

SSP 1.0 (SystemStructureDescription.xsd, Connection and ``suppressUnitConversion``): on each
connection the value is converted from its start connector's unit to its end connector's unit,
then that connection's LinearTransformation applies (only the transformation when the
conversion is suppressed).  A path src → system connector → dst is two connections, so a
system connector's unit is a real stop on the way.  A system connector without a unit is
transparent: it carries the unit of what drives it.

The runs use the UnitSource/UnitSink FMUs of tests/scenarios/test_units.py: src.y_i = a_i + t (y1 starts
at 20 degC), read back from the results; dst's outputs v_i echo its inputs, in its own unit, as
the FMU received them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_units import (
    assert_every_sample,
    built,
    connector,
    refused,
    simulate,
    with_units,
)

from cosim.model.transforms import Affine
from cosim.model.units import BUILTIN, conversion

__all__ = ["built"]  # the module-scoped fixture that builds the two FMUs

SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="nested">
  <ssd:System name="root">
    {root_connectors}{root_bindings}
    <ssd:Elements>
      <ssd:Component name="src" source="resources/src.fmu">
        <ssd:Connectors>{src}</ssd:Connectors>
      </ssd:Component>
      <ssd:System name="sub">
        <ssd:Connectors>{sub_connectors}</ssd:Connectors>
        <ssd:Elements>
          <ssd:Component name="dst" source="resources/dst.fmu">
            <ssd:Connectors>{dst}</ssd:Connectors>
          </ssd:Component>
        </ssd:Elements>
        <ssd:Connections>{inner}</ssd:Connections>
      </ssd:System>
    </ssd:Elements>
    <ssd:Connections>{outer}</ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1">
    <ssd:Annotations><ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation
      xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" stepSize="0.1"/></ssc:Annotation></ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""

SRC_UNITS = {"y1": "degC", "y2": "degC", "y3": "degC", "a1": "degC", "a2": "degC", "a3": "degC"}


def hop(start: tuple[str | None, str], end: tuple[str | None, str], lt: tuple[float, float] | None = None,
        suppress: bool = False) -> str:
    """One ssd:Connection; an element None names a connector of the enclosing system."""
    def side(which: str, element: str | None, name: str) -> str:
        return (f'{which}Element="{element}" ' if element else "") + f'{which}Connector="{name}"'

    attrs = ' suppressUnitConversion="true"' if suppress else ""
    body = f'<ssc:LinearTransformation factor="{lt[0]!r}" offset="{lt[1]!r}"/>' if lt else ""
    return f"<ssd:Connection {side('start', *start)} {side('end', *end)}{attrs}>{body}</ssd:Connection>"


def through_sub(i: int, unit: str | None, outer: tuple | None = None, inner: tuple | None = None, *,
                suppress_outer: bool = False, suppress_inner: bool = False) -> tuple[str, str, str]:
    """src.y_i → sub.s_i (an input connector of ``sub`` in ``unit``) → dst.u_i: the connector
    and the two connections (outer, inner), with their LinearTransformations."""
    return (connector(f"s{i}", "input", unit),
            hop(("src", f"y{i}"), ("sub", f"s{i}"), outer, suppress_outer),
            hop((None, f"s{i}"), ("dst", f"u{i}"), inner, suppress_inner))


def nested(folder: Path, built: dict[str, Path], dst_units: dict[str, str], paths: list[tuple[str, str, str]], *,
           root_connectors: str = "", root_bindings: str = "", extra_outer: str = "") -> Path:
    """A scenario folder: src at the root, dst inside ``sub``, wired through ``paths`` (`through_sub`)."""
    resources = folder / "resources"
    with_units(built["UnitSource"], resources / "src.fmu", SRC_UNITS)
    with_units(built["UnitSink"], resources / "dst.fmu", dst_units)
    text = SSD.format(
        root_connectors=f"<ssd:Connectors>{root_connectors}</ssd:Connectors>" if root_connectors else "",
        root_bindings=root_bindings,
        src="".join(connector(f"y{i}", "output") for i in (1, 2, 3)),
        dst="".join(connector(f"u{i}", "input") + connector(f"v{i}", "output") for i in (1, 2, 3)),
        sub_connectors="".join(p[0] for p in paths), inner="".join(p[2] for p in paths),
        outer="".join(p[1] for p in paths) + extra_outer)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def end_to_end(lt: tuple[float, float], src: str, dst: str) -> tuple[float, float]:
    """What comparing only the two component ends gave: convert src → dst, then the composed
    transformation (the behaviour this module's tests replace)."""
    composed = conversion(BUILTIN[src], BUILTIN[dst]).then(Affine(*lt))
    return composed.factor, composed.offset


K = {"u1": "K", "v1": "K", "u2": "K", "v2": "K", "u3": "K", "v3": "K"}
DEGC_K_DEGC = {"u1": "K", "v1": "K", "u2": "degC", "v2": "degC", "u3": "degC", "v3": "degC"}


def test_a_system_connector_in_kelvin_converts_each_hop(tmp_path, built):
    # degC → s1 [K] → K; degC → s2 [K] → degC (there and back)
    r, _ = simulate(nested(tmp_path, built, DEGC_K_DEGC, [through_sub(1, "K"), through_sub(2, "K")]))
    assert_every_sample(r["sub.dst.v1"], r["src.y1"] + 273.15)
    assert_every_sample(r["sub.dst.v2"], r["src.y2"])
    assert r["src.y1"][0] == 20.0


def test_a_transformation_between_two_unit_changes_applies_in_kelvin(tmp_path, built):
    # 1: degC → s1 [K] → (×2) → K: 2·(y + 273.15); 2: degC → (×2) → s2 [K] → degC: the doubling
    # happens in kelvin, then back to degC: 2·(y + 273.15) − 273.15
    r, _ = simulate(nested(tmp_path, built, DEGC_K_DEGC,
                           [through_sub(1, "K", inner=(2.0, 0.0)), through_sub(2, "K", outer=(2.0, 0.0))]))
    y1, y2 = r["src.y1"], r["src.y2"]
    assert_every_sample(r["sub.dst.v1"], 2.0 * (y1 + 273.15))
    assert_every_sample(r["sub.dst.v2"], 2.0 * (y2 + 273.15) - 273.15)
    # converting end to end, then the composed transformation: the same for the first path (the
    # transformation comes after the only unit change), 273.15 off for the second
    a, b = end_to_end((2.0, 0.0), "degC", "K")
    np.testing.assert_allclose(r["sub.dst.v1"], a * y1 + b, rtol=1e-12)
    a, b = end_to_end((2.0, 0.0), "degC", "degC")
    assert np.all(np.abs(r["sub.dst.v2"] - (a * y2 + b)) > 273.0)


def test_suppress_unit_conversion_applies_to_its_own_hop_only(tmp_path, built):
    # 2: degC → (suppressed) → s2 [K] → degC: the value enters s2 as it is, read as kelvin, then
    # converted to degC; 3: degC → s3 [K] → (suppressed, ×1 + 0) → degC: kelvin values arrive as they are
    r, _ = simulate(nested(tmp_path, built, DEGC_K_DEGC,
                           [through_sub(2, "K", suppress_outer=True),
                            through_sub(3, "K", inner=(1.0, 0.0), suppress_inner=True)]))
    assert_every_sample(r["sub.dst.v2"], r["src.y2"] - 273.15)
    assert_every_sample(r["sub.dst.v3"], r["src.y3"] + 273.15)


def test_a_system_connector_without_a_unit_is_transparent(tmp_path, built):
    # 1: degC → s1 (no unit) → K converts once; 2: degC → (×2) → s1 (no unit, so still degC) → K:
    # the doubling is in degC; 3: degC → s3 (no unit) → degC: unchanged
    r, _ = simulate(nested(tmp_path, built, {**K, "u3": "degC", "v3": "degC"},
                           [through_sub(1, None), through_sub(2, None, outer=(2.0, 0.0)), through_sub(3, None)]))
    assert_every_sample(r["sub.dst.v1"], r["src.y1"] + 273.15)
    assert_every_sample(r["sub.dst.v2"], 2.0 * r["src.y2"] + 273.15)
    assert_every_sample(r["sub.dst.v3"], r["src.y3"])


ROOT_OUTPUTS = connector("TK", "output", "K") + connector("Tplain", "output") + connector("r", "input", "K")


def test_root_outputs_and_constant_inputs_convert_hop_by_hop(tmp_path, built):
    # root outputs: src.y1 [degC] → TK [K]; → Tplain (no unit: degC).  Root input r [K] = 300,
    # a constant input: → sub.s2 [K] → (K to degC, then ×2) → dst.u2 [degC]: 2·(300 − 273.15)
    bindings = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet '
                'version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="r"><ssv:Real value="300.0"/>'
                '</ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
                '</ssd:ParameterBinding></ssd:ParameterBindings>')
    s2 = connector("s2", "input", "K")
    paths = [(s2, hop((None, "r"), ("sub", "s2")), hop((None, "s2"), ("dst", "u2"), (2.0, 0.0)))]
    folder = nested(tmp_path, built, DEGC_K_DEGC, paths, root_connectors=ROOT_OUTPUTS, root_bindings=bindings,
                    extra_outer=hop(("src", "y1"), (None, "TK")) + hop(("src", "y1"), (None, "Tplain")))
    r, meta = simulate(folder)
    assert_every_sample(r["TK"], r["src.y1"] + 273.15)
    assert_every_sample(r["Tplain"], r["src.y1"])
    assert_every_sample(r["sub.dst.v2"], np.full(11, 2.0 * (300.0 - 273.15)))
    assert meta["system_outputs"]["TK"] == "src.y1 + 273.15"
    assert (meta["units"]["TK"], meta["units"]["Tplain"], meta["units"]["src.y1"]) == ("K", "degC", "degC")


@pytest.mark.parametrize("inner", [False, True], ids=["into-the-connector", "out-of-the-connector"])
def test_different_dimensions_at_a_system_connector_are_refused(tmp_path, built, inner):
    # degC → s1 [MPa] → K (refused at the first hop); degC → s1 [K] → u1 [MPa] (at the second)
    dst_units = {"u1": "MPa", "v1": "MPa"} if inner else K
    text = refused(nested(tmp_path, built, dst_units, [through_sub(1, "K" if inner else "MPa")]))
    assert "SystemStructure.ssd" in text and "system connector 'sub.s1'" in text
    if inner:
        assert "'K' (K)" in text and "'MPa' (kg·m^-1·s^-2)" in text and "dst.u1" in text
    else:
        assert "'degC' (K)" in text and "'MPa' (kg·m^-1·s^-2)" in text and "src.y1" in text
