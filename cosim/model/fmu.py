"""FMUs as the master sees them before any is instantiated: the records of a checked model
description (`FMUDescription`, its `Variable` and `DeclaredType` records, `DefaultExperiment`,
`UnitDefinition`), values of our own that `cosim.read.description.describe` makes
from fmpy's parse.  Nothing here imports fmpy: a `cosim.model.structure.Plan` holding them is plain
data (a sweep pickles it for its workers, `cosim.sweep.dispatch`).  `FMUDescription.kind` is the
interface the master drives: an FMI 2.0 Co-Simulation FMU (``fmi2-cs``), an FMI 3.0 Co-Simulation
FMU (``fmi3-cs``) or an FMI 2.0 or 3.0 Model Exchange FMU integrated by the master (``fmi2-me``,
``fmi3-me``); `cosim.run.instances` holds the live instances of each kind.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from collections.abc import Sequence
from typing import Literal

from ..errors import SetupError, did_you_mean
from .frozen import FrozenMap

#: The interface the master drives an FMU through (`cosim.read.description.describe`).
Kind = Literal["fmi2-cs", "fmi3-cs", "fmi2-me", "fmi3-me"]
#: The kinds the master integrates (Model Exchange, `cosim.run.instances.me`).
MODEL_EXCHANGE: tuple[Kind, ...] = ("fmi2-me", "fmi3-me")
#: How the master exchanges a variable (`exchange_type`): the FMI 2.0 type names.
ExchangeType = Literal["Real", "Integer", "Boolean", "String", "Binary"]
#: The exchange types, in the order the exchange buffers and their gets and sets go in.
EXCHANGE_TYPES: tuple[ExchangeType, ...] = ("Real", "Integer", "Boolean", "String", "Binary")


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
    #: parameter it names (§2.4.7.5; None: not a whole number); () for a scalar
    dimensions: tuple[int | None, ...] = ()


@dataclass(frozen=True, kw_only=True)
class ArrayElement(Variable):
    """One element of an FMI 3.0 array variable, exchanged as a scalar of its own."""
    array: Variable = field(repr=False)
    #: 0-based position in the array's values (FMI 3.0 serialises arrays row-major, §2.4.7.5)
    index: int = 0
    size: int = 1


@dataclass(frozen=True)
class UnitDefinition:
    """One ``UnitDefinitions/Unit`` (FMI 2.0 §2.2.2): its BaseUnit's exponents in the order of
    `cosim.model.units.BASE_UNITS`, factor and offset (``base`` None: the Unit has no BaseUnit)."""
    name: str
    base: tuple[int, ...] | None
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class DefaultExperiment:
    """The model description's ``DefaultExperiment``, its attributes as text (None: not given)."""
    start_time: str | None
    stop_time: str | None
    step_size: str | None
    tolerance: str | None


