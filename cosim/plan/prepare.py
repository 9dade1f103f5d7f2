"""Preparing a run: everything that can fail before an FMU is instantiated, by one path for every
caller (`cosim run`, `validate`, `info` and `pack`, the Python API `cosim.prepare` and
`cosim.simulate`, `simulate_fmu`, sweeps and their workers).

`load_scenario` reads a system (an SSD, a folder, an ``.ssp``; or one FMU as a one-component
system, `cosim.read.single`), locates its FMUs, reads the parameter sets and the input table:
what every run of a scenario shares, and the owner of an ``.ssp``'s extraction folder.
`prepare_scenario` makes one run of it: the FMUs described, the ``--start-value`` texts typed by
their variables (`start_value`), the `cosim.model.structure.Plan` built once with all of them, the
input table bound to it, and the grid resolved (`resolve_grid`) -- a `Prepared` -- whose loops are
checked against what our FMUs declare (`cosim.plan.loopcheck`: warnings, errors with ``--strict``).  `prepare` is
the two in one call, the `Prepared` then owning the scenario (``with prepare(...) as prepared``).

What the command line adds (fmpy simulate's names where it has them): ``--start-value NAME=VALUE``
(applied last, after the parameter sets, checked as parameter sets are; for a single FMU a name is
the variable's own, ``u``, as fmpy's, for a system ``component.variable``), ``--input-file``
(`cosim.plan.inputs`), ``--output-interval`` (fmpy's name for the communication step) and
``--fmi-type`` (the interface of an FMU that has both).  A single FMU whose DefaultExperiment gives
no stop time runs 1 s, one without a step fmpy's automatic interval (``fmpy.util.auto_interval``'s
rule, `cosim.read.single.auto_interval`).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..errors import SetupError
from ..model.fmu import FMUDescription, exchange_type
from ..model.grid import Grid
from ..model.structure import Plan, ParameterValue, SystemStructure
from ..read import ssp
from ..read.description import describe_fmus
from ..read.inputs import InputTable, read_input_table
from ..read.resources import locate_fmus
from ..read.single import auto_interval, fmu_structure, is_fmu
from .build import build_plan
from .inputs import bind_table, connector_values, with_table
from .loopcheck import check_loops
from .parameters import split_system_name
from .values import typed_values

ALGORITHMS = ("jacobi", "gauss-seidel")
#: --fmi-type values (fmpy's) and the SSP Component implementation each chooses
FMI_TYPES = {"CoSimulation": "CoSimulation", "ModelExchange": "ModelExchange"}
#: where --start values come from, in messages and the run metadata's parameter origins
START_SOURCE = "--start-value"


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


@dataclass(frozen=True)
class Prepared:
    """A validated plan on a resolved grid: what `cosim.run.simulation.run` executes.  ``owner``:
    the scenario whose extraction folder the plan's FMUs are run from, closed with this (None:
    the caller keeps it, as a sweep does for all its runs); a pickled copy owns nothing."""
    plan: Plan
    grid: Grid
    algorithm: str
    step_source: str
    parameter_sets: tuple[str, ...] = ()     # the --param-set files, in the order applied
    owner: Scenario | None = field(default=None, compare=False, repr=False)

    def close(self) -> None:
        """Remove the extraction folder of an .ssp archive this run owns."""
        if self.owner is not None:
            self.owner.close()

    def __enter__(self) -> Prepared:
        """``with prepare(...) as prepared:`` the caller owns the extracted archive until the block ends."""
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __getstate__(self) -> dict:
        """Pickled without its owner: a copy in another process (a sweep's worker) reads the
        archive's files where the process that extracted them keeps them, and never removes them."""
        return {**self.__dict__, "owner": None}

    def __setstate__(self, state: dict) -> None:
        for name, value in state.items():
            object.__setattr__(self, name, value)


def check_fmi_type(path: str | Path, fmi_type: str | None) -> None:
    """Refuse an unknown ``--fmi-type``, and one given for a system (its SSD chooses)."""
    if fmi_type is None:
        return
    if fmi_type not in FMI_TYPES:
        raise SetupError(f"unknown FMI type '{fmi_type}'; choose {' or '.join(FMI_TYPES)}.", element="--fmi-type")
    if not is_fmu(path):
        raise SetupError("--fmi-type chooses the interface of a single FMU; in a system each ssd:Component's "
                         "implementation attribute does.", file=str(path), element="--fmi-type")


def check_interval(output_interval: float | None, step_size: float | None) -> None:
    """Refuse ``--output-interval`` and ``--step`` both given and different (fmpy's name and ours)."""
    if output_interval is not None and step_size is not None and output_interval != step_size:
        raise SetupError(f"--output-interval {output_interval:g} and --step {step_size:g} differ; both are the "
                         "communication step, at which results are recorded: give one.", element="--output-interval")


def load_scenario(path: str | Path, *, fmi_type: str | None = None, parameter_sets: Sequence[str | Path] = (),
                  fmu_dirs: Sequence[str | Path] = (), input_file: str | Path | None = None,
                  use_providers: bool = True) -> Scenario:
    """Read a system (or build one from an FMU), locate its FMUs, read ``parameter_sets`` and
    the ``input_file`` table; nothing is checked against the FMUs yet (`prepare_scenario`)."""
    check_fmi_type(path, fmi_type)
    single = is_fmu(path)
    if single:
        structure = fmu_structure(path, FMI_TYPES[fmi_type] if fmi_type else "any")
        fmu_paths = {name: Path(path) for name in structure.components}
    else:
        structure = ssp.load(path)
    try:
        if not single:
            fmu_paths = locate_fmus(structure, [Path(d) for d in fmu_dirs], use_providers=use_providers)
            ssp.read_component_bindings(structure, fmu_paths)
        values = [p for ps in parameter_sets for p in ssp.read_ssv(ps)]
        table = read_input_table(input_file) if input_file is not None else None
    except BaseException:
        structure.close()
        raise
    return Scenario(structure, fmu_paths, single, values, tuple(str(p) for p in parameter_sets), table)


def prepare(path: str | Path, *, start_values: Sequence[str] = (), input_file: str | Path | None = None,
            fmi_type: str | None = None, output_interval: float | None = None, start_time: float | None = None,
            stop_time: float | None = None, step_size: float | None = None, algorithm: str | None = None,
            parameter_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
            use_providers: bool = True, loops: str = "iterate", grid_placeholders: bool = False) -> Prepared:
    """Read and check everything a run needs (`load_scenario`, then `prepare_scenario`); nothing
    is instantiated.  The `Prepared` owns the scenario (close it, or use it in a ``with`` block)."""
    check_fmi_type(path, fmi_type)
    check_interval(output_interval, step_size)
    scenario = load_scenario(path, fmi_type=fmi_type, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs,
                             input_file=input_file, use_providers=use_providers)
    try:
        prepared = prepare_scenario(scenario, start_values=start_values, output_interval=output_interval,
                                    start_time=start_time, stop_time=stop_time, step_size=step_size,
                                    algorithm=algorithm, loops=loops, grid_placeholders=grid_placeholders)
    except BaseException:
        scenario.close()
        raise
    return replace(prepared, owner=scenario)


def prepare_scenario(scenario: Scenario, *, parameter_sets: Sequence[str | Path] = (),
                     start_values: Sequence[str] = (), output_interval: float | None = None,
                     start_time: float | None = None, stop_time: float | None = None,
                     step_size: float | None = None, algorithm: str | None = None,
                     loops: str = "iterate", grid_placeholders: bool = False) -> Prepared:
    """The run of a loaded scenario (`load_scenario`): its plan built once against the FMUs with
    the scenario's parameter sets, then ``parameter_sets`` (applied after them), the input table's
    connector values and ``start_values``, on the grid resolved.  The scenario stays the
    caller's.  ``grid_placeholders`` (``cosim validate``, ``info``, ``pack``, which check the SSD but
    run nothing): a stop time and step size the SSD does not give are placeholders, a stop 1 s after
    the start and a step of 1 s.  (`prepare` refuses an ``output_interval`` and ``step_size`` that
    differ before anything is read.)"""
    structure, single, table = scenario.structure, scenario.single, scenario.table
    extra = scenario.values + [p for ps in parameter_sets for p in ssp.read_ssv(ps)]
    if table is not None and not single:
        extra += connector_values(table, structure)
    fmus = describe_fmus(structure, scenario.fmu_paths)
    component = next(iter(structure.components)) if single else None
    extra += [start_value(text, structure, fmus, component) for text in start_values]
    plan = build_plan(structure, fmus, extra, loops)
    if table is not None:
        plan = with_table(plan, bind_table(table, plan, component))
    step, source = (step_size, "command line") if step_size is not None else \
        (output_interval, "--output-interval") if output_interval is not None else (None, None)
    given = (("start time", "--start", start_time), ("stop time", "--stop", stop_time),
             ("step size", "--step" if step_size is not None else "--output-interval", step))
    options = {what: option for what, option, value in given if value is not None}  # what a refusal blames
    experiment = plan.experiment
    if single:
        stop_time, step, source = _fmu_defaults(plan, start_time, stop_time, step, source)
    elif grid_placeholders:  # nobody gave them: nothing to blame
        if stop_time is None and experiment.stop_time is None:
            stop_time = (experiment.start_time or 0.0) + 1.0
        if step is None and experiment.step_size is None:
            step = 1.0
    prepared = resolve_grid(plan, start_time=start_time, stop_time=stop_time, step_size=step,
                            algorithm=algorithm, options=options)
    if not grid_placeholders or single:  # validate checks a system's loops on the SSD's own step only
        check_loops(prepared.plan, prepared.grid)  # cosim.plan.loopcheck: sampling and wiring the FMUs declare
    return replace(prepared, step_source=source or prepared.step_source,
                   parameter_sets=scenario.parameter_sets + tuple(str(p) for p in parameter_sets))


def resolve_grid(plan: Plan, *, start_time: float | None = None, stop_time: float | None = None,
                 step_size: float | None = None, algorithm: str | None = None,
                 options: Mapping[str, str] | None = None) -> Prepared:
    """The time grid and algorithm of a run: the arguments given, else the SSD's default
    experiment and annotations (`cosim.model.structure.Experiment`); a missing stop time or step
    size, or an unknown algorithm, is refused.  ``options``: the command-line option each
    given argument came from, which a refused value is blamed on ("start time", "stop time",
    "step size" -> e.g. "--stop"; default: --start, --stop and --step for those given)."""
    experiment, file = plan.experiment, plan.files.display
    start = start_time if start_time is not None else (experiment.start_time or 0.0)
    stop = stop_time if stop_time is not None else experiment.stop_time
    if stop is None:
        raise SetupError("no stop time: the SSD has no ssd:DefaultExperiment stopTime; pass --stop.", file=file)
    if step_size is not None:
        step, source = step_size, "command line"
    elif experiment.step_size is not None:
        step, source = experiment.step_size, experiment.step_size_source
    else:
        raise SetupError(
            "no step size: pass --step, or add one to ssd:DefaultExperiment/ssd:Annotations — ours "
            f"(<ssc:Annotation type=\"{ssp.GREYFMU_ANNOTATION}\"><greyfmu:Simulation "
            f"xmlns:greyfmu=\"{ssp.GREYFMU_NS}\" stepSize=\"0.1\"/></ssc:Annotation>), OSP's "
            "osp:FixedStepAlgorithm baseStepSize or OpenModelica's oms:FixedStepMaster stepSize.",
            file=file, element="ssd:DefaultExperiment")
    algo = algorithm or experiment.algorithm or "jacobi"
    if algo not in ALGORITHMS:
        raise SetupError(f"unknown algorithm '{algo}'; choose one of {', '.join(ALGORITHMS)}.", file=file)
    try:
        grid = Grid(start, stop, step)
    except SetupError as e:  # name the option or the SSD element the offending time came from
        values = {"start time": start_time, "stop time": stop_time, "step size": step_size}
        if options is None:
            options = {"start time": "--start", "stop time": "--stop", "step size": "--step"}
        if e.element in options and values.get(e.element) is not None:
            raise SetupError(e.detail, element=f"{options[e.element]} {values[e.element]:g}", hint=e.hint) from None
        element = {"stop time": "ssd:DefaultExperiment stopTime",
                   "start time": "ssd:DefaultExperiment startTime"}.get(e.element, e.element)
        raise SetupError(e.detail, file=file, element=element, hint=e.hint) from None
    return Prepared(plan, grid, algo, source)


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


def start_value(text: str, structure: SystemStructure, fmus: Mapping[str, FMUDescription],
                single: str | None) -> ParameterValue:
    """``NAME=VALUE`` as a parameter value of the variable's type, named ``component.variable``
    (typed by the FMUs' descriptions, before the plan is built); the plan's checks (causality,
    range, unit) are `cosim.plan.build.build_plan`'s for parameter sets."""
    name, sep, raw = text.partition("=")
    name = name.strip()
    if not sep or not name or not raw.strip():
        raise SetupError(f"'{text}' is not NAME=VALUE (e.g. " + ("k=2" if single else "controller.Kc=2") + ").",
                         element=START_SOURCE)
    if single is not None:
        desc = fmus[single]
        var_name = name if name in desc.variables or not name.startswith(single + ".") else name[len(single) + 1:]
        var = desc.variable(var_name, f"component '{single}'", f"{START_SOURCE} {text}")
        full = f"{single}.{var_name}"
    elif name in structure.open_connectors or (name in structure.system_outputs
                                               and structure.system_outputs[name].component is None):
        # a value for an undriven system connector (an undriven root output: its recorded constant)
        return ParameterValue(name, "Real", typed_values(raw.strip(), "Real", name, START_SOURCE)[0], START_SOURCE, 0)
    else:
        comp, var_name = split_system_name(structure.components, ParameterValue(name, "Real", 0.0, START_SOURCE, 0))
        var = fmus[comp].variable(var_name, f"component '{comp}'", f"{START_SOURCE} {text}")
        full = name
    kind = exchange_type(var) or var.type
    values = typed_values(raw.strip(), kind, name, START_SOURCE)
    if len(values) != 1:
        raise SetupError(f"'{raw.strip()}' is {len(values)} values; a start value is one.", element=START_SOURCE,
                         variable=name)
    return ParameterValue(full, kind, values[0], START_SOURCE, 0)
