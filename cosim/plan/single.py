"""Runs as ``fmpy simulate`` words them: one FMU without an SSD, start values and an input table.

`fmu_structure` builds a one-component system in memory from an FMU (`cosim run X.fmu`): the
component is named after the FMU's model identifier, every input and output is a connector,
the default experiment of its modelDescription.xml gives the start and stop time and the step
(a missing step is fmpy's automatic interval, ``fmpy.util.auto_interval``); what follows is the
path of an SSD (`cosim.plan.build.build_plan` and on), so results are named ``<model>.<variable>``;
each output is also an output connector of the system named as the variable, so it is recorded
again under the name fmpy gives its column (``y`` besides ``Drive.y``), and a result compares
with an fmpy result or a cross-check reference by name (`cosim compare ref.csv result.csv`).

`prepare_run` prepares a run of an FMU or an SSP system with what the command line adds:
``--start NAME=VALUE`` values (applied last, after the parameter sets, checked as parameter
sets are), ``--input-file`` (`cosim.plan.inputs`), ``--output-interval`` (fmpy's name for the
communication step of a Co-Simulation run) and ``--fmi-type`` (the interface of an FMU that has
both).  For a single FMU a name is the variable's own (``u``, ``inertia1.phi``), as fmpy's; for
a system it is ``component.variable``.
"""
from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from fmpy.util import auto_interval

from ..read import ssp
from ..model.fmu import exchange_type
from ..read.description import describe
from ..errors import SetupError
from ..read.flatten import flatten
from .inputs import InputTable, bind_table, connector_values, read_input_table, with_table
from ..read.loadable import check_fmu_file, check_library
from .parameters import split_system_name
from .build import build_plan
from .loopcheck import check_loops
from ..read.resources import locate_fmus
from ..run.simulation import Prepared, resolve_grid
from ..model.structure import (
    Component,
    Connection,
    Connector,
    Experiment,
    ParameterValue,
    Plan,
    RawStructure,
    RawSystem,
    ScenarioFiles,
    SystemStructure,
)

#: --fmi-type values (fmpy's) and the SSP Component implementation each chooses
FMI_TYPES = {"CoSimulation": "CoSimulation", "ModelExchange": "ModelExchange"}
#: where --start values come from, in messages and the run metadata's parameter origins
START_SOURCE = "--start-value"


def is_fmu(path: str | Path) -> bool:
    return Path(path).suffix.lower() == ".fmu"


def fmu_structure(path: str | Path, fmi_type: str | None = None) -> SystemStructure:
    """A one-component system of the FMU at ``path``, flattened as an SSD's would be."""
    fmu = Path(path)
    if not fmu.is_file():
        raise SetupError("no such FMU file.", file=str(fmu), element="cosim run X.fmu")
    implementation = FMI_TYPES[fmi_type] if fmi_type else "any"
    where = "the FMU given"
    check_fmu_file(fmu, file=str(fmu), where=where)   # what build_plan checks, named as the user gave it
    desc = describe(fmu, where, str(fmu), implementation)
    check_library(desc.path, desc.model_identifier, desc.kind, file=str(fmu), where=where)
    name = desc.model_identifier
    connectors = {v.name: Connector(v.name, v.causality, None, None, 0) for v in desc.variables.values()
                  if v.causality in ("input", "output") and exchange_type(v) is not None and not v.dimensions}
    component = Component(name, fmu.name, 0, connectors, implementation=implementation)
    e = desc.default_experiment
    start = float(e.start_time) if e is not None and e.start_time is not None else None
    stop = float(e.stop_time) if e is not None and e.stop_time is not None else None
    step = float(e.step_size) if e is not None and e.step_size is not None else None
    outputs = [c for c in connectors.values() if c.kind == "output"]
    aliases = {c.name: Connector(c.name, "output", None, None, 0) for c in outputs}
    wires = [Connection(name, c.name, None, c.name, 1.0, 0.0, False, False, 0) for c in outputs]
    root = RawSystem(name, 0, aliases, {name: component}, {}, wires, [], [name])
    raw = RawStructure(name=name, files=ScenarioFiles(fmu, fmu.parent, None), display=str(fmu), root=root,
                       experiment=Experiment(start, stop, step, "modelDescription.xml DefaultExperiment stepSize"
                                             if step is not None else None, None), units={})
    return flatten(raw)


def plotted(plan: Plan, names: list[str]) -> list[str]:
    """The signals a default plot shows: for a single FMU its connectors once (not again under
    the output aliases that `fmu_structure` adds), for a system all."""
    if not is_fmu(plan.files.ssd_file):
        return names
    return [n for n in names if n not in plan.system_outputs]


def check_fmi_type(path: str | Path, fmi_type: str | None) -> None:
    """Refuse an unknown ``--fmi-type``, and one given for a system (its SSD chooses)."""
    if fmi_type is None:
        return
    if fmi_type not in FMI_TYPES:
        raise SetupError(f"unknown FMI type '{fmi_type}'; choose {' or '.join(FMI_TYPES)}.", element="--fmi-type")
    if not is_fmu(path):
        raise SetupError("--fmi-type chooses the interface of a single FMU; in a system each ssd:Component's "
                         "implementation attribute does.", file=str(path), element="--fmi-type")


