"""Parameter values: which value each settable variable starts from, checked against its FMU.

SSP 1.0 precedence (SystemStructureDescription.xsd, ParameterBindings): component-level
bindings, then system-level ones (inner systems first), then the parameter sets given on
the command line; later wins.  A value naming an undriven system connector
(`cosim.model.structure.OpenConnector`) is the constant input of everything it feeds, taken
there hop by hop like a connection (`cosim.plan.routing.hops_map`).  Values are coerced to the
variable's type, converted from the unit they are given in and checked against the
variable's range.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Collection, Sequence
from dataclasses import replace


from ..model.fmu import ArrayElement, FMUDescription, Variable, exchange_type, unit_of
from ..errors import CosimWarning, SetupError, did_you_mean
from .routing import hops_map, transformations, unit_step
from ..model.structure import Hop, OpenConnector, ParameterValue, Plan, StartValue, SystemStructure
from ..model.frozen import FrozenMap
from ..model.transforms import IDENTITY, Transform, Unmapped
from ..model.units import SystemUnits, UnitScope, conversion

SETTABLE_CAUSALITIES = ("parameter", "input")
#: the range of fmi2Integer and fmi3Int32 (a C int)
INT32 = (-2**31, 2**31 - 1)


def resolve_parameters(structure: SystemStructure, fmus: dict[str, FMUDescription],
                       extra: list[ParameterValue], units: SystemUnits) -> list[StartValue]:
    """Component bindings, then system bindings (inner systems first), then extra (command-line)
    sets: later wins.  Values naming an undriven system connector go to what it feeds
    (`bind_system_connectors`)."""
    resolved: dict[tuple[str, str], StartValue] = {}
    for name, comp in structure.components.items():
        for p in comp.parameters:
            _apply_parameter(resolved, name, p.name, p, fmus[name], units)
    system_values = bind_system_connectors(structure, fmus, units, list(structure.parameters) + extra)
    for p in system_values:
        comp_name, var_name = split_system_name(structure.components, p)
        _apply_parameter(resolved, comp_name, var_name, p, fmus[comp_name], units)
    return list(resolved.values())


def _through_hops(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits,
                  p: ParameterValue, open_connector: OpenConnector, comp: str, conn: str,
                  hops: tuple[Hop, ...]) -> ParameterValue:
    """The value a component connector gets from ``p``, given to an open system connector
    (`connector_transform`).  A value that is not a number goes only through an identity, an
    Integer or Boolean one through a Real variable's conversions or a mapping table."""
    where = (f"ssv:Parameter '{p.name}' (line {p.line}) for {comp}.{conn} through system connector "
             f"'{open_connector.path}'")
    var = fmus[comp].variable(conn, where, p.file)
    p, transform = connector_transform(structure, units, p, open_connector, (comp, var), hops, where)
    name = f"{comp}.{conn}"
    if exchange_type(var) == "Real" and p.type in ("Real", "Integer"):
        return replace(p, name=name, type="Real", value=transform.apply(float(p.value)), unit=None, transform=None)
    if transform.identity:
        return replace(p, name=name)
    if p.type not in ("Real", "Integer", "Boolean"):
        raise SetupError(f"a {p.type} value cannot go through the transformation {transform.text()} on the way "
                         f"from system connector '{p.name}' to {name}.", file=p.file, element=p.element(),
                         variable=p.name)
    try:
        value = transform.apply(p.value)
    except Unmapped as e:
        raise SetupError(f"the value {e.table.shown(e.value)} is not a source value of {e.table.element} on the way "
                         f"from system connector '{p.name}' to {name}.", file=p.file, element=p.element(),
                         variable=p.name) from None
    if p.type == "Boolean":
        return replace(p, name=name, value=bool(value))
    return replace(p, name=name, type="Real" if isinstance(value, float) else "Integer", value=value)


