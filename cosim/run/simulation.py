"""The run as a user asks for it: read, locate, validate, then execute and record.

`prepare` does everything that can fail before an FMU is instantiated: `validate`
(read, locate the FMUs, build the `cosim.model.structure.Plan`) and `resolve_grid` (the
time grid and algorithm from the arguments and the SSD); `simulate` runs a prepared
system and returns the samples as a NumPy structured array (like ``fmpy.simulate_fmu``),
writing them to a CSV as it goes if asked.
"""
from __future__ import annotations

import fnmatch
import functools
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..read import ssp
from ..model.fmu import unit_of
from ..errors import ComponentLost, CosimError, OutOfMemory, OutputError, RunError, SetupError, did_you_mean
from .execution import ALGORITHMS, Execution, Grid
from .instances import Unzipped
from .instances.isolated import Isolation
from .instances.reuse import InstancePool
from .interrupts import StopRequest
from ..record.journal import RunJournal
from ..record.observers import DerivedColumns, MemorySink, Recorder, SystemOutputColumns, file_sink
from .outcome import RunOutcome
from ..plan.build import build_plan
from ..plan.loopcheck import check_loops
from ..read.resources import locate_fmus
from ..safeio import lock_output
from .loops import LoopSettings
from ..model.structure import LoopMode, Plan


@dataclass(frozen=True)
class Prepared:
    """A validated plan on a resolved grid: what `run` executes."""
    plan: Plan
    grid: Grid
    algorithm: str
    step_source: str
    parameter_sets: tuple[str, ...] = ()     # the --param-set files, in the order applied

    def close(self) -> None:
        """Remove the extraction folder of an .ssp archive the plan owns (`Plan.close`)."""
        self.plan.close()

    def __enter__(self) -> Prepared:
        """``with prepare(...) as prepared:`` the caller owns the extracted archive until the block ends."""
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def validate(path: str | Path, *, parameter_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
             use_providers: bool = True, loops: LoopMode = "iterate") -> Plan:
    """Read, locate and check a system against its FMUs (`cosim.plan.build.build_plan`; ``loops``:
    how algebraic loops are run, `cosim.run.loops`); nothing is instantiated.  The plan owns an
    extracted archive until it is closed."""
    structure = ssp.load(path)
    try:
        extra = [p for ps in parameter_sets for p in ssp.read_ssv(ps)]
        fmu_paths = locate_fmus(structure, [Path(d) for d in fmu_dirs], use_providers=use_providers)
        ssp.read_component_bindings(structure, fmu_paths)
        return build_plan(structure, fmu_paths, extra, loops)
    except BaseException:
        structure.close()
        raise


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


def prepare(path: str | Path, *, start_time: float | None = None, stop_time: float | None = None,
            step_size: float | None = None, algorithm: str | None = None,
            parameter_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
            use_providers: bool = True, loops: LoopMode = "iterate") -> Prepared:
    """`validate`, then `resolve_grid`; nothing is instantiated."""
    plan = validate(path, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs, use_providers=use_providers,
                    loops=loops)
    try:
        prepared = resolve_grid(plan, start_time=start_time, stop_time=stop_time, step_size=step_size,
                                algorithm=algorithm)
        check_loops(prepared.plan, prepared.grid)  # cosim.plan.loopcheck, as prepare_scenario does
        return replace(prepared, parameter_sets=tuple(str(p) for p in parameter_sets))
    except BaseException:
        plan.close()
        raise


