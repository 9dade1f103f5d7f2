"""The master's data model: every stage's product, as plain dataclasses.

The data path reads one way (docs/architecture.md)::

    ssp.read  (XML → RawStructure)  →  flatten  (→ SystemStructure)
      →  resources.locate_fmus  (→ {component: FMU path})
      →  plan.build_plan  (→ Plan)  →  execution, observers, pack, sweep

Each stage returns a new value and changes nothing it was given.  The readers and the
checks import this module, not each other.
"""
from __future__ import annotations

import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal


import numpy as np

from .fmu import FMUDescription, Variable, exchange_type
from .frozen import FrozenMap
from .transforms import Transform, Transformation
from .units import SystemUnits, Unit



# --------------------------------------------------------------------------- as read (cosim.read.ssp)

@dataclass(frozen=True)
class Connector:
    name: str
    kind: str
    type: str | None
    unit: str | None
    line: int


@dataclass(frozen=True)
class ParameterValue:
    """One value from a parameter set; ``name`` is as it resolves at its binding level."""
    name: str
    type: str
    value: float | int | bool | str
    file: str
    line: int
    #: ``ssv:Real unit``: the unit ``value`` is given in (None: the FMU variable's own)
    unit: str | None = None
    #: the ``ssv:Units`` of the parameter set that holds the value (SSP 1.0 ParameterSet)
    units: Mapping[str, Unit] = field(default_factory=FrozenMap, repr=False)
    #: the ``ssm:MappingEntry`` that renamed (and perhaps transformed) the value, for messages ("" if none)
    mapping: str = ""
    #: a mapping's ``ssc:LinearTransformation`` still to apply after converting ``unit`` to the
    #: variable's unit (SSP 1.0 MappingEntry: units first, then the transformation); None: none left
    transform: Transform | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "units", FrozenMap(self.units))

    def element(self) -> str:
        """Where the value comes from, for messages: its ``ssv:Parameter`` and the mapping entry, if any."""
        return f"ssv:Parameter (line {self.line})" + (f", mapped by {self.mapping}" if self.mapping else "")


@dataclass(frozen=True)
class Component:
    """One ``ssd:Component`` (SSP 1.0): an FMU, its connectors and its parameter bindings' values."""
    name: str
    source: str
    line: int
    connectors: Mapping[str, Connector] = field(default_factory=FrozenMap)
    parameters: tuple[ParameterValue, ...] = ()
    #: SSP 1.0 Component ``implementation``: "any", "CoSimulation" or "ModelExchange" (the
    #: interface the master drives; cosim.read.description.describe checks the FMU has it)
    implementation: str = "any"
    #: the component's ``org.greyfmu.solver`` annotation, for a Model Exchange FMU
    solver: SolverOptions | None = None
    #: its ``sourceBase="component"`` bindings, read once the FMU is located
    component_bindings: tuple[ComponentBinding, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "connectors", FrozenMap(self.connectors))
        object.__setattr__(self, "parameters", tuple(self.parameters))


@dataclass(frozen=True)
class MappingEntry:
    """One ``ssm:MappingEntry``: ``source`` → ``target``, with an optional transformation (applied by
    `cosim.read.mapping`)."""
    source: str
    target: str
    suppress_unit_conversion: bool
    file: str
    line: int
    #: "Linear", "Boolean", "Integer", "Enumeration" (the ssc:...Transformation) or None
    kind: str | None = None
    #: its transformation of the ssv value: an `Affine` (Linear) or a `Table` of ssc:MapEntry values
    transform: Transform | None = None

    def where(self) -> str:
        return f"ssm:MappingEntry '{self.source}' -> '{self.target}' ({self.file}, line {self.line})"


@dataclass(frozen=True)
class ComponentBinding:
    """A ``sourceBase="component"`` ParameterBinding (SSP 1.0 §5.3.3): its ``.ssv`` is a file
    inside the component's FMU, which is known only once the FMU has been located
    (`cosim.read.resources.locate_fmus`: beside the SSD, from a provider or in a ``--fmu-dir``);
    `cosim.read.ssp.read_component_bindings` then reads it and inserts its values at ``position``
    among the component's other binding values, keeping the bindings' order (later wins)."""
    source: str
    prefix: str
    #: the binding's ssd:ParameterMapping entries, or None without one
    mapping: tuple[MappingEntry, ...] | None
    position: int
    #: the SSD and the ssd:ParameterBinding, for messages
    display: str
    where: str