def connector_transform(structure: SystemStructure, units: SystemUnits, p: ParameterValue,
                        open_connector: OpenConnector, sink: tuple[str, Variable], hops: tuple[Hop, ...],
                        where: str) -> tuple[ParameterValue, Transform]:
    """How a value ``p`` given to an open system connector reaches the component input ``sink``
    through ``hops``: ``p`` with its mapping's pending LinearTransformation applied where it comes
    first, and the transformation from its value to the sink's.  The connector holds the value in
    its own unit if it declares one (converted from ``p``'s unit, as a parameter value is), else in
    ``p``'s unit; then each hop as on a connection (`cosim.plan.routing.hops_map`), ending in the FMU
    variable's unit.  A variable that is not Real, or a value that is not a number, takes the
    hops' transformations only (`cosim.plan.routing.transformations`); the connector carries the
    type of what it feeds."""
    comp, var = sink
    source = (f"system connector '{open_connector.path}'", var)
    if p.transform is not None and (exchange_type(var) != "Real" or not open_connector.unit):
        if exchange_type(var) == "Real":
            raise SetupError(f"the value is given in '{p.unit}' and mapped with a LinearTransformation, which SSP 1.0 "
                             "applies after converting it to its target's unit; system connector "
                             f"'{open_connector.path}' declares no unit.", file=p.file, element=p.element(),
                             variable=p.name, hint="Declare the connector's unit, or add "
                             "suppressUnitConversion=\"true\" to the mapping entry.")
        p = replace(p, value=p.transform.apply(float(p.value)), transform=None)
    if exchange_type(var) != "Real" or p.type not in ("Real", "Integer"):
        return p, transformations(hops, source, sink, p.file, where)
    kw = {"file": p.file, "element": where, "variable": open_connector.path}
    unit, scope = p.unit, units.for_value(comp, p.units, file=p.file, element=where)
    given = IDENTITY
    if open_connector.unit:
        own = UnitScope(units.ssd)
        given = unit_step((p.unit, scope), (open_connector.unit, own),
                           f"the value is given in '{p.unit}' and system connector '{open_connector.path}' is in "
                           f"'{open_connector.unit}': ", "Give the value in a unit of the connector's dimension.",
                           **kw)
        unit, scope = open_connector.unit, own
        if p.transform is not None:  # the mapping's LinearTransformation, in the connector's unit
            given = given.then(p.transform)
    return p, hops_map(structure, units, hops, (unit, scope, given, f"system connector '{p.name}'"), sink, where,
                       source)


def open_inputs(structure: SystemStructure, fmus: dict[str, FMUDescription],
                units: SystemUnits) -> FrozenMap[str, tuple[tuple[str, str, Transform], ...]]:
    """Each undriven system connector that feeds something: the inputs it feeds (component,
    variable) and the transformation a number given to it without a unit takes to each
    (`connector_transform`): an input table's column naming it (`cosim.plan.inputs`)."""
    out = {}
    for path, target in structure.open_connectors.items():
        if target.sinks:
            probe = ParameterValue(path, "Real", 0.0, structure.display, target.line)
            sinks = []
            for comp, conn, hops in target.sinks:
                where = f"system connector '{path}' for {comp}.{conn}"
                var = fmus[comp].variable(conn, where, structure.display)
                sinks.append((comp, conn, connector_transform(structure, units, probe, target, (comp, var), hops,
                                                              where)[1]))
            out[path] = tuple(sinks)
    return FrozenMap(out)


def bind_system_connectors(structure: SystemStructure, fmus: dict[str, FMUDescription], units: SystemUnits,
                           values: list[ParameterValue]) -> list[ParameterValue]:
    """Replace each value that names a system connector by values for what it feeds
    (`cosim.model.structure.OpenConnector`), taken along each path hop by hop (`_through_hops`).

    An open connector that gets no value is refused, naming it and what it feeds; a value for
    a connector that a connection drives is refused.  A value for a root output connector that
    no component drives is its recorded constant (`cosim.plan.build`), not a value for an FMU.
    """
    open_connectors, driven, file = structure.open_connectors, structure.driven_connectors, structure.display
    undriven = {name for name, o in structure.system_outputs.items() if o.component is None}
    out: list[ParameterValue] = []
    bound: set[str] = set()
    for p in values:
        if p.name in undriven:
            continue
        if p.name in driven:
            raise SetupError(f"'{p.name}' is a system connector driven by a connection; it cannot also be "
                             "given a value.", file=p.file, element=p.element(),
                             variable=p.name)
        target = open_connectors.get(p.name)
        if target is None:
            out.append(p)
            continue
        bound.add(p.name)
        out += [_through_hops(structure, fmus, units, p, target, comp, conn, hops)
                for comp, conn, hops in target.sinks]
    for path, target in open_connectors.items():
        if path not in bound and target.sinks:
            fed = ", ".join(f"{comp}.{conn}" for comp, conn, _ in target.sinks)
            raise SetupError(f"system connector '{path}' (kind {target.kind}) has no driver and no value; it "
                             f"feeds {fed}.", file=file, element=f"ssd:Connector (line {target.line})",
                             variable=path, hint="Connect an output to it, or give it a value with a "
                             "ParameterBinding (a constant input).")
    return out