@dataclass
class Scenario:
    """A scenario read, its FMUs located, its parameter sets and input table read: what every
    run of it shares (`load_scenario`); `prepare_scenario` makes a run's plan from it.  It owns
    the extracted archive of an .ssp until `close`."""
    structure: SystemStructure
    fmu_paths: dict[str, Path]
    single: bool
    #: the parameter sets' values, in the order applied, and the files they came from
    values: list[ParameterValue]
    parameter_sets: tuple[str, ...]
    table: InputTable | None

    def close(self) -> None:
        """Remove the extraction folder of an .ssp archive (`cosim.model.structure.SystemStructure.close`)."""
        self.structure.close()

    def __enter__(self) -> Scenario:
        """``with load_scenario(...) as scenario:`` the caller owns the extracted archive until the block ends."""
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def load_scenario(path: str | Path, *, fmi_type: str | None = None, parameter_sets: Sequence[str | Path] = (),
                  fmu_dirs: Sequence[str | Path] = (), input_file: str | Path | None = None) -> Scenario:
    """Read a system (or build one from an FMU), locate its FMUs, read ``parameter_sets`` and
    the ``input_file`` table; nothing is checked against the FMUs yet (`prepare_scenario`)."""
    check_fmi_type(path, fmi_type)
    single = is_fmu(path)
    if single:
        structure = fmu_structure(path, fmi_type)
        fmu_paths = {name: Path(path) for name in structure.components}
    else:
        structure = ssp.load(path)
    try:
        if not single:
            fmu_paths = locate_fmus(structure, [Path(d) for d in fmu_dirs])
            ssp.read_component_bindings(structure, fmu_paths)
        values = [p for ps in parameter_sets for p in ssp.read_ssv(ps)]
        table = read_input_table(input_file) if input_file is not None else None
    except BaseException:
        structure.close()
        raise
    return Scenario(structure, fmu_paths, single, values, tuple(str(p) for p in parameter_sets), table)


def prepare_run(path: str | Path, *, start_values: Sequence[str] = (), input_file: str | Path | None = None,
                fmi_type: str | None = None, output_interval: float | None = None,
                start_time: float | None = None, stop_time: float | None = None, step_size: float | None = None,
                algorithm: str | None = None, parameter_sets: Sequence[str | Path] = (),
                fmu_dirs: Sequence[str | Path] = (), loops: str = "iterate") -> Prepared:
    """Read and check everything a run needs (`cosim.run.simulation.prepare`, plus the options of
    this module); nothing is instantiated."""
    check_fmi_type(path, fmi_type)
    check_interval(output_interval, step_size)
    scenario = load_scenario(path, fmi_type=fmi_type, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs,
                             input_file=input_file)
    try:
        return prepare_scenario(scenario, start_values=start_values, output_interval=output_interval,
                                start_time=start_time, stop_time=stop_time, step_size=step_size,
                                algorithm=algorithm, loops=loops)
    except BaseException:
        scenario.close()
        raise


def check_interval(output_interval: float | None, step_size: float | None) -> None:
    """Refuse ``--output-interval`` and ``--step`` both given and different (fmpy's name and ours)."""
    if output_interval is not None and step_size is not None and output_interval != step_size:
        raise SetupError(f"--output-interval {output_interval:g} and --step {step_size:g} differ; both are the "
                         "communication step, at which results are recorded: give one.", element="--output-interval")


def prepare_scenario(scenario: Scenario, *, parameter_sets: Sequence[str | Path] = (),
                     start_values: Sequence[str] = (), output_interval: float | None = None,
                     start_time: float | None = None, stop_time: float | None = None,
                     step_size: float | None = None, algorithm: str | None = None,
                     loops: str = "iterate") -> Prepared:
    """The run of a loaded scenario (`load_scenario`): its plan checked against the FMUs with the
    scenario's parameter sets, then ``parameter_sets`` (applied after them), the input table's
    connector values and ``start_values``, on the grid resolved.  The `Prepared` shares the
    scenario's structure: closing it closes the scenario.  (`prepare_run` refuses an
    ``output_interval`` and ``step_size`` that differ before anything is read.)"""
    structure, fmu_paths, single, table = scenario.structure, scenario.fmu_paths, scenario.single, scenario.table
    extra = scenario.values + [p for ps in parameter_sets for p in ssp.read_ssv(ps)]
    if table is not None and not single:
        extra += connector_values(table, structure)
    with warnings.catch_warnings():
        if start_values:  # this plan only types them; the one built with them warns (cosim.plan.build)
            warnings.simplefilter("ignore", RuntimeWarning)
        plan = build_plan(structure, fmu_paths, extra, loops)
    component = next(iter(plan.components)) if single else None
    if start_values:
        starts = [_start_value(text, plan, component) for text in start_values]
        plan = build_plan(structure, fmu_paths, extra + starts, loops)
        extra += starts
    if table is not None:
        plan = with_table(plan, bind_table(table, plan, component, list(structure.parameters) + extra))
    step, source = (step_size, "command line") if step_size is not None else \
        (output_interval, "--output-interval") if output_interval is not None else (None, None)
    given = (("start time", "--start", start_time), ("stop time", "--stop", stop_time),
             ("step size", "--step" if step_size is not None else "--output-interval", step))
    options = {what: option for what, option, value in given if value is not None}  # what a refusal blames
    if single:
        stop_time, step, source = _fmu_defaults(plan, start_time, stop_time, step, source)
    prepared = resolve_grid(plan, start_time=start_time, stop_time=stop_time, step_size=step,
                            algorithm=algorithm, options=options)
    check_loops(prepared.plan, prepared.grid)  # cosim.plan.loopcheck: sampling and wiring the FMUs declare
    return replace(prepared, step_source=source or prepared.step_source,
                   parameter_sets=scenario.parameter_sets + tuple(str(p) for p in parameter_sets))


