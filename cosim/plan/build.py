"""Validate a system structure against its FMUs and order its evaluation: the `Plan`.

Everything here runs before any FMU is instantiated.  `build_plan` takes each FMU's model
description (`cosim.read.description.describe_fmus`), checks the connectors, connections and
root-system outputs against them, resolves the parameter values (`cosim.plan.parameters`)
and the transformations of every connection (`cosim.plan.routing`), and orders the evaluation
from the connection graph (`cosim.plan.graph`: direct-feedthrough loops from the FMI 2.0
ModelStructure are refused).
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence

from ..errors import SetupError, did_you_mean
from ..model.fmu import FMUDescription, Variable, exchange_type, recorded_type, unit_of
from ..model.frozen import FrozenMap
from ..model.structure import (
    LOOP_MODES,
    Connection,
    Experiment,
    Hop,
    LoopMode,
    ParameterValue,
    Plan,
    RecordedOutput,
    Route,
    ScenarioFiles,
    SystemOutput,
    SystemStructure,
)
from ..model.transforms import Affine
from ..model.units import SystemUnits, fmu_units
from .arrays import expand_arrays
from .graph import algebraic_loops, feedthrough_sequence, gauss_seidel_order, settling_shortcuts, variable_order
from .parameters import open_inputs, resolve_parameters
from .routing import connector_unit, path_transform
from .solvers import check_model_exchange, solvers_of


def build_plan(structure: SystemStructure, fmus: Mapping[str, FMUDescription],
               extra_parameters: Sequence[ParameterValue] = (), loops: LoopMode = "iterate") -> Plan:
    """Check the structure against its FMUs' descriptions (``fmus``:
    `cosim.read.description.describe_fmus`) and order it; ``extra_parameters`` are applied last
    (command-line parameter sets and start values); ``loops``: how algebraic loops are run
    (`cosim.run.loops`).  Nothing given is changed; the plan holds nothing of the structure but
    what a run, a pack, a sweep and `cosim info` read (`cosim.model.structure.Plan`)."""
    file = structure.display
    if loops not in LOOP_MODES:
        raise SetupError(f"unknown loop handling '{loops}'; choose one of {', '.join(LOOP_MODES)}.",
                         element="--loops")
    check_model_exchange(structure, fmus)
    structure = expand_arrays(structure, fmus)
    units = SystemUnits.of(structure.units, {name: fmu_units(desc.unit_definitions, desc.path.name)
                                             for name, desc in fmus.items()}, file)
    fmus, outputs, inputs = _check_connectors(structure, fmus, units)
    routes = _check_connections(structure, fmus, units)
    start_values = resolve_parameters(structure, fmus, list(extra_parameters), units)
    system_outputs = _system_outputs(structure, outputs, units, [*structure.parameters, *extra_parameters])
    _warn_unrecorded(structure, fmus, outputs, inputs)
    recorded_units = _recorded_units(structure, outputs, inputs, system_outputs)
    dependencies = {name: desc.output_dependencies for name, desc in fmus.items()}
    output_names = {c: [v.name for v in vs] for c, vs in outputs.items()}
    found = algebraic_loops(routes, output_names, dependencies)
    order = variable_order(routes, output_names, dependencies, file, cut=found)
    feedthrough = feedthrough_sequence(order, routes, dependencies)
    if loops == "delay":  # a component on a loop is read once per communication point, as libcosim reads all
        delayed = {c for loop in found for c in loop.components}
        feedthrough = [c for c in feedthrough if c not in delayed]
    read_once, set_once = settling_shortcuts(feedthrough, routes)
    return Plan(name=structure.name, system_name=structure.system_name,
                files=ScenarioFiles(structure.ssd_file, structure.base_dir, structure.archive),
                experiment=Experiment(structure.start_time, structure.stop_time, structure.step_size,
                                      structure.step_size_source, structure.algorithm),
                components=FrozenMap(structure.components), fmus=FrozenMap(fmus),
                solvers=FrozenMap(solvers_of(structure, fmus)), routes=tuple(routes),
                start_values=tuple(start_values), outputs=FrozenMap((c, tuple(vs)) for c, vs in outputs.items()),
                inputs=FrozenMap((c, tuple(vs)) for c, vs in inputs.items()),
                feedthrough_sequence=tuple(feedthrough), read_in_settling_only=frozenset(read_once),
                set_in_settling_only=frozenset(set_once), algebraic_loops=tuple(found), loop_mode=loops,
                gauss_seidel_order=tuple(gauss_seidel_order(list(structure.components), routes)),
                system_outputs=FrozenMap(system_outputs), columns=tuple(_columns(structure, outputs, inputs)),
                units=FrozenMap(recorded_units), unit_scopes=units, open_inputs=open_inputs(structure, fmus, units),
                hierarchy=structure.hierarchy)



# --------------------------------------------------------------------------- connectors and connections

def _check_connectors(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits):
    """The descriptions knowing the array elements connectors name (`FMUDescription.resolve`),
    and each component's output and input connectors' variables, checked."""
    file = structure.display
    outputs: dict[str, list[Variable]] = {}
    inputs: dict[str, list[Variable]] = {}
    described = {}
    for name, comp in structure.components.items():
        outputs[name], inputs[name] = [], []
        places = [f"ssd:Connector '{conn.name}' of component '{name}' (line {conn.line})"
                  for conn in comp.connectors.values()]
        desc, variables = fmus[name].resolve(list(comp.connectors), places, file)
        for conn, var, where in zip(comp.connectors.values(), variables, places):
            if conn.kind in ("input", "output") and var.causality != conn.kind:
                raise SetupError(f"declared kind='{conn.kind}' but the FMU {desc.path.name} declares it "
                                 f"causality='{var.causality}'.", file=file, element=where, variable=conn.name)
            if var.causality in ("input", "output"):
                _check_exchangeable(desc, var, where, file)
            if conn.type is not None and conn.type not in (exchange_type(var), var.type) \
                    and not (conn.type == "Enumeration" and var.type == "Enumeration"):
                raise SetupError(f"declared as {conn.type} but the FMU {desc.path.name} declares {var.type}.",
                                 file=file, element=where, variable=conn.name)
            if exchange_type(var) == "Real":  # FMI 2.0 Real, FMI 3.0 Float64: the types with a unit
                connector_unit(units, name, var, conn.unit, where, file)  # refuses a different dimension
            if var.causality == "output":
                outputs[name].append(var)
            elif var.causality == "input":
                inputs[name].append(var)
        described[name] = desc
    return described, outputs, inputs


def _check_exchangeable(desc: FMUDescription, var: Variable, where: str, file: str) -> None:
    """Refuse a connector the exchange cannot carry: a type without an exchange type
    (`cosim.model.fmu.exchange_type`) or a String or Binary FMI 3.0 array (numeric and Boolean
    ones are made element by element, `cosim.plan.arrays`)."""
    if exchange_type(var) is None:
        raise SetupError(f"{var.name} has the type {var.type} in {desc.path.name}; connectors of that type are "
                         "not supported (FMI 2.0 Real, Integer, Boolean, String, Enumeration and FMI 3.0 Float64, "
                         "Float32, Int8..UInt64, Enumeration, Boolean, String, Binary are).", file=file, element=where, variable=var.name)
    if var.dimensions:
        raise SetupError(f"{var.name} is a {var.type} array in {desc.path.name}; the master exchanges numeric and "
                         "Boolean arrays (whole, or element by element), not String or Binary ones.",
                         file=file, element=where, variable=var.name)


def _check_connections(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits):
    file = structure.display
    routes: list[Route] = []
    driven: dict[tuple[str, str], Connection] = {}
    for c in structure.connections:
        where = c.describe()
        a = _endpoint(structure, fmus, c.start_element, c.start_connector, where)
        b = _endpoint(structure, fmus, c.end_element, c.end_connector, where)
        # SSP 1.0: data flows from output to input whatever the start/end naming
        if a.causality == "output" and b.causality == "input":
            (src, sv), (dst, dv) = (c.start_element, a), (c.end_element, b)
        elif a.causality == "input" and b.causality == "output":
            (src, sv), (dst, dv) = (c.end_element, b), (c.start_element, a)
        elif a.causality == b.causality == "output":
            raise SetupError(f"output wired to output ({c.start_element}.{a.name} and {c.end_element}.{b.name}); "
                             "a connection goes from an output to an input.", file=file, element=where)
        elif a.causality == b.causality == "input":
            raise SetupError(f"input wired to input ({c.start_element}.{a.name} and {c.end_element}.{b.name}); "
                             "a connection goes from an output to an input.", file=file, element=where)
        else:
            bad = a if a.causality not in ("input", "output") else b
            raise SetupError(f"'{bad.name}' has causality '{bad.causality}'; only outputs wired to inputs "
                             "are supported.", file=file, element=where, variable=bad.name)
        if exchange_type(sv) != exchange_type(dv):
            raise SetupError(f"{sv.type} output {src}.{sv.name} wired to {dv.type} input {dst}.{dv.name}; "
                             "both ends must have the same type.", file=file, element=where)
        key = (dst, dv.name)
        if key in driven:
            raise SetupError(f"input {dst}.{dv.name} is driven by two connections (the other: "
                             f"{driven[key].describe()}).", file=file, element=where, variable=dv.name)
        driven[key] = c
        # a connection between two components is a path of one hop
        hops = c.hops or (Hop(c.line, None, None, None, None, c.transform, c.suppress_unit_conversion),)
        routes.append(Route(src, sv, dst, dv, path_transform(structure, units, hops, (src, sv), (dst, dv), where)))
    return routes


def _endpoint(structure: SystemStructure, fmus: dict[str, FMUDescription], element: str, connector: str,
              where: str) -> Variable:
    file = structure.display
    if element not in structure.components:
        raise SetupError(f"unknown component '{element}'.", file=file, element=where,
                         hint=did_you_mean(element, structure.components))
    comp = structure.components[element]
    if connector not in comp.connectors:
        var = fmus[element].variables.get(connector)
        if var is not None:
            raise SetupError(f"'{connector}' is a variable of {fmus[element].path.name} but not a declared "
                             f"connector of component '{element}'.", file=file, element=where,
                             variable=connector, hint=f"Add <ssd:Connector name=\"{connector}\" "
                             f"kind=\"{var.causality}\"/> to its ssd:Connectors.")
        raise SetupError(f"component '{element}' has no connector '{connector}'.", file=file, element=where,
                         variable=connector, hint=did_you_mean(connector, comp.connectors))
    return fmus[element].variable(connector, where, file)


def _system_outputs(structure: SystemStructure, outputs: dict[str, list[Variable]],
                    units: SystemUnits, values: Sequence[ParameterValue]) -> dict[str, RecordedOutput]:
    """Each root-system output connector is an alias of a recorded component output (cosim.read.flatten).

    A Real one is recorded as the root connector's value: the output, read in its FMU's unit,
    taken hop by hop to the root connector's unit (`cosim.plan.routing.hops_map`; the connector's own
    unit if it declares one, else the unit carried along the path).  An undriven one is a
    constant (`_undriven_output`)."""
    file = structure.display
    recorded: dict[str, RecordedOutput] = {}
    by_name = {c: {v.name: v for v in vs} for c, vs in outputs.items()}
    columns = {f"{c}.{v.name}" for c, vs in outputs.items() for v in vs}
    for out in structure.system_outputs.values():
        where = f"ssd:Connector '{out.name}' of the root system (line {out.line})"
        if out.component is None:
            recorded[out.name] = _undriven_output(structure, out, where, values)
            continue
        var = by_name[out.component].get(out.connector)
        if var is None:
            raise SetupError(f"it is driven by {out.component}.{out.connector}, which is not an output "
                             "connector of that component.", file=file, element=where, variable=out.name)
        if not recorded_type(var):  # exchanged, not recorded: named by _warn_unrecorded
            continue
        if out.name in columns:
            raise SetupError(f"the name clashes with the component output {out.name} in the results.",
                             file=file, element=where, variable=out.name)
        transform = path_transform(structure, units, out.hops, (out.component, var), None, where)
        declared = [u for hop in out.hops for u in (hop.start_unit, hop.end_unit) if u]
        unit = declared[-1] if declared else _unit(structure, out.component, var)
        recorded[out.name] = RecordedOutput(out.name, out.component, out.connector, transform, unit)
    return recorded


def _undriven_output(structure: SystemStructure, out: SystemOutput, where: str,
                     values: Sequence[ParameterValue]) -> RecordedOutput:
    """A root output connector that no component output drives: SSP 1.0 requires no connector
    to be connected, so it is accepted, with a warning naming it.  Its column holds, in every
    row, the value a ParameterBinding (or a parameter set given to the run) gives the connector
    by its name (the last one, as for parameters), else NaN: SSP 1.0 connectors have no start
    value of their own (``ssc:Real`` has only a ``unit``), and a ParameterBinding is how an SSD
    gives a system connector a value (`cosim.plan.parameters.bind_system_connectors`)."""
    file, declared = structure.display, out.declared
    unit = declared.unit if declared is not None else None
    given = [p for p in values if p.name == out.name]
    value, origin = math.nan, None
    if given:
        p = given[-1]
        if isinstance(p.value, str):
            raise SetupError(f"the value '{p.value}' of undriven root output '{out.name}' is not a number; its "
                             "column holds numbers only.", file=p.file, element=p.element(), variable=out.name)
        if p.unit is not None and p.unit != unit:
            raise SetupError(f"the value of undriven root output '{out.name}' is given in '{p.unit}', its "
                             f"connector's unit is {repr(unit) if unit else 'not declared'}.", file=p.file,
                             element=p.element(), variable=out.name,
                             hint="Give the value in the connector's unit (no conversion is made).")
        value = float(p.value)
        if p.transform is not None:  # a mapping's LinearTransformation (SSP 1.0 MappingEntry)
            value = p.transform.apply(value)
        origin = f"{p.file}:{p.line}" if p.line else p.file  # line 0: --start-value
        origin += f", mapped by {p.mapping}" if p.mapping else ""
    held = f"the value {value:g} from {origin}" if origin else "NaN (no ParameterBinding gives it a value)"
    warnings.warn(f"{file}, {where}, variable '{out.name}': no component output drives this output connector "
                  f"({out.undriven}); SSP 1.0 allows it, its column holds {held} in every row.",
                  RuntimeWarning, stacklevel=2)
    return RecordedOutput(out.name, None, None, Affine(0.0, value), unit, line=out.line, origin=origin)


# --------------------------------------------------------------------------- recording

class NotRecorded(RuntimeWarning):
    """Variables a run exchanges and does not record (String, Binary), and those of a single FMU it
    neither exchanges nor records (String and Binary arrays, Clocks): named once per plan."""


def _warn_unrecorded(structure: SystemStructure, fmus: Mapping[str, FMUDescription],
                     outputs: dict[str, list[Variable]], inputs: dict[str, list[Variable]]) -> None:
    """One warning naming every connector whose values are exchanged and not recorded, the root
    output connectors they drive, and a single FMU's inputs and outputs that are no connector."""
    names = [f"{c}.{v.name} ({v.type})" for c in outputs for v in outputs[c] + inputs[c] if not recorded_type(v)]
    unrecorded = {(c, v.name) for c in outputs for v in outputs[c] if not recorded_type(v)}
    names += [f"root output '{out.name}'" for out in structure.system_outputs.values()
              if (out.component, out.connector) in unrecorded]
    parts = [f"exchanged, not recorded (a result file holds numbers): {', '.join(names)}"] if names else []
    left = _left_out(structure, fmus)
    if left:
        parts.append(f"neither exchanged nor recorded: {', '.join(left)}")
    if parts:
        warnings.warn(NotRecorded(f"{structure.display}: {'; '.join(parts)}"), stacklevel=3)