def check_values(plan: Plan, values: Sequence[ParameterValue]) -> None:
    """Check values named ``component.variable`` against a plan's FMUs as `resolve_parameters`
    checks a parameter set applied last (names, causality, types, units, ranges), without
    building the plan again (`cosim.sweep` checks every swept value before the first run)."""
    for p in values:
        comp, var_name = split_system_name(plan.components, p)
        _apply_parameter({}, comp, var_name, p, plan.fmus[comp], plan.unit_scopes)


def split_system_name(components: Collection[str], p: ParameterValue) -> tuple[str, str]:
    """The component and the variable a system-level name ``comp.var`` names (the longest
    component path first: components of nested systems have dotted names)."""
    for comp in sorted(components, key=len, reverse=True):
        if p.name.startswith(comp + "."):
            return comp, p.name[len(comp) + 1:]
    raise SetupError(f"system-level parameter '{p.name}' does not start with a component name "
                     "('component.variable').", file=p.file, element=p.element(),
                     variable=p.name, hint=did_you_mean(p.name.rpartition(".")[0], components))


def _apply_parameter(resolved: dict, comp: str, var_name: str, p: ParameterValue, desc: FMUDescription,
                     units: SystemUnits) -> None:
    where = f"ssv:Parameter '{p.name}' (line {p.line}) for component '{comp}'" + (
        f", mapped by {p.mapping}" if p.mapping else "")
    var = desc.variable(var_name, where, p.file)
    p = _pending_linear(p, var)
    if var.causality not in SETTABLE_CAUSALITIES or var.variability == "constant":
        raise SetupError(f"'{var_name}' has causality '{var.causality}' and variability '{var.variability}'; "
                         "only parameters and inputs (non-constant) can be given values.",
                         file=p.file, element=where, variable=var_name)
    value = _coerce(p, var, where)
    origin = f"{p.file}:{p.line}" + (f", mapped by {p.mapping}" if p.mapping else "")
    if exchange_type(var) == "Real" and p.unit is not None and unit_of(var) not in (None, p.unit):
        value = _convert_value(p, var, comp, value, where, units)
        origin += f", given as {p.value:g} {p.unit}"
    if p.transform is not None:  # a mapping's LinearTransformation, after the unit conversion (SSP 1.0 MappingEntry)
        value = p.transform.apply(value)
        origin += f", then {p.transform.text()}"
    if exchange_type(var) in ("Real", "Integer"):
        _check_number(value, var, desc, p, where)
        lo = float(var.min) if var.min is not None else None
        hi = float(var.max) if var.max is not None else None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            bound = f"below the variable's minimum {var.min}" if lo is not None and value < lo else \
                f"above the variable's maximum {var.max}"
            raise SetupError(f"value {value} is {bound} declared by {desc.path.name}.", file=p.file, element=where,
                             variable=var_name)
    resolved[(comp, var_name)] = StartValue(comp, var, value, origin)


def _pending_linear(p: ParameterValue, var: Variable) -> ParameterValue:
    """``p`` with its mapping's LinearTransformation applied now where no unit conversion comes
    first (the variable is not Real, or has no unit or the value's own): the transformation then
    acts on the value as given, and the value is coerced to the variable's type afterwards."""
    if p.transform is None or (exchange_type(var) == "Real" and unit_of(var) not in (None, p.unit)):
        return p
    return replace(p, value=p.transform.apply(float(p.value)), transform=None)


