"""FMUs as the master sees them before any is instantiated: their model description, checked,
as values of our own.

`describe` reads and checks a model description with fmpy and keeps what the master uses of
it as frozen records (`Variable`, `DeclaredType`, `cosim.model.units.UnitDefinition`, `DefaultExperiment`,
`FMUDescription`): nothing of fmpy's parsed objects reaches a `cosim.model.structure.Plan`, so a
plan is plain data (a sweep pickles it for its workers, `cosim.sweep.dispatch`).  It decides
which interface the master drives (`FMUDescription.kind`): an FMI 2.0 Co-Simulation FMU
(``fmi2-cs``), an FMI 3.0 Co-Simulation FMU (``fmi3-cs``) or an FMI 2.0 or 3.0 Model Exchange
FMU integrated by the master (``fmi2-me``, ``fmi3-me``); `cosim.run.instances` holds the live
instances of each kind (they load the FMU with fmpy).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import fmpy
from fmpy.model_description import ModelDescription, ModelVariable

from ..errors import SetupError, did_you_mean
from ..model.units import BASE_UNITS, UnitDefinition

#: The interface the master drives an FMU through (`describe`).
Kind = Literal["fmi2-cs", "fmi3-cs", "fmi2-me", "fmi3-me"]
#: The kinds the master integrates (Model Exchange, `cosim.run.instances.me`).
MODEL_EXCHANGE: tuple[Kind, ...] = ("fmi2-me", "fmi3-me")
#: How the master exchanges a variable (`exchange_type`): the FMI 2.0 type names.
ExchangeType = Literal["Real", "Integer", "Boolean", "String", "Binary"]

#: SSP 1.0 Component ``implementation`` values (SystemStructureDescription.xsd).
IMPLEMENTATIONS = ("any", "CoSimulation", "ModelExchange")


@dataclass(frozen=True)
class DeclaredType:
    """A variable's ``declaredType`` (FMI 2.0 §2.2.3 SimpleType, FMI 3.0 §2.4.4 TypeDefinitions):
    its name, unit and, for an Enumeration, its items (name, value)."""
    name: str
    unit: str | None = None
    items: tuple[tuple[str, int], ...] = ()


@dataclass(frozen=True)
class Variable:
    """One ScalarVariable (FMI 2.0 §2.2.7) or FMI 3.0 variable (§2.4.7), the attributes the master
    reads, as the model description gives them (``start``, ``min`` and ``max`` as their text)."""
    name: str
    #: the valueReference
    vr: int
    #: the FMI type name: Real, Integer, Boolean, String, Enumeration; Float64, Int32, Binary, ...
    type: str
    causality: str
    variability: str
    initial: str | None = None
    #: its own ``unit`` attribute (`unit_of`: else its declared type's)
    unit: str | None = None
    start: str | None = None
    min: str | None = None
    max: str | None = None
    description: str | None = None
    declared_type: DeclaredType | None = None
    #: an FMI 3.0 array's extents, each the ``start`` of its Dimension or of the structural
    #: parameter it names (§2.4.7.5); () for a scalar
    dimensions: tuple[str | None, ...] = ()


@dataclass(frozen=True, kw_only=True)
class ArrayElement(Variable):
    """One element of an FMI 3.0 array variable, exchanged as a scalar of its own."""
    array: Variable = field(repr=False)
    #: 0-based position in the array's values (FMI 3.0 serialises arrays row-major, §2.4.7.5)
    index: int = 0
    size: int = 1


@dataclass(frozen=True)
class DefaultExperiment:
    """The model description's ``DefaultExperiment``, its attributes as text (None: not given)."""
    start_time: str | None
    stop_time: str | None
    step_size: str | None
    tolerance: str | None


