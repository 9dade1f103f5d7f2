"""Whole FMI 3.0 arrays in a system structure, element by element: `expand_arrays` makes a
connector that names a whole array (``outputs``, ``A``) one connector per element, named as fmpy
and fmusim name them (``outputs[1]`` .. ``outputs[4]``, ``A[1,1]`` .. ``A[2,3]``, row-major:
`cosim.model.fmu.element_names`), a connection between two whole arrays of equal shape one
connection per element pair, and a root output connector that a whole array drives one root
output per element (``y`` -> ``y[1]``, ...).  Everything after it (`cosim.plan.build`) sees
scalars and elements only, which the exchange carries (`cosim.run.instances.fmi3`).
"""
from __future__ import annotations

from dataclasses import replace
from collections.abc import Mapping

from ..errors import SetupError
from ..model.fmu import FMUDescription, Variable, describe_shape, element_names, recorded_type
from ..model.structure import Connection, SystemOutput, SystemStructure


def expand_arrays(structure: SystemStructure, fmus: Mapping[str, FMUDescription]) -> SystemStructure:
    """``structure`` with its whole-array connectors, connections and root outputs made element
    by element (the module docstring); the same object when it names no whole array.  A
    connection between a whole array and a scalar, or two arrays of different shapes, is refused
    naming both ends and their shapes."""
    file = structure.display
    _check_open_connectors(structure, fmus)
    components = {}
    for name, comp in structure.components.items():
        connectors = {}
        for conn in comp.connectors.values():
            array = _array(fmus[name], conn.name)
            where = f"ssd:Connector '{conn.name}' of component '{name}' (line {conn.line})"
            names = element_names(conn.name, fmus[name].shape(array, where, file)) if array else [conn.name]
            connectors.update({n: replace(conn, name=n) for n in names})
        components[name] = replace(comp, connectors=connectors) if list(connectors) != list(comp.connectors) \
            else comp
    connections = [e for c in structure.connections for e in _connection(structure, fmus, c)]
    outputs = {o.name: o for out in structure.system_outputs.values() for o in _system_output(structure, fmus, out)}
    if all(a is b for a, b in zip(components.values(), structure.components.values())) \
            and len(connections) == len(structure.connections) and list(outputs) == list(structure.system_outputs):
        return structure
    return replace(structure, components=components, connections=connections, system_outputs=outputs)


def _check_open_connectors(structure: SystemStructure, fmus: Mapping[str, FMUDescription]) -> None:
    """Refuse an undriven system connector (one value, from a ParameterBinding or an input table
    column: `cosim.model.structure.OpenConnector`) that feeds a whole array."""
    for path, target in structure.open_connectors.items():
        for comp, conn, _ in target.sinks:
            array = _array(fmus[comp], conn)
            if array is not None:
                where = f"ssd:Connector '{path}' (line {target.line})"
                shape = fmus[comp].shape(array, where, structure.display)
                raise SetupError(f"system connector '{path}' holds one value and feeds {comp}.{conn}, "
                                 f"{describe_shape(shape)}; connect it to one element "
                                 f"({element_names(conn, shape)[0]}).", file=structure.display, element=where,
                                 variable=path)


def _array(desc: FMUDescription, name: str) -> Variable | None:
    """The whole array ``name`` names, None for a scalar or an element (or no variable: refused later)."""
    var = desc.variables.get(name)
    return var if var is not None and var.dimensions and recorded_type(var) else None


def _connection(structure: SystemStructure, fmus: Mapping[str, FMUDescription], c: Connection) -> list[Connection]:
    """One connection per element pair of two whole arrays of equal shape; ``c`` itself otherwise."""
    ends = ((c.start_element, c.start_connector), (c.end_element, c.end_connector))
    arrays = [_array(fmus[e], n) if e in fmus else None for e, n in ends]
    if not any(arrays):
        return [c]
    where, file = c.describe(), structure.display
    shapes = [fmus[e].shape(a, where, file) if a is not None else () for (e, _), a in zip(ends, arrays)]
    if None in arrays or shapes[0] != shapes[1]:
        (a, an), (b, bn) = ends
        raise SetupError(f"{a}.{an} ({describe_shape(shapes[0])}) and {b}.{bn} ({describe_shape(shapes[1])}) "
                         "differ in shape; a connection joins two scalars, two elements, or two whole arrays of "
                         "the same shape.", file=file, element=where)
    return [replace(c, start_connector=s, end_connector=e)
            for s, e in zip(element_names(c.start_connector, shapes[0]), element_names(c.end_connector, shapes[1]))]


def _system_output(structure: SystemStructure, fmus: Mapping[str, FMUDescription],
                   out: SystemOutput) -> list[SystemOutput]:
    """A root output connector a whole array drives: one per element, named after it (``y[1]``)."""
    array = _array(fmus[out.component], out.connector) if out.component is not None else None
    if array is None:
        return [out]
    shape = fmus[out.component].shape(array, f"ssd:Connector '{out.name}' of the root system (line {out.line})",
                                      structure.display)
    return [replace(out, name=n, connector=e)
            for n, e in zip(element_names(out.name, shape), element_names(out.connector, shape))]