@dataclass(frozen=True)
class SolverOptions:
    """``org.greyfmu.solver``: settings for integrating a Model Exchange FMU (None: the default)."""
    rtol: float | None
    max_step: float | None
    #: the SSD file and the annotation element, for messages
    file: str
    element: str


@dataclass(frozen=True)
class SolverSettings:
    """How the master integrates a Model Exchange FMU (recorded in the run metadata)."""
    method: str
    rtol: float
    #: largest internal step (never more than the communication step); None: the communication step
    max_step: float | None = None

    def as_dict(self) -> dict:
        return {"method": self.method, "rtol": self.rtol,
                "max_step": "communication step" if self.max_step is None else self.max_step}


@dataclass
class Connection:
    #: None, before flattening only, where the connection names a connector of its own system
    start_element: str | None
    start_connector: str
    end_element: str | None
    end_connector: str
    #: its transformation (SSP 1.0 GTransformationChoice: an ``ssc:LinearTransformation``, an
    #: `cosim.model.transforms.Affine`, or a `cosim.model.transforms.MappingTable`); None: none.  A
    #: connection resolved through system connectors has its hops' instead (``hops``)
    transform: Transformation | None
    suppress_unit_conversion: bool
    line: int
    #: for a connection resolved through system connectors: its lines and the connectors on the way
    via: str = ""
    #: for a connection resolved through system connectors: each connection on the way (`Hop`)
    hops: tuple[Hop, ...] = ()

    def describe(self) -> str:
        return (f"connection {self.start_element}.{self.start_connector} -> "
                f"{self.end_element}.{self.end_connector} ({self.via or f'line {self.line}'})")



# --------------------------------------------------------------------------- nesting (cosim.read.flatten)

@dataclass
class RawSystem:
    """One ``ssd:System`` as read, before flattening: local names, connections with
    ``start_element``/``end_element`` None where they name this system's own connectors."""
    name: str
    line: int
    connectors: dict[str, Connector]
    components: dict[str, Component]
    systems: dict[str, RawSystem]
    connections: list[Connection]
    parameters: list[ParameterValue]
    #: names of the components and systems in document order
    elements: list[str] = field(default_factory=list)
    #: the ``ssd:SignalDictionaries`` of this system, by name
    dictionaries: dict[str, SignalDictionary] = field(default_factory=dict)
    #: the ``ssd:SignalDictionaryReference`` elements of this system, by name
    references: dict[str, SignalReference] = field(default_factory=dict)


@dataclass
class SignalDictionary:
    """One ``ssd:SignalDictionary``: named signals (``ssb:DictionaryEntry``), each a connector of
    kind ``signal`` owned by the system that declares the dictionary (`cosim.read.flatten`)."""
    name: str
    line: int
    #: the file that declares the entries (the .ssb, or the SSD for an inline dictionary)
    file: str
    entries: dict[str, Connector]


@dataclass
class SignalReference:
    """One ``ssd:SignalDictionaryReference``: an element whose connectors are the entries of the
    dictionary it names, looked up in its system and then in the enclosing ones."""
    name: str
    dictionary: str
    line: int
    connectors: dict[str, Connector]


@dataclass(frozen=True)
class SystemNode:
    """The hierarchy as `cosim info` shows it: full component paths, nested systems."""
    name: str
    path: str
    line: int
    connectors: tuple[Connector, ...]
    components: tuple[str, ...]
    systems: tuple[SystemNode, ...]


@dataclass(frozen=True)
class Hop:
    """One ``ssd:Connection`` on a path through system connectors.

    SSP 1.0 (SystemStructureDescription.xsd, Connection and its ``suppressUnitConversion``)
    converts the value on each connection from its start connector's unit to its end
    connector's unit, then applies that connection's transformation (only the transformation
    when ``suppressUnitConversion="true"``).  `cosim.plan.routing` composes the hops in that order;
    it knows the component ends' units (their FMU variables), this module does not.
    """
    line: int
    #: the system connector at each end (``loop.r``; ``r`` on the root); None where the end is a component
    start_system: str | None
    end_system: str | None
    #: those system connectors' ``ssc:Real unit``; None for a component end or a connector without one
    start_unit: str | None
    end_unit: str | None
    #: its transformation as read (`Connection.transform`), None without one
    transform: Transformation | None
    suppress: bool


