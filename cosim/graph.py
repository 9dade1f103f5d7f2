"""Validate a system structure against its FMUs and order its evaluation.

Everything here runs before any FMU is instantiated.  `build_plan` checks the
connectors, connections and parameter values against each FMU's model
description, detects direct-feedthrough (algebraic) loops from the FMI 2.0
ModelStructure, and returns a `Plan`: the routes and the orders the execution
follows.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field, replace
from functools import partial

from fmpy.model_description import ModelVariable

from .errors import SetupError, did_you_mean
from .flatten import bind_system_connectors
from .description import ArrayElement, FMUDescription, describe, exchange_type, unit_of
from .solvers import check_model_exchange
from .structure import Connection, Hop, OpenConnector, ParameterValue, SystemStructure
from .units import (
    IDENTITY,
    Affine,
    SystemUnits,
    UnitScope,
    check_agree,
    conversion,
    fmu_units,
    then,
)

SETTABLE_CAUSALITIES = ("parameter", "input")


@dataclass
class Route:
    """One connection, resolved: output (src) to input (dst); ``factor``/``offset`` map the
    source FMU's value to the destination FMU's value: the unit conversion and the
    LinearTransformation composed (see `_hops_map`)."""
    src: str
    src_var: ModelVariable
    dst: str
    dst_var: ModelVariable
    factor: float
    offset: float


@dataclass
class StartValue:
    component: str
    variable: ModelVariable
    value: float | int | bool | str
    origin: str


@dataclass
class Plan:
    structure: SystemStructure
    fmus: dict[str, FMUDescription]
    routes: list[Route]
    start_values: list[StartValue]
    #: per component, the connector variables recorded and exchanged, in SSD order
    outputs: dict[str, list[ModelVariable]]
    inputs: dict[str, list[ModelVariable]]
    #: components whose outputs must be re-read after their inputs are set at a
    #: communication point (direct feedthrough), in dependency order; may repeat
    feedthrough_sequence: list[str]
    #: Gauss-Seidel order: upstream first, SSD order inside a loop
    gauss_seidel_order: list[str]
    notes: list[str] = field(default_factory=list)
    #: components of the feedthrough sequence whose outputs nobody reads before the settling
    #: re-reads them: the exchange skips their first read (`settling_shortcuts`)
    read_in_settling_only: set[str] = field(default_factory=set)
    #: components of the feedthrough sequence whose inputs are final when the settling sets
    #: them: the exchange does not set them again
    set_in_settling_only: set[str] = field(default_factory=set)

    def recorded(self) -> tuple[list[str], list[str]]:
        """The result names of the recorded outputs (the root system's output connectors last)
        and inputs: every connector but String ones, which are exchanged, not recorded
        (`cosim.execution.Execution.recorder_sources`)."""
        def names(group: dict[str, list[ModelVariable]]) -> list[str]:
            return [f"{c}.{v.name}" for c, vs in group.items() for v in vs if exchange_type(v) != "String"]
        return names(self.outputs) + list(self.structure.system_outputs), names(self.inputs)


def build_plan(structure: SystemStructure, extra_parameters: list[ParameterValue] = ()) -> Plan:
    """Check the structure against the FMUs (already located) and order it."""
    file = str(structure.ssd_file)
    fmus = {name: describe(comp.fmu_path, f"ssd:Component '{name}' (line {comp.line})", file,
                           comp.implementation)
            for name, comp in structure.components.items()}
    check_model_exchange(structure, fmus)
    units = SystemUnits(structure.units, {name: fmu_units(desc.md.unitDefinitions, desc.path.name)
                                          for name, desc in fmus.items()}, file)
    outputs, inputs = _check_connectors(structure, fmus, units)
    routes = _check_connections(structure, fmus, units)
    start_values = _check_parameters(structure, fmus, list(extra_parameters), units)
    _check_system_outputs(structure, outputs, units)
    order = _variable_order(structure, fmus, routes, outputs)
    feedthrough = _feedthrough_sequence(order, fmus, routes)
    read_once, set_once = settling_shortcuts(feedthrough, routes)
    return Plan(structure=structure, fmus=fmus, routes=routes, start_values=start_values,
                outputs=outputs, inputs=inputs, feedthrough_sequence=feedthrough,
                read_in_settling_only=read_once, set_in_settling_only=set_once,
                gauss_seidel_order=_gauss_seidel_order(structure, routes))


# --------------------------------------------------------------------------- connectors

def _check_connectors(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits):
    file = str(structure.ssd_file)
    outputs: dict[str, list[ModelVariable]] = {}
    inputs: dict[str, list[ModelVariable]] = {}
    for name, comp in structure.components.items():
        desc = fmus[name]
        outputs[name], inputs[name] = [], []
        for conn in comp.connectors.values():
            where = f"ssd:Connector '{conn.name}' of component '{name}' (line {conn.line})"
            var = desc.variable(conn.name, where, file)
            if conn.kind in ("input", "output") and var.causality != conn.kind:
                raise SetupError(f"declared kind='{conn.kind}' but the FMU {desc.path.name} declares it "
                                 f"causality='{var.causality}'.", file=file, element=where, variable=conn.name)
            if var.causality in ("input", "output"):
                _check_exchangeable(desc, var, where, file)
            if conn.type is not None and conn.type != exchange_type(var):
                raise SetupError(f"declared as {conn.type} but the FMU {desc.path.name} declares {var.type}.",
                                 file=file, element=where, variable=conn.name)
            if exchange_type(var) == "Real":  # FMI 2.0 Real, FMI 3.0 Float64: the types with a unit
                _connector_unit(units, name, var, conn.unit, where, file)  # refuses a different dimension
            if var.causality == "output":
                outputs[name].append(var)
            elif var.causality == "input":
                inputs[name].append(var)
    return outputs, inputs


def _check_exchangeable(desc: FMUDescription, var: ModelVariable, where: str, file: str) -> None:
    """Refuse a connector the exchange cannot carry: a type without an exchange type
    (`cosim.description.exchange_type`) or a whole FMI 3.0 array (SSP 1.0 connectors are scalars;
    one element is named as ``vector[1]``, see `FMUDescription.variable`)."""
    if exchange_type(var) is None:
        raise SetupError(f"{var.name} has the type {var.type} in {desc.path.name}; connectors of that type are "
                         "not supported (FMI 2.0 Real, Integer, Boolean, String and FMI 3.0 Float64, Int32, "
                         "Boolean, String are).", file=file, element=where, variable=var.name)
    if var.dimensions:
        raise SetupError(f"{var.name} is an array in {desc.path.name}; a connector carries one element, "
                         f"named {var.name}[1] for the first one.", file=file, element=where, variable=var.name)


def _check_connections(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits):
    file = str(structure.ssd_file)
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
        if c.has_transformation and exchange_type(sv) != "Real":
            raise SetupError("a LinearTransformation applies to Real connections only; "
                             f"this one is {sv.type}.", file=file, element=where)
        key = (dst, dv.name)
        if key in driven:
            raise SetupError(f"input {dst}.{dv.name} is driven by two connections (the other: "
                             f"{driven[key].describe()}).", file=file, element=where, variable=dv.name)
        driven[key] = c
        if exchange_type(sv) != "Real":
            factor, offset = c.factor, c.offset
        else:  # a connection between two components is a path of one hop
            hops = c.hops or (Hop(c.line, None, None, None, None, c.factor, c.offset, c.has_transformation,
                                  c.suppress_unit_conversion),)
            factor, offset = _hops_map(structure, units, hops, _source_view(structure, units, (src, sv), where),
                                       (dst, dv), where)
        routes.append(Route(src, sv, dst, dv, factor, offset))
    return routes


def _connector_unit(units: SystemUnits, comp: str, var: ModelVariable, declared: str | None, where: str,
                    file: str) -> tuple[str | None, UnitScope, Affine, Affine]:
    """A Real connector's unit, where its name is looked up, and the maps from the FMU variable's
    unit to the connector's unit and back.

    The FMU variable's unit (`unit_of`) is what the FMU computes in; an SSD ``ssc:Real unit``
    that names another unit of the same dimension makes the SSD connector a view of the
    variable in that unit: connections convert from and to the connector's unit (and a
    LinearTransformation with suppressUnitConversion works on the connector's values), while
    the FMU is still set and read, and results recorded, in its own unit.  When only one of
    the two is given it is the connector's unit (an SSD may so give a unit to an FMU variable
    without one); when neither is, the connector has no unit and is never converted.
    """
    own = unit_of(var)
    if declared is None or own is None or declared == own:
        scope = units.for_connector(comp) if declared else units.for_variable(comp)
        return declared or own, scope, IDENTITY, IDENTITY
    kw = {"file": file, "element": where, "variable": var.name}
    view = units.for_connector(comp).resolve(declared, **kw)
    fmu = units.for_variable(comp).resolve(own, **kw)
    context = f"the SSD declares unit '{declared}' where the FMU declares '{own}'; "
    return declared, units.for_connector(comp), conversion(fmu, view, context, **kw), conversion(view, fmu, **kw)


def _unit_step(start: tuple[str | None, UnitScope], end: tuple[str | None, UnitScope], context: str,
               hint: str = "Correct one of the units, or add suppressUnitConversion=\"true\" with an "
               "ssc:LinearTransformation that maps the values.", **where) -> Affine:
    """The conversion on one connection from the start connector's unit to the end connector's
    (each a name and where it is looked up): none when either has no unit; for the same name,
    only a check that both places define it alike."""
    (start_name, start_scope), (end_name, end_scope) = start, end
    if not (start_name and end_name):
        return IDENTITY
    if start_name == end_name:
        a, b = start_scope.find(start_name), end_scope.find(end_name)
        if a is not None and b is not None:
            check_agree({start_name: a}, {end_name: b}, file=where["file"], element=where["element"])
        return IDENTITY
    return conversion(start_scope.resolve(start_name, **where), end_scope.resolve(end_name, **where), context,
                      **where, hint=hint)


def _source_view(structure: SystemStructure, units: SystemUnits, source: tuple[str, ModelVariable],
                 where: str) -> tuple[str | None, UnitScope, Affine, str]:
    """A component output as the start of a path: its connector's unit, where that is looked up,
    the map from the FMU's value to the connector's, and its name."""
    src, sv = source
    name, scope, to_view, _ = _connector_unit(units, src, sv, structure.components[src].connectors[sv.name].unit,
                                              where, str(structure.ssd_file))
    return name, scope, to_view, f"{src}.{sv.name}"


def _hops_map(structure: SystemStructure, units: SystemUnits, hops: tuple[Hop, ...],
              start: tuple[str | None, UnitScope, Affine, str], target: tuple[str, ModelVariable] | None,
              where: str) -> Affine:
    """The affine map along a path through system connectors (`cosim.flatten`): from the value
    at its start (``start``: the unit, where it is looked up, the map from the value given to
    the start's unit, a name for messages; see `_source_view`) to the target FMU's value, or,
    with no ``target``, to the value of the root-system output connector that ends the path.

    SSP 1.0 (SystemStructureDescription.xsd, Connection and ``suppressUnitConversion``;
    SystemStructureCommon.xsd LinearTransformation) applies to each connection on the way:
    convert from its start connector's unit to its end connector's unit, then its
    LinearTransformation (target = factor·source + offset); with
    ``suppressUnitConversion="true"`` on a connection, only its transformation.  A connection
    between two components is a path of one hop.  The composition is one factor and one
    offset, so the exchange costs the same as a plain LinearTransformation.  No conversion
    when a connector has no unit (FMI 2.0 §2.2.7: a variable without a unit is not checked)
    or both ends name the same unit.  The component ends take their connector
    views (`_connector_unit`).  A system connector that declares a unit holds its value in
    that unit (names looked up in the SSD's ``ssd:Units``, then the built-ins).  One without
    a unit is transparent: it carries the unit of what drives it, so nothing is converted at
    it — SSP 1.0 gives such a connector no unit of its own, and a graphical tool's pass-through
    port must not change a value; converting end to end would also skip the hops'
    transformations in between.  A hop between units of different dimensions is refused.
    """
    file = str(structure.ssd_file)
    name, scope, result, source = start
    ssd_scope = UnitScope(units.ssd)
    from_view = IDENTITY
    for hop in hops:
        if hop.end_system is None:  # the component input (or parameter, for a constant) that ends the path
            dst, dv = target
            declared = structure.components[dst].connectors.get(dv.name)
            end_name, end_scope, _, from_view = _connector_unit(
                units, dst, dv, declared.unit if declared else None, where, file)
            end_label = f"{dst}.{dv.name}"
        else:
            end_name, end_scope = (hop.end_unit, ssd_scope) if hop.end_unit else (name, scope)
            end_label = f"system connector '{hop.end_system}'"
        start_label = f"system connector '{hop.start_system}'" if hop.start_system else source
        if not hop.suppress:
            context = f"{start_label} is in '{name}' and {end_label} in '{end_name}': "
            element = where
            if len(hops) > 1:  # name the connection of the path
                context = f"on the connection at line {hop.line}, {context}"
                element = f"{where}, ssd:Connection (line {hop.line})"
            result = then(result, _unit_step(
                (name, scope), (end_name, end_scope), context, file=file, element=element,
                variable=hop.end_system or hop.start_system or target[1].name))
        result = then(result, (hop.factor, hop.offset))
        name, scope = end_name, end_scope
    return then(result, from_view)


def _endpoint(structure: SystemStructure, fmus: dict[str, FMUDescription], element: str, connector: str,
              where: str) -> ModelVariable:
    file = str(structure.ssd_file)
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


def _check_system_outputs(structure: SystemStructure, outputs: dict[str, list[ModelVariable]],
                          units: SystemUnits) -> None:
    """Each root-system output connector is an alias of a recorded component output (cosim.flatten).

    A Real one is recorded as the root connector's value: the output, read in its FMU's unit,
    taken hop by hop to the root connector's unit (`_hops_map`; the connector's own unit if it
    declares one, else the unit carried along the path)."""
    file = str(structure.ssd_file)
    for out in list(structure.system_outputs.values()):
        where = f"ssd:Connector '{out.name}' of the root system (line {out.line})"
        var = next((v for v in outputs[out.component] if v.name == out.connector), None)
        if var is None:
            raise SetupError(f"it is driven by {out.component}.{out.connector}, which is not an output "
                             "connector of that component.", file=file, element=where, variable=out.name)
        if (out.factor, out.offset) != (1.0, 0.0) and exchange_type(var) != "Real":
            raise SetupError(f"a LinearTransformation applies to Real connections only; "
                             f"{out.component}.{out.connector} is {var.type}.", file=file, element=where,
                             variable=out.name)
        if any(f"{c}.{v.name}" == out.name for c, vs in outputs.items() for v in vs):
            raise SetupError(f"the name clashes with the component output {out.name} in the results.",
                             file=file, element=where, variable=out.name)
        if exchange_type(var) == "Real":
            factor, offset = _hops_map(structure, units, out.hops,
                                       _source_view(structure, units, (out.component, var), where), None, where)
            structure.system_outputs[out.name] = replace(out, factor=factor, offset=offset)


# --------------------------------------------------------------------------- parameters

def _check_parameters(structure: SystemStructure, fmus: dict[str, FMUDescription],
                      extra: list[ParameterValue], units: SystemUnits) -> list[StartValue]:
    """Component bindings, then system bindings (inner systems first), then extra (command-line)
    sets: later wins.  Values naming an undriven system connector go to what it feeds (cosim.flatten)."""
    resolved: dict[tuple[str, str], StartValue] = {}
    for name, comp in structure.components.items():
        for p in comp.parameters:
            _apply_parameter(resolved, name, p.name, p, fmus[name], units)
    system_values = bind_system_connectors(structure.open_connectors, structure.driven_connectors,
                                           list(structure.parameters) + extra, str(structure.ssd_file),
                                           partial(_through_hops, structure, fmus, units))
    for p in system_values:
        comp_name, var_name = split_system_name(structure, p)
        _apply_parameter(resolved, comp_name, var_name, p, fmus[comp_name], units)
    return list(resolved.values())


def _through_hops(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits,
                  p: ParameterValue, open_connector: OpenConnector, comp: str, conn: str,
                  hops: tuple[Hop, ...]) -> ParameterValue:
    """The value a component connector gets from ``p``, given to an open system connector: the
    connector holds it in its own unit if it declares one (converted from ``p``'s unit, as a
    parameter value is), else in ``p``'s unit; then each hop as on a connection (`_hops_map`),
    ending in the FMU variable's unit.  A variable that is not Real gets the value through the
    transformations only (Real and Integer values; others only where there is none)."""
    where = (f"ssv:Parameter '{p.name}' (line {p.line}) for {comp}.{conn} through system connector "
             f"'{open_connector.path}'")
    var = fmus[comp].variable(conn, where, p.file)
    numeric = p.type in ("Real", "Integer")
    if exchange_type(var) != "Real" or not numeric:
        factor, offset = IDENTITY
        for hop in hops:
            factor, offset = then((factor, offset), (hop.factor, hop.offset))
        if (factor, offset) == IDENTITY:
            return replace(p, name=f"{comp}.{conn}")
        if not numeric:
            raise SetupError(f"a {p.type} value cannot go through the LinearTransformation on the way "
                             f"from system connector '{p.name}' to {comp}.{conn}.", file=p.file,
                             element=f"ssv:Parameter (line {p.line})", variable=p.name)
        return replace(p, name=f"{comp}.{conn}", type="Real", value=factor * float(p.value) + offset)
    kw = {"file": p.file, "element": where, "variable": open_connector.path}
    unit, scope = p.unit, units.for_value(comp, p.units, file=p.file, element=where)
    given = IDENTITY
    if open_connector.unit:
        own = UnitScope(units.ssd)
        given = _unit_step((p.unit, scope), (open_connector.unit, own),
                           f"the value is given in '{p.unit}' and system connector '{open_connector.path}' is in "
                           f"'{open_connector.unit}': ", "Give the value in a unit of the connector's dimension.",
                           **kw)
        unit, scope = open_connector.unit, own
    factor, offset = _hops_map(structure, units, hops, (unit, scope, given, f"system connector '{p.name}'"),
                               (comp, var), where)
    return replace(p, name=f"{comp}.{conn}", type="Real", value=factor * float(p.value) + offset, unit=None)


def split_system_name(structure: SystemStructure, p: ParameterValue) -> tuple[str, str]:
    """The component and the variable a system-level name ``comp.var`` names (the longest
    component path first: components of nested systems have dotted names)."""
    for comp in sorted(structure.components, key=len, reverse=True):
        if p.name.startswith(comp + "."):
            return comp, p.name[len(comp) + 1:]
    raise SetupError(f"system-level parameter '{p.name}' does not start with a component name "
                     "('component.variable').", file=p.file, element=f"ssv:Parameter (line {p.line})",
                     variable=p.name, hint=did_you_mean(p.name.rpartition(".")[0], structure.components))


def _apply_parameter(resolved: dict, comp: str, var_name: str, p: ParameterValue, desc: FMUDescription,
                     units: SystemUnits) -> None:
    where = f"ssv:Parameter '{p.name}' (line {p.line}) for component '{comp}'"
    var = desc.variable(var_name, where, p.file)
    if var.causality not in SETTABLE_CAUSALITIES or var.variability == "constant":
        raise SetupError(f"'{var_name}' has causality '{var.causality}' and variability '{var.variability}'; "
                         "only parameters and inputs (non-constant) can be given values.",
                         file=p.file, element=where, variable=var_name)
    value = _coerce(p, var, where)
    origin = f"{p.file}:{p.line}"
    if exchange_type(var) == "Real" and p.unit is not None and unit_of(var) not in (None, p.unit):
        value = _convert_value(p, var, comp, value, where, units)
        origin += f", given as {p.value:g} {p.unit}"
    if exchange_type(var) in ("Real", "Integer"):
        lo = float(var.min) if var.min is not None else None
        hi = float(var.max) if var.max is not None else None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise SetupError(f"value {value} is outside the variable's range [{var.min}, {var.max}] "
                             f"declared by {desc.path.name}.", file=p.file, element=where, variable=var_name)
    resolved[(comp, var_name)] = StartValue(comp, var, value, origin)


def _convert_value(p: ParameterValue, var: ModelVariable, comp: str, value: float, where: str,
                   units: SystemUnits) -> float:
    """A value given in another unit (``ssv:Real unit``), in the FMU variable's unit: FMUs are
    set in their own units (FMI 2.0 §2.2.7).  A value whose unit is not given, or a variable
    without a unit, is set as it is."""
    kw = {"file": p.file, "element": where, "variable": var.name}
    given = units.for_value(comp, p.units, file=p.file, element=where).resolve(p.unit, **kw)
    own = units.for_variable(comp).resolve(unit_of(var), **kw)
    a, b = conversion(given, own, f"the value is given in '{p.unit}' and {comp}.{var.name} is in "
                      f"'{unit_of(var)}': ", **kw)
    return a * value + b


def _coerce(p: ParameterValue, var: ModelVariable, where: str):
    kind = exchange_type(var)
    if kind is None or var.dimensions or isinstance(var, ArrayElement):
        what = "arrays and their elements" if kind is not None else f"{var.type} variables"
        raise SetupError(f"{what} cannot be given values by this master ({var.name} is "
                         f"{'an array' if kind else var.type}); it sets scalars of the FMI 2.0 types Real, "
                         "Integer, Boolean, String and the FMI 3.0 types Float64, Int32, Boolean, String.",
                         file=p.file, element=where, variable=var.name)
    if kind == p.type:
        return p.value
    if kind == "Real" and p.type == "Integer":
        return float(p.value)
    if kind == "Integer" and p.type == "Real" and float(p.value).is_integer():
        return int(p.value)
    raise SetupError(f"a {p.type} value ({p.value}) is given for a {var.type} variable.", file=p.file,
                     element=where, variable=var.name)


# --------------------------------------------------------------------------- ordering

def _variable_order(structure: SystemStructure, fmus: dict[str, FMUDescription], routes: list[Route],
                    outputs: dict[str, list[ModelVariable]]) -> list[tuple[str, str, str]]:
    """Topological order of connected variables and output connectors; a direct-feedthrough
    cycle is an error.

    Nodes are ('out'|'in', component, variable); edges go along connections and,
    inside a component, from a connected input to each output that depends on it.
    """
    edges: dict[tuple, list[tuple]] = defaultdict(list)
    nodes: list[tuple] = []
    connected_in: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        a, b = ("out", r.src, r.src_var.name), ("in", r.dst, r.dst_var.name)
        edges[a].append(b)
        nodes += [a, b]
        connected_in[r.dst].add(r.dst_var.name)
    for comp, variables in outputs.items():
        for var in variables:
            out = ("out", comp, var.name)
            nodes.append(out)
            for dep in fmus[comp].output_dependencies.get(var.name, []):
                if dep in connected_in[comp]:
                    edges[("in", comp, dep)].append(out)
    nodes = list(dict.fromkeys(nodes))
    cycles = [scc for scc in _tarjan(nodes, edges) if len(scc) > 1]
    if cycles:
        text = "; ".join(" -> ".join(f"{c}.{v} ({k}put)" for k, c, v in _cycle_path(scc, edges))
                         for scc in cycles)
        raise SetupError("algebraic loop: these variables depend on each other at the same instant "
                         f"through direct feedthrough: {text}. Break the loop with a component that has "
                         "no direct feedthrough (a delay or a filter), or check the FMUs' ModelStructure "
                         "dependencies.", file=str(structure.ssd_file), element="ssd:Connections")
    return _topological(nodes, edges)


def _tarjan(nodes: list, edges: dict) -> list[list]:
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    result: list[list] = []
    counter = [0]

    def visit(v):  # recursion depth is bounded by the number of connected variables
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                scc.append(w)
                if w == v:
                    break
            result.append(scc[::-1])

    for v in nodes:
        if v not in index:
            visit(v)
    return result


def _cycle_path(scc: list, edges: dict) -> list:
    """Order an SCC's nodes along its edges so the message reads as a loop."""
    members = set(scc)
    path = [scc[0]]
    seen = {scc[0]}
    while True:
        nxt = next((w for w in edges.get(path[-1], []) if w in members and w not in seen), None)
        if nxt is None:
            break
        path.append(nxt)
        seen.add(nxt)
    path += [n for n in scc if n not in seen]
    return path + [path[0]]


def _topological(nodes: list, edges: dict) -> list:
    indegree = {n: 0 for n in nodes}
    for v in nodes:
        for w in edges.get(v, []):
            indegree[w] += 1
    ready = [n for n in nodes if indegree[n] == 0]
    order = []
    while ready:
        v = ready.pop(0)
        order.append(v)
        for w in edges.get(v, []):
            indegree[w] -= 1
            if indegree[w] == 0:
                ready.append(w)
    return order


def _feedthrough_sequence(order: list, fmus: dict[str, FMUDescription], routes: list[Route]) -> list[str]:
    """Components whose connected outputs depend on connected inputs, in dependency order."""
    connected_in: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        connected_in[r.dst].add(r.dst_var.name)
    sequence: list[str] = []
    for kind, comp, var in order:
        if kind != "out":
            continue
        if set(fmus[comp].output_dependencies.get(var, [])) & connected_in[comp]:
            if not sequence or sequence[-1] != comp:
                sequence.append(comp)
    return sequence


def settling_shortcuts(sequence: list[str], routes: list[Route]) -> tuple[set[str], set[str]]:
    """FMI calls the exchange can leave out without changing a value.

    The exchange reads every output, then settles the feedthrough sequence (set a
    component's inputs, re-read its outputs), then sets every input.  A component F of the
    sequence need not be read first when every component that reads F inside the sequence
    comes after F's first place in it (F's own loop-back counts as reading it first); a
    component X need not be set at the end when every source of X in the sequence has its
    last place before X's last place (X was set with final values).  A chain of feedthrough
    blocks then costs one set and one get per block instead of two of each.
    """
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    for i, comp in enumerate(sequence):
        first.setdefault(comp, i)
        last[comp] = i
    consumers: dict[str, set[str]] = defaultdict(set)
    sources: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        consumers[r.src].add(r.dst)
        sources[r.dst].add(r.src)
    read_once = {f for f in first if all(first[x] > first[f] for x in consumers[f] if x in first)}
    set_once = {x for x in last if all(last[s] < last[x] for s in sources[x] if s in last)}
    return read_once, set_once


def _gauss_seidel_order(structure: SystemStructure, routes: list[Route]) -> list[str]:
    """Components upstream first (SCCs of the connection graph in topological order)."""
    names = list(structure.components)
    edges: dict[str, list[str]] = defaultdict(list)
    for r in routes:
        if r.dst not in edges[r.src]:
            edges[r.src].append(r.dst)
    sccs = _tarjan(names, edges)
    position = {n: i for i, n in enumerate(names)}
    scc_of = {n: i for i, scc in enumerate(sccs) for n in scc}
    dag: dict[int, list[int]] = defaultdict(list)
    for a, targets in edges.items():
        for b in targets:
            if scc_of[a] != scc_of[b] and scc_of[b] not in dag[scc_of[a]]:
                dag[scc_of[a]].append(scc_of[b])
    scc_order = _topological(sorted(range(len(sccs)), key=lambda i: min(position[n] for n in sccs[i])), dag)
    return [n for i in scc_order for n in sorted(sccs[i], key=position.get)]