@dataclass(frozen=True)
class FMUDescription:
    """A checked model description, as values, and the interface the master drives it through."""
    path: Path
    kind: Kind
    fmi_version: str
    guid: str
    generation_tool: str | None
    #: the modelIdentifier of the interface ``kind`` drives
    model_identifier: str
    variables: dict[str, Variable]
    #: For each output: the inputs it depends on at the same instant (FMI 2.0 ModelStructure).
    #: An output without a ``dependencies`` attribute depends on every input (FMI 2.0 §2.2.8).
    output_dependencies: dict[str, list[str]]
    unit_definitions: tuple[UnitDefinition, ...]
    default_experiment: DefaultExperiment | None
    log_categories: tuple[str, ...]
    #: the Co-Simulation interface's canBeInstantiatedOnlyOncePerProcess (False without one)
    instantiated_once_per_process: bool
    #: Model Exchange: numberOfContinuousStates, numberOfEventIndicators, needsCompletedIntegratorStep
    continuous_states: int
    event_indicators: int
    needs_completed_integrator_step: bool
    #: Array elements named by connectors (``vector[2]``), by the value reference the master
    #: gives them (not the FMU's; cosim.run.instances.fmi3 maps it back to the array and the index).
    elements: dict[int, ArrayElement] = field(default_factory=dict)

    def variable(self, name: str, where: str, file: str) -> Variable:
        """The variable called ``name``, or the element ``name`` names of an FMI 3.0 array."""
        var = self.variables.get(name)
        if var is not None:
            return var
        match = _ELEMENT.fullmatch(name)
        if match is not None and match.group(1) in self.variables and self.variables[match.group(1)].dimensions:
            return self._element(self.variables[match.group(1)], match.group(2), name, where, file)
        raise SetupError(f"the FMU {self.path.name} has no variable '{name}'.", file=file,
                         element=where, variable=name, hint=did_you_mean(name, self.variables))

    def _element(self, array: Variable, index_text: str, name: str, where: str, file: str) -> ArrayElement:
        """One element of a one-dimensional FMI 3.0 array, 1-based as in Modelica and in the
        FMI 2.0 structured names of scalarised arrays (``x[1]`` is the first element)."""
        known = next((e for e in self.elements.values() if e.name == name), None)
        if known is not None:
            return known
        if len(array.dimensions) != 1 or array.type in ("String", "Binary"):
            raise SetupError(f"'{array.name}' is a {len(array.dimensions)}-dimensional {array.type} array; only "
                             "elements of one-dimensional numeric and Boolean arrays can be connected.",
                             file=file, element=where, variable=name)
        size = int(array.dimensions[0])
        if not index_text.strip().isdigit() or not 1 <= int(index_text) <= size:
            raise SetupError(f"'{index_text}' is not an element of {array.name}, an array of {size} values in "
                             f"{self.path.name}; elements are numbered {array.name}[1] .. {array.name}[{size}].",
                             file=file, element=where, variable=name)
        used = {v.vr for v in self.variables.values()} | set(self.elements)
        vr = 0xFFFFFFFF
        while vr in used:
            vr -= 1
        element = ArrayElement(name=name, vr=vr, type=array.type, description=array.description,
                               causality=array.causality, variability=array.variability, initial=array.initial,
                               declared_type=array.declared_type, unit=array.unit, min=array.min, max=array.max,
                               array=array, index=int(index_text) - 1, size=size)
        self.elements[vr] = element
        for deps in self.output_dependencies.values():  # an input element is known as its array
            if array.name in deps:
                deps.append(name)
        if array.name in self.output_dependencies:  # an output element depends on what its array does
            self.output_dependencies[name] = list(self.output_dependencies[array.name])
        return element


_ELEMENT = re.compile(r"(.+)\[([^\]]*)\]")


def _extent(dimension) -> str | None:
    """A Dimension's extent as text: its ``start``, or the start of the structural parameter it names."""
    return dimension.start if dimension.start is not None else dimension.variable.start


