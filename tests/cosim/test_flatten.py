"""cosim.read.flatten on its own: a `RawStructure` built in the test (no XML, no FMU) in, a
`SystemStructure` out, and nothing it was given changed."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest

from cosim.errors import SetupError
from cosim.read.flatten import flatten
from cosim.model.transforms import Affine
from cosim.model.structure import (
    Component,
    Connection,
    Connector,
    Experiment,
    ParameterValue,
    RawStructure,
    RawSystem,
    ScenarioFiles,
)


def connector(name: str, kind: str, unit: str | None = None) -> Connector:
    return Connector(name, kind, "Real", unit, 1)


def component(name: str, **kinds: str) -> Component:
    return Component(name, f"resources/{name}.fmu", 1, connectors={c: connector(c, k) for c, k in kinds.items()})


def connection(start: str, end: str, factor: float = 1.0, offset: float = 0.0, line: int = 1) -> Connection:
    """``"ctrl.u"`` names a connector of an element, ``".r"`` one of the enclosing system."""
    (a, ca), (b, cb) = start.split("."), end.split(".")
    transform = Affine(factor, offset) if (factor, offset) != (1.0, 0.0) else None
    return Connection(a or None, ca, b or None, cb, transform, False, line)


def system(name: str, components=(), systems=(), connections=(), connectors=(), parameters=()) -> RawSystem:
    return RawSystem(name=name, line=1, connectors={c.name: c for c in connectors},
                     components={c.name: c for c in components}, systems={s.name: s for s in systems},
                     connections=list(connections), parameters=list(parameters),
                     elements=[e.name for e in (*components, *systems)])


def raw(root: RawSystem) -> RawStructure:
    return RawStructure(name="test", files=ScenarioFiles(Path("x.ssd"), Path("."), None), display="x.ssd",
                        root=root, experiment=Experiment(0.0, 1.0, 0.1, "annotation", None), units={})


def loop_in_a_subsystem() -> RawStructure:
    """Root: setpoint -> loop.r; loop holds ctrl and plant; loop.y -> root output y (x2 on the way)."""
    loop = system("loop", components=[component("ctrl", r="input", y="input", u="output"),
                                      component("plant", u="input", y="output")],
                  connectors=[connector("r", "input"), connector("y", "output", "degC")],
                  connections=[connection(".r", "ctrl.r", line=10), connection("ctrl.u", "plant.u", line=11),
                               connection("plant.y", "ctrl.y", line=12), connection("plant.y", ".y", 2.0, 0.0, 13)],
                  parameters=[ParameterValue("ctrl.Kc", "Real", 2.0, "x.ssd", 20)])
    root = system("root", components=[component("setpoint", y="output")], systems=[loop],
                  connectors=[connector("y", "output")],
                  connections=[connection("setpoint.y", "loop.r", 3.0, 1.0, line=5),
                               connection("loop.y", ".y", line=6)],
                  parameters=[ParameterValue("loop.ctrl.Kc", "Real", 4.0, "x.ssd", 30)])
    return raw(root)


def test_components_get_their_paths_as_new_values_and_the_input_is_unchanged():
    given = loop_in_a_subsystem()
    before = copy.deepcopy(given)
    flat = flatten(given)
    assert list(flat.components) == ["setpoint", "loop.ctrl", "loop.plant"]
    assert flat.components["loop.ctrl"].name == "loop.ctrl"
    assert given == before and given.root.systems["loop"].components["ctrl"].name == "ctrl"
    assert (flat.name, flat.system_name, flat.step_size) == ("test", "root", 0.1)


def test_a_chain_through_system_connectors_becomes_one_connection_with_its_hops():
    flat = flatten(loop_in_a_subsystem())
    ends = {(c.start_element, c.start_connector, c.end_element, c.end_connector): c for c in flat.connections}
    through = ends[("setpoint", "y", "loop.ctrl", "r")]
    assert [(h.line, h.transform) for h in through.hops] == [(5, Affine(3.0, 1.0)), (10, None)]
    assert through.hops[0].end_system == "loop.r" and through.transform is None   # its hops carry them
    assert "lines 5, 10 through system connector loop.r" in through.describe()
    assert ("loop.plant", "y", "loop.ctrl", "y") in ends and len(flat.connections) == 3


def test_a_root_output_is_an_alias_of_the_component_output_with_the_hops_on_the_way():
    out = flatten(loop_in_a_subsystem()).system_outputs["y"]
    assert (out.name, out.component, out.connector) == ("y", "loop.plant", "y")
    assert [(h.line, h.transform, h.end_unit) for h in out.hops] == [(13, Affine(2.0), "degC"), (6, None, None)]


def test_parameters_of_inner_systems_come_first_so_outer_bindings_win():
    flat = flatten(loop_in_a_subsystem())
    assert [(p.name, p.value) for p in flat.parameters] == [("loop.ctrl.Kc", 2.0), ("loop.ctrl.Kc", 4.0)]


def test_an_undriven_system_input_is_open_and_lists_what_it_feeds():
    loop = system("loop", components=[component("ctrl", r="input", u="output")],
                  connectors=[connector("r", "input", "K")], connections=[connection(".r", "ctrl.r", line=7)])
    flat = flatten(raw(system("root", systems=[loop])))
    opened = flat.open_connectors["loop.r"]
    assert (opened.kind, opened.unit) == ("input", "K")
    assert [(comp, conn, [h.line for h in hops]) for comp, conn, hops in opened.sinks] == [("loop.ctrl", "r", [7])]
    assert flat.driven_connectors == set()


def test_a_system_connector_driven_twice_is_refused_naming_both_lines():
    loop = system("loop", components=[component("ctrl", r="input")], connectors=[connector("r", "input")],
                  connections=[connection(".r", "ctrl.r", line=9)])
    root = system("root", components=[component("a", y="output"), component("b", y="output")], systems=[loop],
                  connections=[connection("a.y", "loop.r", line=3), connection("b.y", "loop.r", line=4)])
    with pytest.raises(SetupError, match=r"'loop.r' is driven by two connections \(lines 3 and 4\)"):
        flatten(raw(root))


def test_an_undriven_root_output_is_recorded_without_a_source():
    """SSP 1.0 requires no connector to be connected (issue 30): cosim.plan.build records it as a constant."""
    root = system("root", components=[component("a", y="output")], connectors=[connector("out", "output")])
    out = flatten(raw(root)).system_outputs["out"]
    assert (out.component, out.connector, out.undriven, out.declared.name) == (None, None, "no connection drives it",
                                                                             "out")
