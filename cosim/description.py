"""FMUs as the master sees them before any is instantiated: their model description, checked.

`describe` reads and checks a model description and decides which interface
the master drives (`FMUDescription.kind`): an FMI 2.0 Co-Simulation FMU
(``fmi2-cs``), an FMI 3.0 Co-Simulation FMU (``fmi3-cs``) or an FMI 2.0 Model
Exchange FMU integrated by the master (``fmi2-me``); `cosim.instances` holds the
live instances of each kind.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import fmpy
from attrs import define, field as attrs_field
from fmpy.model_description import ModelDescription, ModelVariable

from .errors import SetupError, did_you_mean

#: The interface the master drives an FMU through (`describe`).
Kind = Literal["fmi2-cs", "fmi3-cs", "fmi2-me", "fmi3-me"]
#: The kinds the master integrates (Model Exchange, `cosim.instances.me`).
MODEL_EXCHANGE: tuple[Kind, ...] = ("fmi2-me", "fmi3-me")
#: How the master exchanges a variable (`exchange_type`): the FMI 2.0 type names.
ExchangeType = Literal["Real", "Integer", "Boolean", "String", "Binary"]

#: SSP 1.0 Component ``implementation`` values (SystemStructureDescription.xsd).
IMPLEMENTATIONS = ("any", "CoSimulation", "ModelExchange")


@dataclass
class FMUDescription:
    """A checked model description and the interface the master drives it through."""
    path: Path
    md: ModelDescription
    variables: dict[str, ModelVariable]
    #: For each output: the inputs it depends on at the same instant (FMI 2.0 ModelStructure).
    #: An output without a ``dependencies`` attribute depends on every input (FMI 2.0 §2.2.8).
    output_dependencies: dict[str, list[str]]
    kind: Kind = "fmi2-cs"

    @property
    def model_identifier(self) -> str:
        interface = self.md.modelExchange if self.kind in MODEL_EXCHANGE else self.md.coSimulation
        return interface.modelIdentifier

    #: Array elements named by connectors (``vector[2]``), by the value reference the master
    #: gives them (not the FMU's; cosim.instances.fmi3 maps it back to the array and the index).
    elements: dict[int, ArrayElement] = field(default_factory=dict)

    def variable(self, name: str, where: str, file: str) -> ModelVariable:
        """The variable called ``name``, or the element ``name`` names of an FMI 3.0 array."""
        var = self.variables.get(name)
        if var is not None:
            return var
        match = _ELEMENT.fullmatch(name)
        if match is not None and match.group(1) in self.variables and self.variables[match.group(1)].dimensions:
            return self._element(self.variables[match.group(1)], match.group(2), name, where, file)
        raise SetupError(f"the FMU {self.path.name} has no variable '{name}'.", file=file,
                         element=where, variable=name, hint=did_you_mean(name, self.variables))

    def _element(self, array: ModelVariable, index_text: str, name: str, where: str, file: str) -> ArrayElement:
        """One element of a one-dimensional FMI 3.0 array, 1-based as in Modelica and in the
        FMI 2.0 structured names of scalarised arrays (``x[1]`` is the first element)."""
        known = next((e for e in self.elements.values() if e.name == name), None)
        if known is not None:
            return known
        if len(array.dimensions) != 1 or array.type in ("String", "Binary"):
            raise SetupError(f"'{array.name}' is a {len(array.dimensions)}-dimensional {array.type} array; only "
                             "elements of one-dimensional numeric and Boolean arrays can be connected.",
                             file=file, element=where, variable=name)
        size = _dimension_size(array.dimensions[0])
        if not index_text.strip().isdigit() or not 1 <= int(index_text) <= size:
            raise SetupError(f"'{index_text}' is not an element of {array.name}, an array of {size} values in "
                             f"{self.path.name}; elements are numbered {array.name}[1] .. {array.name}[{size}].",
                             file=file, element=where, variable=name)
        used = {v.valueReference for v in self.md.modelVariables} | set(self.elements)
        vr = 0xFFFFFFFF
        while vr in used:
            vr -= 1
        element = ArrayElement(name=name, valueReference=vr, type=array.type, description=array.description,
                               causality=array.causality, variability=array.variability, initial=array.initial,
                               declaredType=array.declaredType, unit=array.unit, min=array.min, max=array.max,
                               array=array, index=int(index_text) - 1, size=size)
        self.elements[vr] = element
        for deps in self.output_dependencies.values():  # an input element is known as its array
            if array.name in deps:
                deps.append(name)
        if array.name in self.output_dependencies:  # an output element depends on what its array does
            self.output_dependencies[name] = list(self.output_dependencies[array.name])
        return element


@define(eq=False)
class ArrayElement(ModelVariable):
    """One element of an FMI 3.0 array variable, exchanged as a scalar of its own."""
    array: ModelVariable = attrs_field(default=None, repr=False)
    #: 0-based position in the array's values (FMI 3.0 serialises arrays row-major, §2.4.7.5)
    index: int = 0
    size: int = 1


_ELEMENT = re.compile(r"(.+)\[([^\]]*)\]")


def _dimension_size(dimension) -> int:
    """A Dimension's extent: its ``start``, or the start of the structural parameter it names."""
    if dimension.start is not None:
        return int(dimension.start)
    return int(dimension.variable.start)


