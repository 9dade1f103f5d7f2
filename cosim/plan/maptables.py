"""SSP 1.0 mapping transformations on connections: ``ssc:BooleanMappingTransformation``,
``ssc:IntegerMappingTransformation`` and ``ssc:EnumerationMappingTransformation``
(SystemStructureCommon.xsd, GTransformationChoice), tables of ``ssc:MapEntry`` source → target
values applied to a value on its way from an output to an input.

The schema makes each valid for its type: the Boolean table for Boolean connections, the Integer
table for Integer and Enumeration ones (on the item values), the Enumeration table for
Enumeration ones, by item name: a source name is looked up among the items of the source
variable's type, a target name among those of the destination variable's, both from the FMUs'
model descriptions.  Along a path through system connectors (`cosim.model.structure.Hop`) the tables
are composed, in the order of the path, into one `cosim.model.structure.RouteTable` of the exchanged
values.  A value that a table does not name has no defined target; it is refused when it
occurs (`cosim.run.execution`), naming the transformation and the value.  Mapping transformations
on a path that ends at a root-system output connector or starts at an open system connector
given a value are refused (`refuse_on_path`).
"""
from __future__ import annotations

from ..model.fmu import Variable, exchange_type
from ..errors import SetupError
from ..model.structure import Hop, RouteTable, ValueTable

#: the exchange type (`cosim.model.fmu.exchange_type`) each table applies to
APPLIES_TO = {"Boolean": "Boolean", "Integer": "Integer", "Enumeration": "Integer"}


def route_table(hops: tuple[Hop, ...], src: str, sv: Variable, dst: str, dv: Variable, file: str,
                where: str) -> RouteTable | None:
    """The mapping transformations of ``hops`` from ``src.sv`` to ``dst.dv`` composed, or None
    when no hop has one."""
    tables = [hop.table for hop in hops if hop.table is not None]
    if not tables:
        return None
    composed: dict[int, int] | None = None
    for table in tables:
        step = _values(table, src, sv, dst, dv, file, where)
        composed = step if composed is None else {k: step[v] for k, v in composed.items() if v in step}
    return RouteTable(composed, exchange_type(sv) == "Boolean", ", ".join(t.element() for t in tables))


def refuse_on_path(hops: tuple[Hop, ...], what: str, file: str, element: str) -> None:
    """Refuse a mapping transformation on a path that is not an output-to-input route (``what``
    says which), naming the transformation."""
    for hop in hops:
        if hop.table is not None:
            raise SetupError(f"{hop.table.element()} on the connection at line {hop.line}: mapping transformations "
                             f"are applied on connections from a component output to a component input, not on {what}.",
                             file=file, element=element)


def _values(table: ValueTable, src: str, sv: Variable, dst: str, dv: Variable, file: str,
            where: str) -> dict[int, int]:
    """One table as exchanged values: Booleans as 0/1, item names as their values."""
    element = f"{where}, {table.element()}"
    kind = exchange_type(sv)
    if kind != APPLIES_TO[table.kind]:
        valid = {"Boolean": "Boolean", "Integer": "Integer and Enumeration",
                 "Enumeration": "Enumeration"}[table.kind]
        raise SetupError(f"ssc:{table.kind}MappingTransformation applies to {valid} connections; "
                         f"{src}.{sv.name} -> {dst}.{dv.name} is {sv.type}.", file=file, element=element)
    if table.kind == "Boolean":
        return {int(s): int(t) for s, t in table.entries}
    if table.kind == "Integer":
        return dict(table.entries)
    source_items, target_items = _items(src, sv, file, element), _items(dst, dv, file, element)
    out = {}
    for s, t in table.entries:
        for name, items, comp, var in ((s, source_items, src, sv), (t, target_items, dst, dv)):
            if name not in items:
                raise SetupError(f"ssc:MapEntry '{s}' -> '{t}': '{name}' is not an item of {comp}.{var.name}'s type "
                                 f"{var.declared_type.name} (items: {', '.join(items)}).", file=file, element=element)
        out[source_items[s]] = target_items[t]
    return out


def _items(comp: str, var: Variable, file: str, element: str) -> dict[str, int]:
    items = dict(var.declared_type.items if var.declared_type else ())
    if var.type != "Enumeration" or not items:
        raise SetupError(f"ssc:EnumerationMappingTransformation maps item names; {comp}.{var.name} is {var.type} "
                         "without enumeration items.", file=file, element=element)
    return items
