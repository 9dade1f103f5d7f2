"""The ordering algorithms of cosim.plan.graph on their own: plain names and routes, no FMU.

A route here is a `cosim.model.structure.Route` between fmpy `ModelVariable`s built in the
test; the dependencies are what an FMU's ModelStructure would give
(`cosim.model.fmu.FMUDescription.output_dependencies`).
"""
from __future__ import annotations

import pytest
from fmpy.model_description import ModelVariable

from cosim.errors import SetupError
from cosim.plan.graph import (
    cycle_path,
    feedthrough_sequence,
    gauss_seidel_order,
    settling_shortcuts,
    tarjan,
    topological,
    variable_order,
)
from cosim.model.structure import Route
from cosim.model.transforms import IDENTITY


def route(src: str, dst: str) -> Route:
    """``"a.y" -> "b.u"``: output y of a to input u of b."""
    (a, y), (b, u) = src.split("."), dst.split(".")
    return Route(a, ModelVariable(name=y, causality="output"), b, ModelVariable(name=u, causality="input"), IDENTITY)


def test_tarjan_finds_each_loop_and_the_single_nodes():
    edges = {1: [2], 2: [3], 3: [1, 4], 4: [5], 5: [4], 6: []}
    components = tarjan([1, 2, 3, 4, 5, 6], edges)
    assert sorted(map(sorted, components)) == [[1, 2, 3], [4, 5], [6]]
    # reverse topological order: the loop {4, 5} fed by {1, 2, 3} comes out first
    assert [sorted(c) for c in components].index([4, 5]) < [sorted(c) for c in components].index([1, 2, 3])


def test_cycle_path_reads_along_the_edges_and_closes_the_loop():
    edges = {"a": ["c", "b"], "b": ["a"], "c": ["b"]}
    assert cycle_path(["a", "b", "c"], edges) == ["a", "c", "b", "a"]


def test_topological_breaks_ties_in_the_given_order():
    edges = {"x": ["z"], "y": ["z"]}
    assert topological(["y", "x", "z"], edges) == ["y", "x", "z"]
    assert topological(["x", "y", "z"], edges) == ["x", "y", "z"]


def test_a_feedthrough_chain_is_settled_in_dependency_order():
    # source -> g1 -> g2 -> sink; the gains have direct feedthrough, the source and the sink none
    routes = [route("g2.y", "sink.u"), route("g1.y", "g2.u"), route("source.y", "g1.u")]
    outputs = {"source": ["y"], "g1": ["y"], "g2": ["y"], "sink": ["y"]}
    dependencies = {"source": {"y": []}, "g1": {"y": ["u"]}, "g2": {"y": ["u"]}, "sink": {"y": []}}
    order = variable_order(routes, outputs, dependencies, "system.ssd")
    assert order.index(("out", "g1", "y")) < order.index(("in", "g2", "u")) < order.index(("out", "g2", "y"))
    assert feedthrough_sequence(order, routes, dependencies) == ["g1", "g2"]


def test_an_output_that_does_not_depend_on_its_connected_input_is_not_settled():
    routes = [route("a.y", "b.u"), route("b.y", "a.u")]
    outputs = {"a": ["y"], "b": ["y"]}
    order = variable_order(routes, outputs, {"a": {"y": ["u"]}, "b": {"y": []}}, "system.ssd")
    assert feedthrough_sequence(order, routes, {"a": {"y": ["u"]}, "b": {"y": []}}) == ["a"]


def test_an_algebraic_loop_is_refused_naming_the_variables_in_loop_order():
    routes = [route("a.y", "b.u"), route("b.y", "a.u")]
    with pytest.raises(SetupError) as err:
        variable_order(routes, {"a": ["y"], "b": ["y"]}, {"a": {"y": ["u"]}, "b": {"y": ["u"]}}, "loop.ssd")
    text = str(err.value)
    assert "algebraic loop" in text and "loop.ssd" in text and "ssd:Connections" in text
    assert "a.y (output) -> b.u (input) -> b.y (output) -> a.u (input) -> a.y (output)" in text


def test_gauss_seidel_puts_upstream_first_and_keeps_ssd_order_inside_a_loop():
    # SSD order: plant, ctrl, setpoint; setpoint feeds the loop ctrl <-> plant
    routes = [route("setpoint.y", "ctrl.r"), route("ctrl.u", "plant.u"), route("plant.y", "ctrl.y")]
    assert gauss_seidel_order(["plant", "ctrl", "setpoint"], routes) == ["setpoint", "plant", "ctrl"]
    # independent components keep SSD order
    assert gauss_seidel_order(["b", "a"], []) == ["b", "a"]


def test_settling_shortcuts_take_any_route_with_src_and_dst():
    read_once, set_once = settling_shortcuts(["g1", "g2"], [route("g1.y", "g2.u"), route("p.y", "g1.u")])
    assert read_once == {"g1", "g2"} and set_once == {"g1", "g2"}