@dataclass
class SystemOutput:
    """A root-system output connector: an alias of the component output that drives it
    through ``hops``; `cosim.plan.build` composes them, with the unit conversions, into the
    plan's `RecordedOutput`.  ``component`` and ``connector`` are None for one that no
    component output drives (SSP 1.0 does not require a system connector to be connected):
    ``undriven`` says why, and its column is constant (`cosim.plan.build`)."""
    name: str
    component: str | None
    connector: str | None
    line: int
    hops: tuple[Hop, ...] = ()
    #: an undriven one: why, and its ssd:Connector (type and unit of its value)
    undriven: str = ""
    declared: Connector | None = None


@dataclass
class OpenConnector:
    """A system connector without a driver, and the component inputs or parameters it feeds
    (none: a value for it has no effect); a ParameterBinding naming ``path`` gives it its
    (constant) value."""
    path: str
    kind: str
    line: int
    #: (component path, connector name, the connections on the way) reached through the hierarchy
    sinks: list[tuple[str, str, tuple[Hop, ...]]]
    #: its ``ssc:Real unit``, if it declares one
    unit: str | None = None


@dataclass(frozen=True)
class ScenarioFiles:
    """Where a scenario was read from."""
    ssd_file: Path
    #: the SSD's folder (inside an .ssp archive: the extraction folder)
    base_dir: Path
    archive: Path | None

    @property
    def source(self) -> Path:
        """What the user gave: the archive, else the SSD."""
        return self.archive or self.ssd_file

    @property
    def single_fmu(self) -> bool:
        """Whether the scenario is one FMU run as a system (`cosim.read.single`): its "SSD" is the FMU."""
        return self.ssd_file.suffix.lower() == ".fmu"

    @property
    def display(self) -> str:
        """The SSD as messages name it: ``archive.ssp!SystemStructure.ssd`` inside an archive
        (its extraction folder is temporary), else its path."""
        return display_name(self.ssd_file, self.archive)


def display_name(ssd_file: Path, archive: Path | None) -> str:
    """`ScenarioFiles.display`."""
    return f"{archive}!{ssd_file.name}" if archive is not None else str(ssd_file)


@dataclass(frozen=True)
class Experiment:
    """The SSD's ``ssd:DefaultExperiment`` and step-size annotation (None where it gives none)."""
    start_time: float | None
    stop_time: float | None
    step_size: float | None
    #: which annotation gave the step size
    step_size_source: str | None
    algorithm: str | None


@dataclass
class RawStructure:
    """An SSD as read (`cosim.read.ssp.read`): the root system with its nesting and local names,
    the default experiment and the SSD's units; `cosim.read.flatten.flatten` makes it a
    `SystemStructure`."""
    name: str
    files: ScenarioFiles
    #: the SSD as messages name it (``archive.ssp!SystemStructure.ssd`` inside an archive)
    display: str
    root: RawSystem
    experiment: Experiment
    #: the SSD's top-level ``ssd:Units`` (SSP 1.0 SystemStructureDescription.xsd)
    units: dict[str, Unit]
    #: the extraction folder of an .ssp archive
    _tmp: tempfile.TemporaryDirectory | None = field(default=None, repr=False)


# --------------------------------------------------------------------------- flattened (cosim.read.flatten)

@dataclass
class SystemStructure:
    name: str
    system_name: str
    ssd_file: Path
    base_dir: Path
    components: dict[str, Component]
    connections: list[Connection]
    parameters: list[ParameterValue]
    start_time: float | None
    stop_time: float | None
    step_size: float | None
    step_size_source: str | None
    algorithm: str | None
    #: the SSD's top-level ``ssd:Units`` (SSP 1.0 SystemStructureDescription.xsd)
    units: dict[str, Unit] = field(default_factory=dict)
    archive: Path | None = None
    _tmp: tempfile.TemporaryDirectory | None = field(default=None, repr=False)
    #: the systems as nested in the SSD, for `cosim info`
    hierarchy: SystemNode | None = None
    #: root-system output connectors: recorded under their name, aliases of component outputs
    system_outputs: dict[str, SystemOutput] = field(default_factory=dict)
    #: undriven system connectors feeding inputs or parameters: they need a ParameterBinding value
    open_connectors: dict[str, OpenConnector] = field(default_factory=dict)
    #: paths of the system connectors a connection drives (they cannot also be given a value)
    driven_connectors: set[str] = field(default_factory=set)

    @property
    def display(self) -> str:
        """The SSD as messages name it (`ScenarioFiles.display`)."""
        return display_name(self.ssd_file, self.archive)

    def close(self) -> None:
        """Remove the extraction folder of an .ssp archive, if this copy owns it."""
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __getstate__(self) -> dict:
        """Pickled without the extraction folder: a copy in another process (a sweep's worker,
        `cosim.sweep.dispatch.Task.prepared`) reads the archive's files where the process that
        extracted them keeps them, and never removes them."""
        return {**self.__dict__, "_tmp": None}