#: The exchange types of the master (the FMI 2.0 type names) for the FMI types it connects.
_EXCHANGE_TYPES: dict[str, ExchangeType] = {
    "Real": "Real", "Integer": "Integer", "Boolean": "Boolean", "String": "String", "Enumeration": "Integer",
    "Float64": "Real", "Float32": "Real", "Int8": "Integer", "UInt8": "Integer", "Int16": "Integer",
    "UInt16": "Integer", "Int32": "Integer", "UInt32": "Integer", "Int64": "Integer", "UInt64": "Integer",
    "Binary": "Binary"}


def exchange_type(variable: ModelVariable) -> ExchangeType | None:
    """How the master exchanges ``variable``: "Real" (C double), "Integer" (C int), "Boolean"
    or "String", for FMI 2.0 variables of those types and Enumeration (an Integer, FMI 2.0
    §2.2.3), FMI 3.0 Float64 and Float32 (Real), Int8..UInt64 and Enumeration (Integer; a value
    beyond 32 bits is refused when read, `cosim.instances.fmi3`), Boolean, String and Binary
    (exchanged, not recorded); None for the type it does not connect (FMI 3.0 Clock)."""
    return _EXCHANGE_TYPES.get(variable.type)


_cache: dict[tuple[Path, str], FMUDescription] = {}


def describe(path: Path, where: str, file: str, implementation: str = "any", validate: bool = True) -> FMUDescription:
    """Read and check an FMU's model description; ``where``/``file`` say who refers to it and
    ``implementation`` is the SSD Component's choice of interface (SSP 1.0: any,
    CoSimulation, ModelExchange; "any" prefers Co-Simulation when the FMU has both).
    ``validate``: against the FMI schema (False: this content passed before, `cosim.plan`)."""
    path = path.resolve()
    key = (path, implementation)
    if key in _cache and _cache[key].path.stat().st_mtime == path.stat().st_mtime:
        return _cache[key]
    try:
        md = fmpy.read_model_description(str(path), validate=validate)
    except Exception as e:  # fmpy raises several types for unreadable or invalid FMUs
        raise SetupError(f"cannot read the model description of {path.name}: {e}", file=file,
                         element=where) from None
    kind = _kind(md, path, implementation, where, file)
    if not md.guid or not md.guid.strip():
        raise SetupError(f"{path.name} has an empty GUID in its modelDescription.xml; an FMU without a GUID "
                         "cannot be instantiated.", file=file, element=where)
    variables = {v.name: v for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    deps: dict[str, list[str]] = {}
    for unknown in md.outputs:
        if unknown.dependencies is None:
            deps[unknown.variable.name] = list(inputs)
        else:
            deps[unknown.variable.name] = [d.name for d in unknown.dependencies if d.causality == "input"]
    for v in md.modelVariables:
        if v.causality == "output" and v.name not in deps:
            deps[v.name] = list(inputs)
    desc = FMUDescription(path=path, md=md, variables=variables, output_dependencies=deps, kind=kind)
    _cache[key] = desc
    return desc


def _kind(md: ModelDescription, path: Path, implementation: str, where: str, file: str) -> Kind:
    """The interface the master drives: the SSD's ``implementation`` if the FMU has it, else
    Co-Simulation when present, else Model Exchange."""
    if implementation not in IMPLEMENTATIONS:
        raise SetupError(f"implementation='{implementation}' is not one of {', '.join(IMPLEMENTATIONS)} "
                         "(SSP 1.0 Component).", file=file, element=where)
    if md.fmiVersion not in ("2.0", "3.0"):
        raise SetupError(f"{path.name} is an FMI {md.fmiVersion} FMU; this master runs FMI 2.0 and 3.0 FMUs.",
                         file=file, element=where)
    has_cs, has_me = md.coSimulation is not None, md.modelExchange is not None
    if not has_cs and not has_me:  # FMI 3.0 allows an FMU with only Scheduled Execution
        interfaces = "only a Scheduled Execution interface" if md.scheduledExecution is not None \
            else "neither a Co-Simulation nor a Model Exchange interface"
        raise SetupError(f"{path.name} has {interfaces}; this master runs Co-Simulation and Model Exchange "
                         "FMUs (FMI 2.0 and 3.0).", file=file, element=where)
    if implementation == "CoSimulation" and not has_cs:
        raise SetupError(f"implementation='CoSimulation' but {path.name} has no Co-Simulation interface.",
                         file=file, element=where)
    if implementation == "ModelExchange" and not has_me:
        raise SetupError(f"implementation='ModelExchange' but {path.name} has no Model Exchange interface.",
                         file=file, element=where)
    use_me = implementation == "ModelExchange" or (implementation == "any" and not has_cs)
    if md.fmiVersion == "3.0":
        return "fmi3-me" if use_me else "fmi3-cs"
    return "fmi2-me" if use_me else "fmi2-cs"



def unit_of(v: ModelVariable) -> str | None:
    if v.unit:
        return v.unit
    return v.declaredType.unit if v.declaredType is not None and v.declaredType.unit else None