def simulate(path: str | Path, *, start_time: float | None = None, stop_time: float | None = None,
             step_size: float | None = None, algorithm: str | None = None,
             parameter_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
             output: str | Path | None = None, progress: bool = False,
             use_providers: bool = True, fmu_log: str = "errors", loops: LoopMode = "iterate",
             loop_settings: LoopSettings | None = None, isolate: bool = False,
             call_timeout: float | None = None, kernel: str = "auto", threads: int = 1) -> np.ndarray:
    """Run an SSP system and return every connector at every communication point.

    The result is a structured array with a ``time`` field and one field per
    connector named ``component.variable`` (in a nested system the component is
    its path relative to the root system, ``loop.controller.u``), plus one per
    output connector of the root system, under its own name.  With ``output`` the samples are
    also written to that CSV (or Parquet file, by its suffix) as the run goes
    (metadata in ``<output>.json``): to ``<output>.part``, renamed onto ``output`` when the run
    ends, and under ``<output>.lock`` (`cosim.safeio.lock_output`), so another process writing
    the same output meanwhile is a `SetupError` naming it.
    A failed run raises `RunError` with the samples so far in ``error.result`` (its
    ``run_outcome``, `cosim.run.outcome.RunOutcome`; and on disk when ``output`` is given).  ``fmu_log``: which FMU log messages are
    collected to explain a failure ("errors", "all" or "off"; see `cosim.run.instances.fmi2.FMI2Instance.instantiate`).
    ``loops``: algebraic loops solved by iteration ("iterate", with ``loop_settings``) or broken
    by one step of delay ("delay", with a warning), see `cosim.run.loops`.
    ``isolate``: each FMU in a process of its own (`cosim.run.instances.isolated`), so a crashing
    FMU raises `cosim.errors.ComponentLost` naming it; ``call_timeout`` (needs ``isolate``):
    seconds an FMU call may take before its process is killed.
    ``kernel`` and ``threads``: which stepping loop runs, see `run`.
    """
    isolation_of(isolate, call_timeout)  # refused before anything is read
    prepared = prepare(path, start_time=start_time, stop_time=stop_time, step_size=step_size,
                       algorithm=algorithm, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs,
                       use_providers=use_providers, loops=loops)
    with prepared, lock_output(output, option="output") if output is not None else nullcontext():
        outcome = run(prepared, output=output, progress=progress, fmu_log=fmu_log,
                      loop_settings=loop_settings, isolate=isolate,
                      call_timeout=call_timeout, kernel=kernel, threads=threads)
    if outcome.status == "discarded":
        warnings.warn(outcome.message, RuntimeWarning, stacklevel=2)
    return outcome.result


def run(prepared: Prepared, *, output: str | Path | None = None, progress: bool = False,
        fmu_log: str = "errors", keep: Sequence[str] | None = None,
        loop_settings: LoopSettings | None = None, stop: StopRequest | None = None,
        journal: bool = True, isolate: bool = False, call_timeout: float | None = None,
        kernel: str = "auto", threads: int = 1, pool: InstancePool | None = None) -> RunOutcome:
    """Execute a prepared system; returns its `cosim.run.outcome.RunOutcome` (status, message, error
    code, the samples, the result file, the metadata; it unpacks as ``result, metadata``).  A run
    that fails raises, the error's ``run_outcome`` holding what was recorded up to the failure.

    ``output``: a result file written as the run goes, Parquet for a ``.parquet`` suffix, else
    CSV (`cosim.record.observers.file_sink`), with every row also in its journal
    (`cosim.record.journal`) until the run ends, so a crash of the process loses none (unless
    ``journal`` is False).  ``keep``: the
    signals the returned array holds besides ``time`` (None: all); a long run streamed to
    ``output`` keeps only what it needs in memory.  ``stop``: set by a signal
    (`cosim.run.interrupts.stop_on_signals`), ends the run at the next communication point.
    ``isolate``: components in processes of their own (`cosim.run.instances.isolated`); a
    component whose process crashed or whose call took more than ``call_timeout`` seconds ends
    the run with status "crashed" or "timeout" (`cosim.errors.ComponentLost`), the rows so far
    written.
    ``kernel``: the stepping loop, "auto" (the compiled one of `cosim.kernel` where it can
    run, else the Python one, the metadata's ``kernel_reason`` saying why), "native" (refused
    with a `SetupError` naming why where it cannot) or "python"; ``threads``: the doSteps of a
    Jacobi step on that many threads of the compiled kernel (`cosim.kernel`), results bit-identical.
    ``pool``: instances kept across runs (`cosim.run.instances.reuse`): the run takes its instances
    from it where it has them and gives them back, reset, when it completes.
    """
    isolation = isolation_of(isolate, call_timeout)
    plan = prepared.plan
    memory = MemorySink(keep)
    derived = DerivedColumns.of(list(plan.system_outputs.values()), ["time"] + plan.columns)
    observers = [SystemOutputColumns(derived, [memory] + ([file_sink(output)] if output is not None else []))]
    execution = Execution(plan, prepared.grid, prepared.algorithm, fmu_log, loop_settings, isolation,
                          kernel, threads, pool)
    recorder = None
    bar = None
    try:
        execution.instantiate()
        names, arrays = execution.recorder_sources()
        journaled = output is not None and journal
        recorder = Recorder(names, arrays, plan.columns, observers,
                            journal=_journal(output, plan, derived, _metadata(prepared, execution)) if journaled else None)
        execution.initialize()
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=prepared.grid.steps, delay=1.0, unit="step", leave=False,
                       desc=plan.name or "cosim")
        execution.run(recorder, bar, stop)
    except BaseException as e:
        error = _failed(e, prepared, execution, recorder, memory, output)
        if error is e:
            raise
        raise error from None
    finally:
        if bar is not None:
            bar.close()
        execution.close()
    metadata = _metadata(prepared, execution)
    recorder.close(metadata)
    return RunOutcome.of(metadata, memory.array(), output)