def _left_out(structure: SystemStructure, fmus: Mapping[str, FMUDescription]) -> list[str]:
    """The inputs and outputs of a single FMU run as a system (`cosim.read.single`, which makes
    every other one a connector) that are no connector: String and Binary arrays, FMI 3.0 Clocks."""
    if structure.ssd_file.suffix.lower() != ".fmu":
        return []
    left = []
    for name, comp in structure.components.items():
        arrays = {c.partition("[")[0] for c in comp.connectors}   # made element by element (cosim.plan.arrays)
        for v in fmus[name].variables.values():
            if v.causality in ("input", "output") and v.name not in comp.connectors and v.name not in arrays:
                shape = "×".join(str(d) for d in v.dimensions)
                left.append(f"{name}.{v.name} ({v.type}{f' array of {shape}' if shape else ''})")
    return left


def _columns(structure: SystemStructure, outputs: dict[str, list[Variable]],
             inputs: dict[str, list[Variable]]) -> list[str]:
    """The recorded connectors component by component in SSD order, connectors as each component
    lists them: every output and input but String and Binary ones (exchanged, not recorded)."""
    columns = []
    for name, comp in structure.components.items():
        recorded = {v.name for v in outputs[name] + inputs[name] if recorded_type(v)}
        columns += [f"{name}.{conn}" for conn in comp.connectors if conn in recorded]
    return columns


def _recorded_units(structure: SystemStructure, outputs: dict[str, list[Variable]],
                    inputs: dict[str, list[Variable]],
                    system_outputs: dict[str, RecordedOutput]) -> dict[str, str | None]:
    units = {f"{comp}.{v.name}": _unit(structure, comp, v) for comp in outputs for v in outputs[comp] + inputs[comp]}
    units.update({name: out.unit for name, out in system_outputs.items()})
    return units


def _unit(structure: SystemStructure, comp: str, var: Variable) -> str | None:
    """A recorded connector's unit: its FMU variable's own (values are recorded as the FMU
    computes or receives them, after any unit conversion of the connection), else the unit the
    SSD connector gives a variable without one (`cosim.plan.routing.connector_unit`); None: no unit."""
    declared = structure.components[comp].connectors.get(var.name)
    return unit_of(var) or (declared.unit if declared is not None else None)