def _check_number(value: float | int, var: Variable, desc: FMUDescription, p: ParameterValue,
                  where: str) -> None:
    """A Real must be finite (NaN would pass any min/max test, FMI 2.0 §2.2.7 has no NaN start
    value) and an Integer must fit the C int of fmi2Integer / fmi3Int32."""
    if exchange_type(var) == "Real" and not math.isfinite(value):
        raise SetupError(f"value {value} is not a finite number{'' if value == p.value else f' (given {p.value})'}; "
                         f"{desc.path.name} takes a finite Real.", file=p.file, element=where, variable=var.name)
    if exchange_type(var) == "Integer" and not INT32[0] <= value <= INT32[1]:
        raise SetupError(f"value {value} is outside the range of {var.type} ([{INT32[0]}, {INT32[1]}], a 32-bit "
                         f"C int) in {desc.path.name}.", file=p.file, element=where, variable=var.name)


def _convert_value(p: ParameterValue, var: Variable, comp: str, value: float, where: str,
                   units: SystemUnits) -> float:
    """A value given in another unit (``ssv:Real unit``), in the FMU variable's unit: FMUs are
    set in their own units (FMI 2.0 §2.2.7).  A value whose unit is not given, or a variable
    without a unit, is set as it is."""
    kw = {"file": p.file, "element": where, "variable": var.name}
    scope = units.for_value(comp, p.units, file=p.file, element=where)
    if scope.find(p.unit) is None:
        return _undefined_unit(p, var, comp, value, where)
    given = scope.resolve(p.unit, **kw)
    own = units.for_variable(comp).resolve(unit_of(var), **kw)
    return conversion(given, own, f"the value is given in '{p.unit}' and {comp}.{var.name} is in "
                      f"'{unit_of(var)}': ", **kw).apply(value)


class UndefinedValueUnit(CosimWarning):
    """A parameter value is given in a unit nothing defines (`_undefined_unit`)."""


def _undefined_unit(p: ParameterValue, var: Variable, comp: str, value: float, where: str) -> float:
    """A value whose ``ssv:Real unit`` no ``ssv:Units``, SSD, FMU or built-in table defines (the
    EMBRACE system's parameter set writes ``[m]`` and defines ``m``): set as given, in the
    variable's unit, as OMSimulator sets it, with a warning naming the value (``--strict`` refuses)."""
    warnings.warn(UndefinedValueUnit(
        f"{p.file}, {where}, variable '{var.name}': the value {value:g} is given in unit '{p.unit}', which no "
        f"ssv:Units, ssd:Units, FMU UnitDefinitions or built-in unit defines; set as given, in {comp}.{var.name}'s "
        f"unit '{unit_of(var)}', as OMSimulator sets it (--strict refuses it)"), stacklevel=2)
    return value


def _coerce(p: ParameterValue, var: Variable, where: str):
    kind = exchange_type(var)
    if kind is None or var.dimensions or isinstance(var, ArrayElement):
        what = "arrays and their elements" if kind is not None else f"{var.type} variables"
        raise SetupError(f"{what} cannot be given values by this master ({var.name} is "
                         f"{'an array' if kind else var.type}); it sets scalars of the FMI 2.0 types Real, "
                         "Integer, Boolean, String, Enumeration and the FMI 3.0 types Float64, Float32, "
                         "Int8..UInt64, Enumeration, Boolean, String.",
                         file=p.file, element=where, variable=var.name)
    if p.type == "Enumeration":
        return _enumeration_item(p, var, where)
    if kind == p.type:
        return p.value
    if kind == "Real" and p.type == "Integer":
        return float(p.value)
    if kind == "Integer" and p.type == "Real" and float(p.value).is_integer():
        return int(p.value)
    raise SetupError(f"a {p.type} value ({p.value}) is given for a {var.type} variable.", file=p.file,
                     element=where, variable=var.name)


def _enumeration_item(p: ParameterValue, var: Variable, where: str) -> int:
    """The value of the item an ``ssv:Enumeration`` names, in the variable's declared type."""
    items = dict(var.declared_type.items if var.declared_type else ())
    if var.type != "Enumeration" or not items:
        raise SetupError(f"an Enumeration value ('{p.value}') is given for a {var.type} variable.", file=p.file,
                         element=where, variable=var.name)
    if p.value not in items:
        raise SetupError(f"'{p.value}' is not an item of {var.declared_type.name} (items: {', '.join(items)}).",
                         file=p.file, element=where, variable=var.name, hint=did_you_mean(p.value, items))
    return items[p.value]