def _failed(e: BaseException, prepared: Prepared, execution: Execution, recorder: Recorder | None,
            memory: MemorySink, output: str | Path | None) -> BaseException:
    """The error a run that raised ``e`` ends with (`_out_of_memory`), its `RunOutcome` in its
    ``run_outcome``: the metadata with status "failed" (or the `ComponentLost` outcome), the
    error's code and message, written by the observers with every row recorded before."""
    error = _out_of_memory(e, output, execution, recorder, memory)
    metadata = _metadata(prepared, execution)
    metadata.update(status=error.outcome if isinstance(error, ComponentLost) else "failed",
                    message=(str(error) if isinstance(error, (RunError, OutputError))
                             else f"{type(error).__name__}: {error}"),
                    error=error.code.value if isinstance(error, CosimError) else None)
    if recorder is not None:
        try:
            recorder.close(metadata)
        except (OutputError, MemoryError) as closing:  # the disk is full: said after what ended the run
            if not isinstance(error, OutputError):
                raise
            detail = closing.detail if isinstance(closing, OutputError) else "out of memory"
            error = error.extended(f" The metadata JSON could not be written either ({detail})")
    try:
        result = memory.array() if recorder is not None else None
    except MemoryError:  # no memory left to join the samples: they are in the result file, if any
        result = None
    error.run_outcome = RunOutcome.of(metadata, result, output)
    return error


def _out_of_memory(e: BaseException, output: str | Path | None, execution: Execution, recorder: Recorder | None,
                   memory: MemorySink) -> BaseException:
    """The error a run ends with: ``e``, or when the process ran out of memory (a `MemoryError`,
    or a journal mapping refused, `OutOfMemory`: the address space exhausted, ``ulimit -v``) an
    `OutOfMemory` naming the result file.  With a result file, the samples kept in memory are
    dropped first (the file has them; the error's ``result`` is then empty), so that closing
    the results has memory to work with."""
    if not isinstance(e, (MemoryError, OutOfMemory)):
        return e
    if output is not None:
        memory.chunks.clear()
    rows = recorder.samples if recorder is not None else 0
    return OutOfMemory(f"the process ran out of memory (its address space: see ulimit -v) at t = "
                       f"{execution.last_time:g}; the {rows} rows recorded before are kept"
                       + ("." if output is not None else " in the error's result, if memory allows."),
                       file=str(output) if output is not None else None)


def isolation_of(isolate: bool, call_timeout: float | None) -> Isolation | None:
    """The `Isolation` of ``--isolate`` and ``--call-timeout`` (which needs it), or None."""
    if call_timeout is not None and not isolate:
        raise SetupError("it needs --isolate (isolate=True): only an FMU call in a process of "
                         "its own can be stopped.", element="--call-timeout")
    return Isolation(call_timeout) if isolate else None


def _journal(output: str | Path, plan: Plan, derived: DerivedColumns, metadata: dict) -> RunJournal:
    """The journal of a run writing ``output`` (`cosim.record.journal.RunJournal`): its header holds what
    `cosim.record.journal.recover` needs to write the result files without the plan."""
    return RunJournal(output, ["time"] + plan.columns, derived, metadata,
                      temporary=[Unzipped.folder()] if Unzipped.folder() else [])


def _portable(path: str | Path, *bases: Path) -> str:
    """``path`` relative to the first of ``bases`` holding it, else its file name alone: no
    absolute path of the machine that ran it in the metadata (nor in the report made from it)."""
    return _portable_in(str(path), tuple(str(b) for b in bases), os.getcwd())


@functools.lru_cache(maxsize=4096)
def _portable_in(path: str, bases: tuple[str, ...], cwd: str) -> str:
    """`_portable` for the working folder ``cwd``, remembered: a sweep worker's runs name the same
    files (a run's metadata names some 25; resolving each was a tenth of a short run's fixed cost)."""
    resolved = Path(cwd, path).resolve()
    for base in bases:
        root = Path(cwd, base).resolve()
        if resolved.is_relative_to(root):
            return resolved.relative_to(root).as_posix()
    return resolved.name


