"""Reading a model description: `describe` reads and checks an FMU's ``modelDescription.xml``
with fmpy and keeps what the master uses of it as our own frozen records (`cosim.model.fmu`):
nothing of fmpy's parsed objects leaves this module.  It decides which interface the master drives
(`cosim.model.fmu.FMUDescription.kind`); `cosim.run.instances` load the FMU with fmpy to run it.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import fmpy
from fmpy.model_description import ModelDescription, ModelVariable

from ..errors import SetupError
from ..model.structure import SystemStructure
from ..model.fmu import MODEL_EXCHANGE, DeclaredType, DefaultExperiment, FMUDescription, Kind, UnitDefinition, Variable
from ..model.frozen import FrozenMap
from ..model.units import BASE_UNITS
from . import conformance
from .fmucache import passed, record_pass
from .loadable import check_fmu_file, check_library

#: the verdict name of a model description valid against the FMI schema
SCHEMA_CHECK = "FMI schema"

#: SSP 1.0 Component ``implementation`` values (SystemStructureDescription.xsd).
IMPLEMENTATIONS = ("any", "CoSimulation", "ModelExchange")


def _extent(dimension) -> int | None:
    """A Dimension's extent: its ``start``, or the start of the structural parameter it names; None
    where neither is a whole number (`cosim.model.fmu.FMUDescription.shape` refuses such an array)."""
    start = dimension.start if dimension.start is not None else getattr(dimension.variable, "start", None)
    try:
        return int(start)
    except (TypeError, ValueError):
        return None


def _variable(v: ModelVariable) -> Variable:
    """fmpy's ``ModelVariable`` as our record."""
    t = v.declaredType
    declared = None if t is None else DeclaredType(t.name, t.unit, tuple((i.name, int(i.value)) for i in t.items))
    variability = "discrete" if v.variability == "continuous" and v.type not in conformance.REAL_TYPES \
        else v.variability   # tolerated (conformance: 'variability'), run as discrete
    return Variable(name=v.name, vr=v.valueReference, type=v.type, causality=v.causality,
                    variability=variability, initial=v.initial, unit=v.unit, start=v.start, min=v.min,
                    max=v.max, description=v.description, declared_type=declared,
                    dimensions=tuple(_extent(d) for d in v.dimensions or ()))


def _unit_definition(u) -> UnitDefinition:
    """fmpy's ``Unit`` as our record (`cosim.model.units.fmu_units` checks it)."""
    b = u.baseUnit
    if b is None:
        return UnitDefinition(u.name, None)
    return UnitDefinition(u.name, tuple(int(getattr(b, n)) for n in BASE_UNITS), float(b.factor), float(b.offset))


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
    try:  # the standard's rules are checked by conformance, each tolerated or refused
        md = fmpy.read_model_description(str(path), validate=False)
    except Exception as e:  # fmpy raises several types for unreadable FMUs
        raise SetupError(f"cannot read the model description of {path.name}: {e}", file=file,
                         element=where) from None
    kind = _kind(md, path, implementation, where, file)
    bends = conformance.check(md, path, schemas=Path(fmpy.__file__).parent / "schema" if validate else None,
                              file=file, where=where)
    if not md.guid or not md.guid.strip():
        raise SetupError(f"{path.name} has an empty GUID in its modelDescription.xml; an FMU without a GUID "
                         "cannot be instantiated.", file=file, element=where)
    variables = {v.name: v for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    deps: dict[str, tuple[str, ...]] = {}
    for unknown in md.outputs:
        if unknown.dependencies is None:
            deps[unknown.variable.name] = tuple(inputs)
        else:
            deps[unknown.variable.name] = tuple(d.name for d in unknown.dependencies if d.causality == "input")
    for v in md.modelVariables:
        if v.causality == "output" and v.name not in deps:
            deps[v.name] = tuple(inputs)
    interface = md.modelExchange if kind in MODEL_EXCHANGE else md.coSimulation
    e = md.defaultExperiment
    me = md.modelExchange
    desc = FMUDescription(
        path=path, kind=kind, fmi_version=md.fmiVersion, guid=md.guid, generation_tool=md.generationTool,
        model_identifier=interface.modelIdentifier,
        variables=FrozenMap((n, _variable(v)) for n, v in variables.items()), output_dependencies=FrozenMap(deps),
        unit_definitions=tuple(_unit_definition(u) for u in md.unitDefinitions),
        default_experiment=None if e is None else DefaultExperiment(e.startTime, e.stopTime, e.stepSize,
                                                                    e.tolerance),
        log_categories=tuple(c.name for c in md.logCategories),
        instantiated_once_per_process=bool(md.coSimulation is not None
                                           and md.coSimulation.canBeInstantiatedOnlyOncePerProcess),
        continuous_states=md.numberOfContinuousStates, event_indicators=md.numberOfEventIndicators,
        needs_completed_integrator_step=bool(me is not None and me.needsCompletedIntegratorStep), bends=bends)
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




def describe_fmu(path: Path, where: str, file: str, implementation: str = "any", warn: bool = True) -> FMUDescription:
    """`describe`, with the checks of what run loads (`cosim.read.loadable`): the archive and its
    entities before, the library after; the FMI schema validation made once per FMU content
    (`cosim.read.fmucache.passed`: a valid one); then one warning per rule of the standard the
    FMU bends (`cosim.read.conformance`), each time it is described (``warn``: False for a look
    that is followed by the description the plan is built from, `cosim.read.single`)."""
    check_fmu_file(path, file=file, where=where)
    schema_checked = passed(path, SCHEMA_CHECK)
    desc = describe(path, where, file, implementation, validate=not schema_checked)
    if not schema_checked and not any(rule == "schema" for rule, _ in desc.bends):
        record_pass(path, SCHEMA_CHECK)
    check_library(desc.path, desc.model_identifier, desc.kind, file=file, where=where)
    if warn:
        conformance.warn(desc.bends)
    return desc


def describe_fmus(structure: SystemStructure, fmu_paths: Mapping[str, Path]) -> dict[str, FMUDescription]:
    """Every component's FMU (``fmu_paths``: `cosim.read.resources.locate_fmus`) described and
    checked (`describe_fmu`), by component in SSD order: each FMU file once per interface asked
    for (the first component naming it in the errors), so a system of 1000 copies of one FMU
    checks it once, not 1000 times (issue 42: 1.2 ms a component)."""
    found: dict[tuple[Path, str], FMUDescription] = {}
    described = {}
    for name, comp in structure.components.items():
        key = (fmu_paths[name], comp.implementation)
        if key not in found:
            found[key] = describe_fmu(fmu_paths[name], f"ssd:Component '{name}' (line {comp.line})",
                                      structure.display, comp.implementation)
        described[name] = found[key]
    return described