@dataclass(frozen=True)
class FMUDescription:
    """A checked model description, as values, and the interface the master drives it through.
    Immutable: the elements of FMI 3.0 arrays that connectors name are added by `with_elements`,
    which returns a new description (`cosim.plan.build` keeps the one with its connectors')."""
    path: Path
    kind: Kind
    fmi_version: str
    guid: str
    generation_tool: str | None
    #: the modelIdentifier of the interface ``kind`` drives
    model_identifier: str
    variables: FrozenMap[str, Variable]
    #: For each output: the inputs it depends on at the same instant (FMI 2.0 ModelStructure).
    #: An output without a ``dependencies`` attribute depends on every input (FMI 2.0 §2.2.8).
    output_dependencies: FrozenMap[str, tuple[str, ...]]
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
    elements: FrozenMap[int, ArrayElement] = FrozenMap()
    #: (rule, warning) for each place its model description breaks a rule of the standard the
    #: master tolerates (`cosim.read.conformance`), warned about each time the FMU is described
    bends: tuple[tuple[str, str], ...] = ()

    def variable(self, name: str, where: str, file: str) -> Variable:
        """The variable called ``name``, or the element ``name`` names of an FMI 3.0 array (one
        `with_elements` added, else a new one with the next free value reference: `resolve`)."""
        known = self.variables.get(name) or self._elements_by_name.get(name)
        return known if known is not None else self.resolve([name], where, file)[1][0]

    @cached_property
    def _elements_by_name(self) -> dict[str, ArrayElement]:
        return {e.name: e for e in self.elements.values()}

    def resolve(self, names: Sequence[str], where: str | Sequence[str], file: str
                ) -> tuple[FMUDescription, list[Variable]]:
        """The variables ``names`` name (`variable`; ``where``: one place for all, or one per name) and
        this description knowing the new array elements among them (`with_elements`), each with
        a value reference of its own, in one pass however many (an array of 10 000 elements)."""
        known = dict(self._elements_by_name)
        new: list[ArrayElement] = []
        vr = min([*self.elements, 0x100000000]) - 1
        used = {v.vr for v in self.variables.values()}
        found = []
        for i, name in enumerate(names):
            place = where if isinstance(where, str) else where[i]
            var = self.variables.get(name) or known.get(name)
            if var is None:
                match = _ELEMENT.fullmatch(name)
                array = self.variables.get(match.group(1)) if match is not None else None
                if array is None or not array.dimensions:
                    raise SetupError(f"the FMU {self.path.name} has no variable '{name}'.", file=file,
                                     element=place, variable=name, hint=did_you_mean(name, self.variables))
                while vr in used:
                    vr -= 1
                var = known[name] = self._element(array, match.group(2), name, vr, place, file)
                new.append(var)
                vr -= 1
            found.append(var)
        return self.with_elements(new), found

    def shape(self, array: Variable, where: str, file: str) -> tuple[int, ...]:
        """The extents of an FMI 3.0 array (() for a scalar): each Dimension's ``start``, or the start
        of the structural parameter it names (FMI 3.0 §2.4.7.5; this master sets no structural
        parameter, so the start is the extent of the whole run)."""
        if any(d is None or d < 0 for d in array.dimensions):
            raise SetupError(f"the extents of the array {array.name} in {self.path.name} are "
                             f"{', '.join(str(d) for d in array.dimensions)}: not all are known numbers (a Dimension's "
                             "start, or the start of the structural parameter it names).",
                             file=file, element=where, variable=array.name)
        return tuple(array.dimensions)

    def with_elements(self, elements: Sequence[ArrayElement]) -> FMUDescription:
        """This description knowing ``elements`` (from `resolve`) by their value references, an input
        element among the inputs an output depends on where its array is, an output element
        depending on what its array depends on; itself when it knows them all."""
        elements = [e for e in elements if e.vr not in self.elements]
        if not elements:
            return self
        inputs: dict[str, list[str]] = {}
        for e in elements:
            inputs.setdefault(e.array.name, []).append(e.name)
        deps = {out: ins + tuple(n for name in ins for n in inputs.get(name, ()))
                for out, ins in self.output_dependencies.items()}
        deps.update({e.name: deps[e.array.name] for e in elements if e.array.name in deps})
        return replace(self, elements=FrozenMap({**self.elements, **{e.vr: e for e in elements}}),
                       output_dependencies=FrozenMap(deps))

    def _element(self, array: Variable, index_text: str, name: str, vr: int, where: str, file: str) -> ArrayElement:
        """One element of an FMI 3.0 array with the value reference ``vr``, named as fmpy and fmusim
        name it: 1-based indices as in Modelica and in the FMI 2.0 structured names of scalarised
        arrays, one per dimension, separated by commas (``x[1]`` is the first element, ``A[2,3]``
        row 2, column 3)."""
        if array.type in ("String", "Binary"):
            raise SetupError(f"'{array.name}' is a {array.type} array; only elements of numeric and Boolean "
                             "arrays can be connected.", file=file, element=where, variable=name)
        shape = self.shape(array, where, file)
        index = tuple(int(i) for i in index_text.split(",")) if _INDEX.fullmatch(index_text) else ()
        if element_name(array.name, index) != name or not all(1 <= i <= n for i, n in zip(index, shape)) \
                or len(index) != len(shape):
            bare = index_text.replace(" ", "")
            hint = (f"Write it {array.name}[{','.join(str(int(i)) for i in bare.split(','))}], as fmpy and fmusim "
                    "name it." if _INDEX.fullmatch(bare) and bare != index_text else None)
            raise SetupError(f"'{index_text}' is not an element of {array.name}, {describe_shape(shape)} in "
                             f"{self.path.name}; elements are numbered {element_name(array.name, (1,) * len(shape))} "
                             f".. {element_name(array.name, shape)}.", file=file, element=where, variable=name,
                             hint=hint)
        position = 0
        for i, n in zip(index, shape):   # row-major (FMI 3.0 §2.4.7.5)
            position = position * n + i - 1
        return ArrayElement(name=name, vr=vr, type=array.type, description=array.description,
                            causality=array.causality, variability=array.variability, initial=array.initial,
                            declared_type=array.declared_type, unit=array.unit, min=array.min, max=array.max,
                            array=array, index=position, size=math.prod(shape))


def element_name(array: str, index: tuple[int, ...]) -> str:
    """The name of one element of an FMI 3.0 array, as fmpy and fmusim name it: ``A[2,3]``."""
    return f"{array}[{','.join(str(i) for i in index)}]"


def element_names(array: str, shape: tuple[int, ...]) -> list[str]:
    """Every element's `element_name`, in the order FMI 3.0 serialises the values (row-major, §2.4.7.5)."""
    return [element_name(array, index) for index in itertools.product(*(range(1, n + 1) for n in shape))]


def describe_shape(shape: tuple[int, ...]) -> str:
    """``a scalar``, ``an array of 4 values``, ``an array of 2×3 values``."""
    return f"an array of {'×'.join(str(n) for n in shape)} values" if shape else "a scalar"


_INDEX = re.compile(r"\d+(,\d+)*")
_ELEMENT = re.compile(r"(.+)\[([^\]]*)\]")

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


def unit_of(v: Variable) -> str | None:
    """A variable's unit: its own, else its declared type's (FMI 2.0 §2.2.7); None: no unit."""
    if v.unit:
        return v.unit
    return v.declared_type.unit if v.declared_type is not None and v.declared_type.unit else None


def recorded_type(variable: Variable) -> bool:
    """Whether a result column can hold the variable's values: every exchange type but String and
    Binary (a result file holds numbers; they are exchanged, not recorded)."""
    return exchange_type(variable) not in ("String", "Binary")
