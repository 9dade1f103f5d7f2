"""Routing: the transformation each connection applies, from the source FMU's value to the
destination FMU's value (SSP 1.0 unit conversion and the connections' transformations, hop by hop).

`connector_unit` is a connector's view of its FMU variable's unit; `hops_map` composes the unit
conversions and transformations along a path through system connectors
(`cosim.model.structure.Hop`) into one `cosim.model.transforms.Affine` for a Real value;
`path_transform` is the transformation of a path for a value of any type.  Unit definitions and
their scopes are `cosim.model.units`.
"""
from __future__ import annotations


from ..model.fmu import Variable, exchange_type, unit_of
from ..model.structure import Hop, SystemStructure
from ..model.transforms import IDENTITY, Affine, End, Transform, compose
from ..model.units import SystemUnits, UnitScope, check_agree, conversion


def connector_unit(units: SystemUnits, comp: str, var: Variable, declared: str | None, where: str,
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


def unit_step(start: tuple[str | None, UnitScope], end: tuple[str | None, UnitScope], context: str,
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


def source_view(structure: SystemStructure, units: SystemUnits, source: tuple[str, Variable],
                 where: str) -> tuple[str | None, UnitScope, Affine, str]:
    """A component output as the start of a path: its connector's unit, where that is looked up,
    the map from the FMU's value to the connector's, and its name."""
    src, sv = source
    name, scope, to_view, _ = connector_unit(units, src, sv, structure.components[src].connectors[sv.name].unit,
                                              where, structure.display)
    return name, scope, to_view, f"{src}.{sv.name}"


def hops_map(structure: SystemStructure, units: SystemUnits, hops: tuple[Hop, ...],
              start: tuple[str | None, UnitScope, Affine, str], target: tuple[str, Variable] | None,
              where: str, origin: End) -> Affine:
    """The affine map along a path through system connectors (`cosim.read.flatten`): from the value
    at its start (``start``: the unit, where it is looked up, the map from the value given to
    the start's unit, a name for messages; see `source_view`) to the target FMU's value, or,
    with no ``target``, to the value of the root-system output connector that ends the path.

    SSP 1.0 (SystemStructureDescription.xsd, Connection and ``suppressUnitConversion``;
    SystemStructureCommon.xsd LinearTransformation) applies to each connection on the way:
    convert from its start connector's unit to its end connector's unit, then its
    LinearTransformation (target = factor·source + offset; ``origin``: the variable whose values
    take the path, which each hop's transformation is checked against,
    `cosim.model.transforms.Transformation.resolve`); with
    ``suppressUnitConversion="true"`` on a connection, only its transformation.  A connection
    between two components is a path of one hop.  The composition is one factor and one
    offset, so the exchange costs the same as a plain LinearTransformation.  No conversion
    when a connector has no unit (FMI 2.0 §2.2.7: a variable without a unit is not checked)
    or both ends name the same unit.  The component ends take their connector
    views (`connector_unit`).  A system connector that declares a unit holds its value in
    that unit (names looked up in the SSD's ``ssd:Units``, then the built-ins).  One without
    a unit is transparent: it carries the unit of what drives it, so nothing is converted at
    it — SSP 1.0 gives such a connector no unit of its own, and a graphical tool's pass-through
    port must not change a value; converting end to end would also skip the hops'
    transformations in between.  A hop between units of different dimensions is refused.
    """
    file = structure.display
    name, scope, result, source = start
    ssd_scope = UnitScope(units.ssd)
    from_view = IDENTITY
    for hop in hops:
        if hop.end_system is None:  # the component input (or parameter, for a constant) that ends the path
            dst, dv = target
            declared = structure.components[dst].connectors.get(dv.name)
            end_name, end_scope, _, from_view = connector_unit(
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
            result = result.then(unit_step(
                (name, scope), (end_name, end_scope), context, file=file, element=element,
                variable=hop.end_system or hop.start_system or target[1].name))
        result = result.then(_resolved(hop, origin, target, file, where))
        name, scope = end_name, end_scope
    return result.then(from_view)


def _resolved(hop: Hop, source: End, target: tuple[str, Variable] | None, file: str, where: str) -> Transform:
    """A hop's transformation as it acts on the exchanged values (none: the identity)."""
    if hop.transform is None:
        return IDENTITY
    end = None if target is None else (f"{target[0]}.{target[1].name}", target[1])
    return hop.transform.resolve(source, end, file, where)


def transformations(hops: tuple[Hop, ...], source: End, target: tuple[str, Variable] | None, file: str,
                    where: str) -> Transform:
    """The transformations along a path composed, without any unit conversion: what a value that
    has no unit (not Real) goes through."""
    return compose(_resolved(hop, source, target, file, where) for hop in hops)


def path_transform(structure: SystemStructure, units: SystemUnits, hops: tuple[Hop, ...], source: tuple[str, Variable],
                   target: tuple[str, Variable] | None, where: str) -> Transform:
    """The transformation of a path from the output ``source`` (component, variable) to the
    input ``target`` (None: the root-system output connector that ends the path): for a Real
    value the unit conversions and transformations composed (`hops_map`), for the others their
    transformations (mapping tables)."""
    src, sv = source
    end = (f"{src}.{sv.name}", sv)
    if exchange_type(sv) == "Real":
        return hops_map(structure, units, hops, source_view(structure, units, source, where), target, where, end)
    return transformations(hops, end, target, structure.display, where)