# --------------------------------------------------------------------------- validated (cosim.plan.build)

@dataclass(frozen=True)
class Route:
    """One connection, resolved: output (src) to input (dst); ``transform`` maps the source FMU's
    value to the destination FMU's value: the unit conversions and the transformations on the way
    composed (`cosim.plan.routing.path_transform`; an `cosim.model.transforms.Affine` for Real
    values, a `cosim.model.transforms.Table` for mapping tables of the others)."""
    src: str
    src_var: Variable
    dst: str
    dst_var: Variable
    transform: Transform

    @property
    def source(self) -> str:
        """``src.var``: the output, as results name it (and the operand of its transformation's text)."""
        return f"{self.src}.{self.src_var.name}"

    @property
    def label(self) -> str:
        """``src.var -> dst.var``, as messages and the metadata name it."""
        return f"{self.source} -> {self.dst}.{self.dst_var.name}"


#: How the master treats an algebraic loop (`cosim.run.loops`): solve it by iteration at every
#: communication point, or break it by one step of delay (libcosim's behaviour).
LoopMode = Literal["iterate", "delay"]
LOOP_MODES: tuple[LoopMode, ...] = ("iterate", "delay")


@dataclass(frozen=True)
class AlgebraicLoop:
    """A strongly connected set of connected variables through direct feedthrough
    (`cosim.plan.graph.algebraic_loops`): outputs that depend on each other at the same instant."""
    #: one cycle through the loop, as ('out' | 'in', component, variable) nodes, back to its start
    path: tuple[tuple[str, str, str], ...]
    #: every variable of the loop
    variables: frozenset[tuple[str, str, str]]

    @property
    def components(self) -> list[str]:
        return list(dict.fromkeys(c for _, c, _ in sorted(self.variables, key=lambda n: (n[1], n[2]))))

    @property
    def outputs(self) -> list[tuple[str, str]]:
        """(component, output) of the loop: the values iterated on."""
        return sorted((c, v) for kind, c, v in self.variables if kind == "out")

    def describe(self) -> str:
        return " -> ".join(f"{c}.{v} ({k}put)" for k, c, v in self.path)


@dataclass(frozen=True)
class StartValue:
    component: str
    variable: Variable
    value: float | int | bool | str
    origin: str


@dataclass(frozen=True)
class RecordedOutput:
    """A root-system output connector as recorded: ``transform`` of ``component.connector``, the
    per-hop composition of unit conversions and transformations from the FMU variable's value to
    the root connector's (`cosim.plan.routing.path_transform`).

    An undriven one (``component`` None) is ``Affine(0, value)`` of time: the constant its
    ParameterBinding value gives, else NaN, in every row (`cosim.plan.build`), through the same
    per-chunk arithmetic as the others (`source`)."""
    name: str
    component: str | None
    connector: str | None
    transform: Transform
    #: the last unit a system connector declares on the way, else the source's
    unit: str | None
    #: an undriven one: the line of its ssd:Connector, and where its value comes from
    #: (``FILE:LINE`` of the ssv:Parameter; None: no value, NaN)
    line: int | None = None
    origin: str | None = None

    @property
    def source(self) -> str:
        """The recorded column it is computed from: the driving component output, or ``time``."""
        return "time" if self.component is None else f"{self.component}.{self.connector}"


#: the Real types of FMI 2.0 and 3.0 that may be continuous
REAL_TYPES = ("Real", "Float64", "Float32")


@dataclass(frozen=True)
class Target:
    """The input one column of an input table drives, and the values it gets (the column's, through
    a system connector's transformations and unit conversions where the column names one)."""
    column: int
    component: str
    variable: Variable
    values: tuple[float, ...]

    @property
    def name(self) -> str:
        return f"{self.component}.{self.variable.name}"

    @property
    def discrete(self) -> bool:
        """Held between samples (fmpy: every input that is not a continuous Real)."""
        return not (self.variable.type in REAL_TYPES and self.variable.variability not in ("discrete", "tunable"))