def _portable_origin(origin: str, bases: Sequence[Path]) -> str:
    """A parameter's origin ``FILE:LINE[, mapped by ...]`` with FILE made `_portable`."""
    where, comma, rest = origin.partition(", ")
    file, colon, line = where.rpartition(":")
    if not colon or not line.isdigit() or not file:
        return origin
    return f"{_portable(file, *bases)}:{line}{comma}{rest}"


def _metadata(prepared: Prepared, execution: Execution) -> dict:
    meta = execution.metadata()
    plan = prepared.plan
    scenario = Path(plan.files.source).parent
    # the system and parameter sets relative to the working folder (as the user named them), the
    # FMUs to the scenario that ships them or the working folder (a provider's build/fmus)
    named = (Path.cwd(), scenario.parent)
    meta["system"] = _portable(plan.files.source, *named)
    meta["scenario"] = plan.name
    # result names are paths relative to this system (loop.ctrl.u for component ctrl of subsystem loop)
    meta["root_system"] = plan.system_name
    if plan.system_outputs:
        meta["system_outputs"] = {o.name: f"{o.factor:.17g} * {o.component}.{o.connector} + {o.offset:.17g}"
                                  if o.component is not None else "undriven"
                                  for o in plan.system_outputs.values()}
        undriven = {o.name: {"line": o.line, "value": None if math.isnan(o.offset) else o.offset,
                             "origin": _portable_origin(o.origin, named) if o.origin else None}
                    for o in plan.system_outputs.values() if o.component is None}
        if undriven:  # root output connectors no component drives: a constant column (value None: NaN)
            meta["undriven_system_outputs"] = undriven
    meta["isolation"] = execution.isolation.metadata() if execution.isolation is not None else None
    meta["step_size_source"] = prepared.step_source
    meta["units"] = plan.units
    meta["parameter_sets"] = [_portable(p, *named) for p in prepared.parameter_sets]
    for component in meta.get("components", {}).values():
        component["fmu"] = _portable(component["fmu"], scenario, Path.cwd())
    meta["parameter_origins"] = {f"{sv.component}.{sv.variable.name}": _portable_origin(sv.origin, named)
                                 for sv in plan.start_values}
    meta.update(signal_info(plan))
    return meta


def signal_info(plan: Plan) -> dict:
    """What a plot or report needs to label a result: each recorded connector's description
    (from its FMU) and the connections (``src.var -> dst.var``, with a factor/offset if any)."""
    variables = {f"{c}.{v.name}": v for c in plan.outputs for v in plan.outputs[c] + plan.inputs[c]}
    connections = [f"{r.src}.{r.src_var.name} -> {r.dst}.{r.dst_var.name}"
                   + (f" (x{r.factor:g} {r.offset:+g})" if (r.factor, r.offset) != (1.0, 0.0) else "")
                   for r in plan.routes]
    return {"descriptions": {n: v.description for n, v in variables.items() if v.description},
            "connections": connections,
            # sampled outputs (FMI variability discrete): held between samples, drawn as steps
            "discrete": sorted(n for n, v in variables.items() if v.variability == "discrete"),
            "parameter_descriptions": {f"{sv.component}.{sv.variable.name}": sv.variable.description
                                       for sv in plan.start_values if sv.variable.description},
            "parameter_units": {f"{sv.component}.{sv.variable.name}": unit_of(sv.variable)
                                for sv in plan.start_values if unit_of(sv.variable)}}


def signal_units(plan: Plan) -> dict[str, tuple[str, bool]]:
    """Each recorded signal's unit and whether it is "as wired" (`cosim.present.plots.units`)."""
    from ..present.plots import units

    return units({"units": plan.units, "connections": signal_info(plan)["connections"],
                  "components": {name: {"fmu": str(d.path)} for name, d in plan.fmus.items()}})


def select(names: Sequence[str], patterns: Sequence[str], option: str = "--signals") -> list[str]:
    """Names matching any glob pattern, in the order of ``names``; an unmatched pattern is an error
    naming the ``option`` it was given with."""
    chosen = []
    for pattern in patterns:
        matched = [n for n in names if fnmatch.fnmatchcase(n, pattern)]
        if not matched:
            raise SetupError(f"no signal matches '{pattern}'.", element=option,
                             hint=did_you_mean(pattern, names) or f"Signals: {', '.join(names[:12])}.")
        chosen += [n for n in matched if n not in chosen]
    return chosen