def _fmu_defaults(plan: Plan, start_time: float | None, stop_time: float | None, step: float | None,
                  source: str | None) -> tuple[float | None, float | None, str | None]:
    """What fmpy takes for an FMU whose DefaultExperiment gives no stop time (start + 1 s) or
    no step (``fmpy.util.auto_interval`` of the span): the stop time, step and its source."""
    experiment = plan.experiment
    start = start_time if start_time is not None else (experiment.start_time or 0.0)
    if stop_time is None and experiment.stop_time is None:
        stop_time = start + 1.0
    stop = stop_time if stop_time is not None else experiment.stop_time
    if step is None and experiment.step_size is None and stop > start:
        return stop_time, float(auto_interval(stop - start)), "fmpy's automatic interval"
    return stop_time, step, source


def _start_value(text: str, plan: Plan, single: str | None) -> ParameterValue:
    """``NAME=VALUE`` as a parameter value of the variable's type, named ``component.variable``;
    the plan's checks (causality, range, unit) are `cosim.plan.build.build_plan`'s for parameter sets."""
    from ..sweep.values import typed_values

    name, sep, raw = text.partition("=")
    name = name.strip()
    if not sep or not name or not raw.strip():
        raise SetupError(f"'{text}' is not NAME=VALUE (e.g. " + ("k=2" if single else "controller.Kc=2") + ").",
                         element=START_SOURCE)
    if single is not None:
        desc = plan.fmus[single]
        var_name = name if name in desc.variables or not name.startswith(single + ".") else name[len(single) + 1:]
        var = desc.variable(var_name, f"component '{single}'", f"{START_SOURCE} {text}")
        full = f"{single}.{var_name}"
    elif name in plan.structure.open_connectors or (name in plan.system_outputs
                                                    and plan.system_outputs[name].component is None):
        # a value for an undriven system connector (an undriven root output: its recorded constant)
        return ParameterValue(name, "Real", typed_values(raw.strip(), "Real", name, START_SOURCE)[0], START_SOURCE, 0)
    else:
        comp, var_name = split_system_name(plan.components, ParameterValue(name, "Real", 0.0, START_SOURCE, 0))
        var = plan.fmus[comp].variable(var_name, f"component '{comp}'", f"{START_SOURCE} {text}")
        full = name
    kind = exchange_type(var) or var.type
    values = typed_values(raw.strip(), kind, name, START_SOURCE)
    if len(values) != 1:
        raise SetupError(f"'{raw.strip()}' is {len(values)} values; a start value is one.", element=START_SOURCE,
                         variable=name)
    return ParameterValue(full, kind, values[0], START_SOURCE, 0)


def simulate_fmu(path: str | Path, *, start_values: Mapping[str, object] | None = None,
                 input_file: str | Path | None = None, output: str | Path | None = None,
                 **options) -> np.ndarray:
    """Run an FMU (or a system) as `cosim run` does and return the samples, like
    ``fmpy.simulate_fmu``: ``start_values`` by name (``{"gain": 3}``, the names of
    ``--start-value``), ``input_file`` an input table (`cosim.plan.inputs`), ``output`` a result file
    written as the run goes; ``options`` are `prepare_run`'s (``stop_time``, ``output_interval``,
    ``fmi_type``, ...).  A failed run raises `cosim.errors.RunError` (the samples so far in its
    ``result``)."""
    from ..safeio import lock_output
    from ..run.simulation import run

    texts = [f"{name}={str(value).lower() if isinstance(value, bool) else value}"
             for name, value in (start_values or {}).items()]
    with prepare_run(path, start_values=texts, input_file=input_file, **options) as prepared, \
            lock_output(output, option="output") if output is not None else nullcontext():
        outcome = run(prepared, output=output)
    return outcome.result