@dataclass(frozen=True)
class BoundTable:
    """An input table (``--input-file``) checked against a plan (`cosim.plan.inputs.bind_table`):
    its sample times and which input each column drives."""
    file: str
    time: tuple[float, ...]
    targets: tuple[Target, ...]

    def event_times(self) -> list[float]:
        """The table's events as fmpy finds them (``Input.findEvents``): times given twice, and the
        times a discrete input's value changes."""
        t = np.array(self.time)
        events = set(t[np.flatnonzero(np.diff(t) == 0)].tolist())
        for target in self.targets:
            if target.discrete:
                events.update(t[np.flatnonzero(np.diff(np.array(target.values))) + 1].tolist())
        return sorted(events)


@dataclass(frozen=True)
class Plan:
    """Everything a run needs, checked against the FMUs (`cosim.plan.build.build_plan`): execution,
    recording, packing and sweeps take what they need from here, and nothing else of the scenario.
    Immutable all the way down (tuples, frozensets, `cosim.model.frozen.FrozenMap` and frozen
    records) and hashable: a value a sweep ships to its workers and a test compares."""
    name: str | None
    #: the root system's name (result names are paths relative to it)
    system_name: str
    files: ScenarioFiles
    experiment: Experiment
    #: the flattened components, by path, in SSD order
    components: Mapping[str, Component]
    fmus: Mapping[str, FMUDescription]
    #: how the master integrates each Model Exchange component (`cosim.plan.solvers`)
    solvers: Mapping[str, SolverSettings]
    routes: tuple[Route, ...]
    start_values: tuple[StartValue, ...]
    #: per component, the connector variables recorded and exchanged, in SSD order
    outputs: Mapping[str, tuple[Variable, ...]]
    inputs: Mapping[str, tuple[Variable, ...]]
    #: components whose outputs must be re-read after their inputs are set at a
    #: communication point (direct feedthrough), in dependency order; may repeat.  With
    #: ``loop_mode`` "iterate" it includes the components of algebraic loops (the sweep the
    #: loop solver repeats); with "delay" they are left out (read once per communication
    #: point: every connection out of them one step late, as libcosim runs them).
    feedthrough_sequence: tuple[str, ...]
    #: Gauss-Seidel order: upstream first, SSD order inside a loop
    gauss_seidel_order: tuple[str, ...]
    #: root-system output connectors, recorded after the component connectors
    system_outputs: Mapping[str, RecordedOutput]
    #: the recorded connectors of the components in result-column order: component by component
    #: in SSD order, connectors as each component lists them
    columns: tuple[str, ...]
    #: each recorded signal's unit (None: no unit)
    units: Mapping[str, str | None]
    #: where unit names are looked up (`cosim.plan.parameters.check_values`)
    unit_scopes: SystemUnits
    #: components of the feedthrough sequence whose outputs nobody reads before the settling
    #: re-reads them: the exchange skips their first read (`cosim.plan.graph.settling_shortcuts`)
    read_in_settling_only: frozenset[str] = frozenset()
    #: the algebraic loops of direct feedthrough (`cosim.plan.graph.algebraic_loops`)
    algebraic_loops: tuple[AlgebraicLoop, ...] = ()
    loop_mode: LoopMode = "iterate"
    #: components of the feedthrough sequence whose inputs are final when the settling sets
    #: them: the exchange does not set them again
    set_in_settling_only: frozenset[str] = frozenset()
    #: an input table (``--input-file``) feeding inputs by name (`BoundTable`, `cosim.plan.inputs.bind_table`), or None
    input_table: BoundTable | None = None
    #: each undriven system connector that feeds inputs: (component, variable, the transformation a
    #: number given to it without a unit takes on the way) per input it feeds (`cosim.plan.parameters.open_inputs`)
    open_inputs: Mapping[str, tuple[tuple[str, str, Transform], ...]] = field(default_factory=FrozenMap)
    #: the systems as nested in the SSD, for `cosim info`
    hierarchy: SystemNode | None = None

    def recorded(self) -> tuple[list[str], list[str]]:
        """The result names of the recorded outputs (the root system's output connectors last)
        and inputs: every connector but String and Binary ones, which are exchanged, not recorded
        (`cosim.run.link.LinkedProgram.recorder_sources`)."""
        def names(group: Mapping[str, tuple[Variable, ...]]) -> list[str]:
            return [f"{c}.{v.name}" for c, vs in group.items() for v in vs
                    if exchange_type(v) not in ("String", "Binary")]
        return names(self.outputs) + list(self.system_outputs), names(self.inputs)
