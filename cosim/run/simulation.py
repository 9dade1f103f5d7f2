"""The run as a user asks for it: prepared (`cosim.plan.prepare`), then executed and recorded.

`run` executes a `cosim.plan.prepare.Prepared` run and records it (the observers, the journal, the
metadata), returning its `cosim.run.outcome.RunOutcome`; `simulate` (and `simulate_fmu`, its name
in fmpy's words) prepares and runs in one call and returns the samples as a NumPy structured array
(like ``fmpy.simulate_fmu``), writing them to a result file as it goes if asked.
"""
from __future__ import annotations

import functools
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from ..errors import ComponentLost, CosimError, OutOfMemory, OutputError, RunError, SetupError
from ..model.structure import LoopMode, Plan
from ..plan.prepare import Prepared, prepare
from ..record.journal import RunJournal
from ..record.metadata import signal_info
from ..record.observers import CsvSink, DerivedColumns, MemorySink, ParquetSink, Recorder, file_sink, rows_per_chunk
from ..safeio import lock_output
from .execution import Execution
from .program import compile as compile_program
from .instances import Unzipped
from .instances.isolated import Isolation
from .instances.reuse import InstancePool
from .interrupts import StopRequest
from .loops import LoopSettings
from .outcome import RunOutcome


def simulate(path: str | Path, *, start_time: float | None = None, stop_time: float | None = None,
             step_size: float | None = None, algorithm: str | None = None,
             parameter_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
             start_values: Mapping[str, object] | None = None, input_file: str | Path | None = None,
             output_interval: float | None = None, fmi_type: str | None = None,
             output: str | Path | None = None, progress: bool = False,
             use_providers: bool = True, fmu_log: str = "errors", loops: LoopMode = "iterate",
             loop_settings: LoopSettings | None = None, isolate: bool = False,
             call_timeout: float | None = None, kernel: str = "auto", threads: int = 1) -> np.ndarray:
    """Run an SSP system (or one FMU) and return every connector at every communication point.

    The result is a structured array with a ``time`` field and one field per
    connector named ``component.variable`` (in a nested system the component is
    its path relative to the root system, ``loop.controller.u``), plus one per
    output connector of the root system, under its own name.  ``start_values`` by name
    (``{"controller.Kc": 2}``; ``{"gain": 3}`` for one FMU: the names of ``--start-value``),
    ``input_file`` an input table (`cosim.plan.inputs`), ``output_interval`` and ``fmi_type``
    fmpy's options (`cosim.plan.prepare.prepare`).  With ``output`` the samples are
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
    texts = [f"{name}={str(value).lower() if isinstance(value, bool) else value}"
             for name, value in (start_values or {}).items()]
    prepared = prepare(path, start_time=start_time, stop_time=stop_time, step_size=step_size,
                       algorithm=algorithm, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs,
                       use_providers=use_providers, loops=loops, start_values=texts, input_file=input_file,
                       output_interval=output_interval, fmi_type=fmi_type)
    with prepared, lock_output(output, option="output") if output is not None else nullcontext():
        outcome = run(prepared, output=output, progress=progress, fmu_log=fmu_log,
                      loop_settings=loop_settings, isolate=isolate,
                      call_timeout=call_timeout, kernel=kernel, threads=threads)
    if outcome.status == "discarded":
        warnings.warn(outcome.message, RuntimeWarning, stacklevel=2)
    return outcome.result


#: ``fmpy.simulate_fmu``'s name for `simulate`: one FMU (or a system) as ``cosim run`` runs it
simulate_fmu = simulate


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
    rows = prepared.grid.steps + 1
    memory = MemorySink(keep, rows)
    recorded, outputs = _recorded(plan, keep if output is None else None)
    derived = DerivedColumns.of(outputs, ["time", *recorded])
    observers = [memory] + ([file_sink(output)] if output is not None else [])
    execution = Execution(plan, prepared.grid, prepared.algorithm, fmu_log, loop_settings, isolation,
                          kernel, threads, pool)
    program = compile_program(plan, prepared.algorithm)   # from the plan alone
    recorder = None
    bar = None
    try:
        execution.instantiate()
        names, arrays = execution.link(program).recorder_sources()
        journaled = output is not None and journal
        recorder = Recorder(names, arrays, recorded, observers, derived=derived, rows=rows,
                            journal=_journal(output, plan, derived, _metadata(prepared, execution), rows,
                                             observers[-1]) if journaled else None)
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


def _recorded(plan: Plan, keep: Sequence[str] | None) -> tuple[list[str], list]:
    """The component columns a run records and its root output connectors (`DerivedColumns`):
    all of them, or with ``keep`` (a run writing no file) those it keeps and what the root
    outputs it keeps are computed from, so a run keeping only ``time`` records only the time."""
    outputs = list(plan.system_outputs.values())
    if keep is None:
        return list(plan.columns), outputs
    outputs = [o for o in outputs if o.name in keep]
    needed = set(keep) | {o.source for o in outputs}
    return [c for c in plan.columns if c in needed], outputs


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
        memory.clear()
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


def _journal(output: str | Path, plan: Plan, derived: DerivedColumns, metadata: dict, rows: int,
             sink: CsvSink | ParquetSink) -> RunJournal:
    """The journal of a run of ``rows`` rows writing ``output`` through ``sink``
    (`cosim.record.journal.RunJournal`): its header holds what `cosim.record.journal.recover` needs
    to write the result files without the plan; its windows are chunks
    (`cosim.record.observers.rows_per_chunk`) of the run's rows, one written over and over beside
    a CSV, whose part file keeps the rows flushed."""
    return RunJournal(output, ["time", *plan.columns], derived, metadata,
                      temporary=[Unzipped.folder()] if Unzipped.folder() else [],
                      chunk_rows=rows_per_chunk(1 + len(plan.columns) + len(derived.names), rows),
                      durable=sink if isinstance(sink, CsvSink) else None)


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
        meta["system_outputs"] = {o.name: o.transform.text(o.source) if o.component is not None else "undriven"
                                  for o in plan.system_outputs.values()}
        undriven = {o.name: {"line": o.line, "value": None if math.isnan(o.transform.offset) else o.transform.offset,
                             "origin": _portable_origin(o.origin, named) if o.origin else None}
                    for o in plan.system_outputs.values() if o.component is None}
        if undriven:  # root output connectors no component drives: a constant column (value None: NaN)
            meta["undriven_system_outputs"] = undriven
    meta["isolation"] = execution.isolation.metadata() if execution.isolation is not None else None
    meta["step_size_source"] = prepared.step_source
    meta["units"] = dict(plan.units)
    meta["parameter_sets"] = [_portable(p, *named) for p in prepared.parameter_sets]
    fmu_bases = (scenario, Path.cwd())
    for component in meta.get("components", {}).values():
        component["fmu"] = _portable(component["fmu"], *fmu_bases)
    meta["parameter_origins"] = {f"{sv.component}.{sv.variable.name}": _portable_origin(sv.origin, named)
                                 for sv in plan.start_values}
    meta.update(signal_info(plan))
    return meta
