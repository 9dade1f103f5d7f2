"""SSP 1.0 parameter mappings (SystemStructureParameterMapping, ``.ssm``): rename and transform
the values of a parameter set before they are applied.

A ParameterBinding with a ``ssd:ParameterMapping`` applies only the mapped values, under the
names they are mapped to; values that no ``ssm:MappingEntry`` names are not applied (SSP 1.0
§5.2.3 ParameterBindings).  A binding's ``prefix`` is prepended to the names in the parameter
source before the mapping is processed, so an entry's ``source`` names the prefixed name.  One
source may be mapped to several targets; two entries must not map to the same target.  An entry
with an empty ``source`` (the templates OMSimulator writes: a target awaiting its source) maps
nothing.

Transformations (SSP 1.0 §4.5.2, Transformation Choice): ``ssc:LinearTransformation``
``target = factor * source + offset`` on Real values, after the unit conversion (or instead of it
with ``suppressUnitConversion="true"``): a value given in a unit keeps the transformation in
`cosim.model.structure.ParameterValue.transform` until `cosim.plan.parameters` has converted it to the
variable's unit.  The Boolean, Integer and Enumeration mapping transformations are tables of
``ssc:MapEntry`` source → target values (Enumeration values by item name, mapped before the name
is resolved to the target variable's item value); a value that no MapEntry names is refused,
naming the file, the entry and the value (the schema gives a table no default: passing the value
through unchanged would apply a value the mapping does not define).  A transformation on a value
of another type is refused, naming the entry.
"""
from __future__ import annotations

from dataclasses import replace

from ..errors import SetupError, did_you_mean
from ..model.transforms import Unmapped
from ..model.structure import MappingEntry, ParameterValue

#: the ssv value type each transformation applies to
APPLIES_TO = {"Linear": "Real", "Boolean": "Boolean", "Integer": "Integer", "Enumeration": "Enumeration"}


def apply_mapping(values: list[ParameterValue], entries: list[MappingEntry]) -> list[ParameterValue]:
    """The values the entries map, renamed and transformed, in the order of the entries.

    An entry naming a value the parameter set does not hold is refused: it would silently
    apply nothing."""
    by_name = {p.name: p for p in values}  # later wins, as between the values of one set
    out = []
    for entry in entries:
        p = by_name.get(entry.source)
        if p is None:
            raise SetupError(f"the mapping entry's source '{entry.source}' is not a parameter of the parameter "
                             "set it maps.", file=entry.file, element=f"ssm:MappingEntry (line {entry.line})",
                             variable=entry.source, hint=did_you_mean(entry.source, by_name))
        out.append(_mapped(p, entry))
    return out


def transformation_element(kind: str) -> str:
    """The element of a transformation kind: ``ssc:LinearTransformation``, ``ssc:BooleanMappingTransformation``..."""
    return "ssc:LinearTransformation" if kind == "Linear" else f"ssc:{kind}MappingTransformation"


def _mapped(p: ParameterValue, entry: MappingEntry) -> ParameterValue:
    mapped = replace(p, name=entry.target, mapping=entry.where(),
                     unit=None if entry.suppress_unit_conversion else p.unit)
    if entry.kind is None:
        return mapped
    if p.type != APPLIES_TO[entry.kind]:
        raise SetupError(f"{transformation_element(entry.kind)} applies to ssv:{APPLIES_TO[entry.kind]} values; "
                         f"'{entry.source}' is an ssv:{p.type} ({p.file}, line {p.line}).",
                         file=entry.file, element=f"ssm:MappingEntry (line {entry.line})", variable=entry.source)
    if entry.kind != "Linear":
        try:
            return replace(mapped, value=entry.transform.apply(p.value))
        except Unmapped as e:
            sources = ", ".join(e.table.shown(v) for v in e.table.mapping)
            raise SetupError(f"the value {e.table.shown(p.value)} of '{entry.source}' ({p.file}, line {p.line}) is "
                             f"not a source of the {transformation_element(entry.kind)} (its ssc:MapEntry "
                             f"sources: {sources}).", file=entry.file,
                             element=f"ssm:MappingEntry '{entry.source}' -> '{entry.target}' (line {entry.line})",
                             variable=entry.source) from None
    if mapped.unit is None:
        return replace(mapped, value=entry.transform.apply(float(p.value)))
    return replace(mapped, transform=entry.transform)
