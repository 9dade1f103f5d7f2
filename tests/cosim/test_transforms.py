"""A connection's transformation as one value (issue 40, cosim.model.transforms): the kinds and their
operations, and a kind defined here, in this file alone, taken by every consumer (the plan, the root
outputs, the metadata, both interpreters) as the built-in kinds are."""
from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from cosim.errors import SetupError
from cosim.model.frozen import FrozenMap
from cosim.model.transforms import IDENTITY, Affine, Chain, Table, Unmapped, chain, compose, from_json
from cosim.plan.build import build_plan
from cosim.read import ssp
from cosim.read.description import describe_fmus
from cosim.read.resources import locate_fmus
from cosim.plan.prepare import resolve_grid
from cosim.run.simulation import run
from ssdgen import ssd_text, write_system

TABLE = Table(FrozenMap({1: 10, 2: 20, 3: 30}), False, "ssc:IntegerMappingTransformation (line 4)")


def test_affine_composes_with_the_roundings_of_the_step_it_replaced():
    """(a1, b1) then (a2, b2) is (a2·a1, a2·b1 + b2), applied as x·a + b: the arithmetic the
    routes' (factor, offset) pairs had, bit for bit (a unit conversion degC -> degF, then a gain)."""
    first, second = Affine(1.8, 32.0), Affine(0.1, 3.3)
    composed = first.then(second)
    assert (composed.factor, composed.offset) == (0.1 * 1.8, 0.1 * 32.0 + 3.3)
    x = np.linspace(-40.0, 120.0, 1001)
    assert composed.apply_array(x).tobytes() == (x * (0.1 * 1.8) + (0.1 * 32.0 + 3.3)).tobytes()
    assert compose([]) == IDENTITY and IDENTITY.identity and not composed.identity
    assert Affine(4.0, 2.0).inverse().apply(Affine(4.0, 2.0).apply(3.0)) == 3.0 and Affine(0.0, 1.0).inverse() is None


def test_a_table_composes_inverts_and_names_what_it_does_not_map():
    second = Table(FrozenMap({10: 1, 20: 2}), False, "ssc:IntegerMappingTransformation (line 9)")
    both = TABLE.then(second)
    assert both.mapping == {1: 1, 2: 2} and both.element.endswith("(line 4), ssc:IntegerMappingTransformation (line 9)")
    assert TABLE.inverse().apply(20) == 2 and Table(FrozenMap({1: 5, 2: 5})).inverse() is None
    with pytest.raises(Unmapped, match="7 is not a source value of ssc:IntegerMappingTransformation"):
        TABLE.apply(7)
    assert np.isnan(TABLE.apply_array(np.array([1.0, 7.0]))).tolist() == [False, True]
    boolean = Table(FrozenMap({0: 1, 1: 0}), True)
    assert [boolean.apply(v) for v in (0, 1, 5)] == [1, 0, 0] and boolean.text("b") == "map(b; false→true, true→false)"


def test_kinds_chain_and_every_kind_renders_hashes_and_round_trips():
    chained = Affine(2.0, 1.0).then(TABLE).then(Affine(0.5))
    assert isinstance(chained, Chain) and chained.apply(0.5) == 10.0 and chained.text("u") == \
        "0.5*map(2*u + 1; 1→10, 2→20, 3→30)"
    assert chained.inverse().apply(10.0) == pytest.approx(0.5)
    assert Affine(2.0).then(Affine(3.0, 1.0)) == Affine(6.0, 1.0) and IDENTITY.then(TABLE) == TABLE
    assert [t.text("x") for t in (IDENTITY, Affine(0.001, -0.2), Affine(1.0, 273.15))] == \
        ["x", "0.001*x - 0.2", "x + 273.15"]
    for t in (Affine(1.8, 32.0), TABLE, chained):
        assert from_json(t.as_json()) == t and pickle.loads(pickle.dumps(t)) == t and hash(t) == hash(from_json(t.as_json()))


@dataclasses.dataclass(frozen=True)
class Clamp:
    """A kind of transformation no cosim module knows: values limited to [lo, hi]."""
    lo: float
    hi: float
    partial = False

    @property
    def identity(self) -> bool:
        return False

    def apply(self, value):
        return min(max(value, self.lo), self.hi)

    def apply_array(self, values):
        return np.clip(values, self.lo, self.hi)

    def then(self, after):
        return chain(self, after)

    def inverse(self):
        return None

    def text(self, x: str = "x") -> str:
        return f"clamp({x}, {self.lo:g}, {self.hi:g})"

    def as_json(self) -> dict:
        return {"clamp": [self.lo, self.hi]}

    def native(self):
        return None

    def resolve(self, source, target, file, where):
        return self


def test_a_new_kind_is_one_class_every_consumer_takes(tmp_path, twin_fmus):
    """Step 0 -> 3 at t = 0.5 into a gain, through ``Clamp(0.5, 2)`` given to the connection's
    transformation and to a root output's path as a reader would: the plan routes it, the gain
    sees the clamped value in both interpreters (the compiled loop hands the route to Python, as
    it has no C form), the root output records it, the metadata renders it."""
    components = {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("clamped", components, [("step", "y", "gain", "u")], stop=1.0, step=0.25,
                    parameters={"step": {"t_step": 0.5, "final": 3.0}, "gain": {"k": 1.0}})
    text = text.replace('<ssd:Elements>', '<ssd:Connectors><ssd:Connector name="out" kind="output"/></ssd:Connectors>'
                        '<ssd:Elements>').replace('</ssd:Connections>', '<ssd:Connection startElement="step" '
                        'startConnector="y" endConnector="out"/></ssd:Connections>')
    folder = write_system(tmp_path / "clamped", {f: twin_fmus[f.removesuffix(".fmu")] for f, _ in components.values()},
                          text)
    structure = ssp.load(folder)
    clamp = Clamp(0.5, 2.0)
    structure.connections = [dataclasses.replace(c, transform=clamp) for c in structure.connections]
    structure.system_outputs = {n: dataclasses.replace(o, hops=tuple(dataclasses.replace(h, transform=clamp)
                                                                      for h in o.hops))
                                for n, o in structure.system_outputs.items()}
    plan = build_plan(structure, describe_fmus(structure, locate_fmus(structure, use_providers=False)))
    assert [r.transform for r in plan.routes] == [clamp] and plan.system_outputs["out"].transform == clamp
    results = {}
    for kernel in ("python", "native"):
        result, meta = run(resolve_grid(plan), kernel=kernel, journal=False)
        results[kernel] = result
        assert list(result["gain.u"]) == [0.5, 0.5, 2.0, 2.0, 2.0]
        assert list(result["out"]) == [0.5, 0.5, 2.0, 2.0, 2.0]
        assert meta["transforms"] == {"step.y -> gain.u": "clamp(step.y, 0.5, 2)"}
        assert meta["system_outputs"] == {"out": "clamp(step.y, 0.5, 2)"}
    assert any("clamp(step.y, 0.5, 2), which has no C form" in why for why in meta["python_operations"])
    assert results["python"].tobytes() == results["native"].tobytes()


def test_a_linear_transformation_on_a_path_to_an_integer_is_refused(tmp_path, twin_fmus):
    """`Affine.resolve`: a LinearTransformation acts on Real values only (the check the plan made
    itself, now the kind's)."""
    with pytest.raises(SetupError, match="a LinearTransformation applies to Real connections only; step.y is Integer"):
        Affine(2.0).resolve(("step.y", dataclasses.replace(_real(), type="Integer")), None, "x.ssd", "here")


def _real():
    from cosim.model.fmu import Variable
    return Variable("y", 1, "Real", "output", "continuous")