def _variable(v: ModelVariable) -> Variable:
    """fmpy's ``ModelVariable`` as our record."""
    t = v.declaredType
    declared = None if t is None else DeclaredType(t.name, t.unit, tuple((i.name, int(i.value)) for i in t.items))
    return Variable(name=v.name, vr=v.valueReference, type=v.type, causality=v.causality,
                    variability=v.variability, initial=v.initial, unit=v.unit, start=v.start, min=v.min,
                    max=v.max, description=v.description, declared_type=declared,
                    dimensions=tuple(_extent(d) for d in v.dimensions or ()))


def _unit_definition(u) -> UnitDefinition:
    """fmpy's ``Unit`` as our record (`cosim.model.units.fmu_units` checks it)."""
    b = u.baseUnit
    if b is None:
        return UnitDefinition(u.name, None)
    return UnitDefinition(u.name, tuple(int(getattr(b, n)) for n in BASE_UNITS), float(b.factor), float(b.offset))


#: The exchange types of the master (the FMI 2.0 type names) for the FMI types it connects.
_EXCHANGE_TYPES: dict[str, ExchangeType] = {
    "Real": "Real", "Integer": "Integer", "Boolean": "Boolean", "String": "String", "Enumeration": "Integer",
    "Float64": "Real", "Float32": "Real", "Int8": "Integer", "UInt8": "Integer", "Int16": "Integer",
    "UInt16": "Integer", "Int32": "Integer", "UInt32": "Integer", "Int64": "Integer", "UInt64": "Integer",
    "Binary": "Binary"}


def exchange_type(variable: Variable) -> ExchangeType | None:
    """How the master exchanges ``variable``: "Real" (C double), "Integer" (C int), "Boolean"
    or "String", for FMI 2.0 variables of those types and Enumeration (an Integer, FMI 2.0
    §2.2.3), FMI 3.0 Float64 and Float32 (Real), Int8..UInt64 and Enumeration (Integer; a value
    beyond 32 bits is refused when read, `cosim.run.instances.fmi3`), Boolean, String and Binary
    (exchanged, not recorded); None for the type it does not connect (FMI 3.0 Clock)."""
    return _EXCHANGE_TYPES.get(variable.type)


_cache: dict[tuple[Path, str], FMUDescription] = {}


def describe(path: Path, where: str, file: str, implementation: str = "any", validate: bool = True) -> FMUDescription:
    """Read and check an FMU's model description; ``where``/``file`` say who refers to it and
    ``implementation`` is the SSD Component's choice of interface (SSP 1.0: any,
    CoSimulation, ModelExchange; "any" prefers Co-Simulation when the FMU has both).
    ``validate``: against the FMI schema (False: this content passed before, `cosim.plan.build`)."""
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
    interface = md.modelExchange if kind in MODEL_EXCHANGE else md.coSimulation
    e = md.defaultExperiment
    me = md.modelExchange
    desc = FMUDescription(
        path=path, kind=kind, fmi_version=md.fmiVersion, guid=md.guid, generation_tool=md.generationTool,
        model_identifier=interface.modelIdentifier, variables={n: _variable(v) for n, v in variables.items()},
        output_dependencies=deps, unit_definitions=tuple(_unit_definition(u) for u in md.unitDefinitions),
        default_experiment=None if e is None else DefaultExperiment(e.startTime, e.stopTime, e.stepSize,
                                                                    e.tolerance),
        log_categories=tuple(c.name for c in md.logCategories),
        instantiated_once_per_process=bool(md.coSimulation is not None
                                           and md.coSimulation.canBeInstantiatedOnlyOncePerProcess),
        continuous_states=md.numberOfContinuousStates, event_indicators=md.numberOfEventIndicators,
        needs_completed_integrator_step=bool(me is not None and me.needsCompletedIntegratorStep))
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



def unit_of(v: Variable) -> str | None:
    """A variable's unit: its own, else its declared type's (FMI 2.0 §2.2.7); None: no unit."""
    if v.unit:
        return v.unit
    return v.declared_type.unit if v.declared_type is not None and v.declared_type.unit else None
