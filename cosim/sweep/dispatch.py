"""Running a sweep's runs: one run in a worker (`execute`), and the local engines that hand
the runs out: serially in this process, a local process pool (``spawn``: FMUs loaded in the
parent are never forked) or any `concurrent.futures.Executor` (a Dask cluster: `.cluster`)."""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CosimError, Errc, SetupError
from ..present.metrics import METRICS, step_response
from ..safeio import unpack_limit
from ..plan.prepare import Prepared, prepare
from ..run.simulation import run
from .values import Metric
from .worker import kept_for, prepare_task, release


@dataclass(frozen=True)
class Task:
    """One run as a worker process receives it (plain data, picklable)."""
    run_id: str
    scenario: str
    parameter_sets: tuple[str, ...]
    fmu_dirs: tuple[str, ...]
    start: float
    stop: float
    step: float
    algorithm: str
    csv: str
    metrics: tuple[Metric, ...]
    #: the parent's limit on what an .ssp archive may expand to (--max-unpacked), in bytes
    max_unpacked: int
    #: ``--start-value`` texts (``component.variable=value``), applied after the parameter sets
    start_values: tuple[str, ...] = ()
    #: the ``--input-file`` table (`cosim.plan.inputs`), or None
    input_file: str | None = None
    #: how many of ``parameter_sets`` (the first) every run of the sweep shares; the others are the run's own
    shared_sets: int = 0
    #: the digest of the sweep's identity (`cosim.sweep.values.identity_of`): what a worker keeps
    #: across runs is kept under it (`cosim.sweep.worker`); "" keeps nothing
    sweep_key: str = ""
    #: the worker keeps the scenario and the instances across runs (`cosim.sweep.worker`); False:
    #: every run read, checked and instantiated afresh
    reuse: bool = True
    #: write the run's result file (``csv``) and its metadata JSON; False: the table row only
    run_files: bool = True
    #: the run's plan, prepared by the sweep in its process (`cosim.sweep.sweep`) and pickled with
    #: the task: the worker runs it as is, on its kept instances (None: the worker prepares the run
    #: from the files the task names, `cosim.sweep.worker.prepare_task`)
    prepared: Prepared | None = None
    #: called in the worker on the run's result (None for a failed run): the columns it returns
    #: join the row (`cosim.tune` measures its objective and constraints there); picklable
    measure: Callable[[np.ndarray | None], dict[str, Any]] | None = None


# --------------------------------------------------------------------------- one run (in a worker)

def execute(task: Task) -> dict[str, Any]:
    """Run one combination (in a worker process) and return its table row (without the swept values)."""
    began = time.perf_counter()
    row: dict[str, Any] = {"run_id": task.run_id, "status": "completed", "message": None, "error": None}
    result = None
    output = task.csv if task.run_files else None
    try:
        with unpack_limit(task.max_unpacked):  # the FMUs are unpacked by run(): inside the limit too
            if task.reuse and task.sweep_key:
                kept = kept_for(task)
                prepared = task.prepared if task.prepared is not None else prepare_task(task, kept)
                outcome = run(prepared, output=output, pool=kept.pool)
            else:
                with prepare(task.scenario, start_time=task.start, stop_time=task.stop,
                             step_size=task.step, algorithm=task.algorithm,
                             parameter_sets=task.parameter_sets, fmu_dirs=task.fmu_dirs,
                             start_values=task.start_values, input_file=task.input_file) as prepared:
                    outcome = run(prepared, output=output)
        result = outcome.result
        if outcome.status == "discarded":
            row.update(status="discarded", message=outcome.message)
    except CosimError as e:
        row.update(status="failed", message=str(e), error=e.code.value)
    row["wall_time"] = time.perf_counter() - began
    row.update(run_metrics(result, task.metrics))
    if task.measure is not None:
        row.update(task.measure(None if row["status"] == "failed" else result))
    return row


def run_metrics(result: np.ndarray | None, metrics: Sequence[Metric]) -> dict[str, float | str | None]:
    out: dict[str, float | str | None] = {}
    for m in metrics:
        response = (step_response(result["time"], result[m.signal], result[m.setpoint])
                    if result is not None and len(result) else None)
        values = response.values if response is not None else {}
        out.update({f"{m.signal}:{k}": float(values[k]) if k in values else None for k in METRICS})
        out[m.reason_column()] = response.reasons() if response is not None else "the run produced no samples"
    return out


# --------------------------------------------------------------------------- engines

Executor = str | cf.Executor | Any   # "process", "serial", a Dask scheduler address, "local:N", or a Client


def dispatch(tasks: list[Task], executor: Executor, workers: int | None,
              done: Callable[[Task, dict[str, Any]], None]) -> None:
    """Hand the runs to the chosen engine; ``done`` is called in this process as each finishes."""
    if not tasks:
        return
    if executor == "serial":
        try:
            run_serially(tasks, done)
        finally:   # this process is the caller's: nothing of the sweep is kept after it
            release()
    elif executor == "process":
        with ProcessPool(workers or os.cpu_count() or 1) as pool:
            _pool_sweep(tasks, pool, done)
    elif isinstance(executor, ProcessPool):
        _pool_sweep(tasks, executor, done)
    elif isinstance(executor, cf.Executor):
        _collect(tasks, executor, done)
    else:
        raise SetupError(f"unknown executor {executor!r}: give 'process', 'serial', a Dask scheduler "
                         "address, 'local:N', a concurrent.futures.Executor or a distributed.Client.")


def run_serially(tasks: list[Task], done: Callable[[Task, dict[str, Any]], None]) -> None:
    """The runs one after the other in this process, which keeps their scenario and instances
    (`cosim.sweep.worker`) until `release`."""
    for task in tasks:
        try:
            row = execute(task)
        except Exception as e:  # noqa: BLE001 -- as in a worker: a failed row, not a stopped sweep
            row = failed_row(task, e)
        done(task, row)


def is_cluster(executor: Executor) -> bool:
    """Whether the runs go to Dask (an address, ``local:N`` or a Client) rather than a local engine."""
    if isinstance(executor, str):
        return executor not in ("process", "serial")
    if isinstance(executor, (cf.Executor, ProcessPool)):
        return False
    return isinstance(executor, distributed().Client)


def distributed():
    """Dask's distributed scheduler, an optional dependency (``pip install 'greyfmu[dask]'``)."""
    try:
        import distributed
    except ImportError:
        raise SetupError("sweeps on a Dask cluster need Dask, which is not installed; install it with "
                         "pip install 'greyfmu[dask]' (or run on the local process pool: --workers N).",
                         element="--scheduler") from None
    return distributed


def _collect(tasks: list[Task], engine: cf.Executor, done) -> None:
    """Submit every run; a worker that dies or raises makes that run a failed row, not a stopped sweep."""
    futures = {engine.submit(execute, task): task for task in tasks}
    for future in cf.as_completed(list(futures)):
        task = futures[future]
        try:
            row = future.result()
        except BrokenProcessPool as e:  # a worker of the executor died
            row = failed_row(task, e, Errc.worker_lost)
        except Exception as e:  # noqa: BLE001 -- a run that raised
            row = failed_row(task, e)
        done(task, row)


class ProcessPool:
    """A local pool of ``workers`` spawned processes (``spawn``: FMUs loaded in the parent are
    never forked), kept from one `dispatch` to the next (a tuning's batches: each worker keeps
    its scenario and instances, `cosim.sweep.worker`) until `close`; a pool broken by a dying
    process is replaced by a fresh one at the next use."""

    def __init__(self, workers: int):
        self.workers = workers
        self._executor: cf.ProcessPoolExecutor | None = None

    def executor(self) -> cf.ProcessPoolExecutor:
        if self._executor is None:
            self._executor = cf.ProcessPoolExecutor(max_workers=self.workers,
                                                    mp_context=multiprocessing.get_context("spawn"),
                                                    initializer=_ignore_interrupt)
        return self._executor

    def close(self, kill: bool = False) -> None:
        """Shut the processes down (``kill``: terminate them first, for Ctrl-C or a broken pool)."""
        executor, self._executor = self._executor, None
        if executor is None:
            return
        if kill:
            for process in list((executor._processes or {}).values()):   # no public way to kill them
                process.terminate()
        executor.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> ProcessPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _pool_sweep(tasks: list[Task], pool: ProcessPool, done: Callable[[Task, dict[str, Any]], None]) -> None:
    """The runs on a local pool of spawned processes.

    A process that dies (an FMU calling abort(), a segfault) breaks the whole pool, and every
    unfinished run raises ``BrokenProcessPool``: the runs that had started then (each worker
    marks the run it is in with a file) are each rerun alone in a fresh process, where one
    that dies again is a failed row; the runs not started yet go to a fresh pool.
    """
    remaining = tasks
    while remaining:
        broken, started = _pool_round(remaining, pool, done)
        if broken and not started:      # the processes died outside any run: no progress to make
            for task in broken:
                done(task, failed_row(task, BrokenProcessPool("the pool's worker processes died before "
                                                              "starting this run"), Errc.worker_lost))
            return
        for task in started:
            with ProcessPool(1) as alone_pool:
                _, alone = _pool_round([task], alone_pool, done)
            if alone:
                done(task, failed_row(task, BrokenProcessPool(
                    "the worker process died during this run, and again when it was rerun alone "
                    "in a fresh process (an FMU that aborts or crashes?)"), Errc.worker_lost))
        remaining = [t for t in broken if t not in started]


def _pool_round(tasks: list[Task], pool: ProcessPool, done) -> tuple[list[Task], list[Task]]:
    """``tasks`` on ``pool``: the runs a dying process left unfinished, and those of them that had
    started (the broken pool is shut down, so the next use makes a fresh one)."""
    broken: list[Task] = []
    with tempfile.TemporaryDirectory(prefix="cosim-sweep-started-") as marks:
        try:
            executor = pool.executor()
            futures = {executor.submit(_execute_marked, task, marks): task for task in tasks}
            for future in cf.as_completed(list(futures)):
                task = futures[future]
                try:
                    row = future.result()
                except BrokenProcessPool:
                    broken.append(task)
                    continue
                except Exception as e:  # noqa: BLE001 -- a run that raised: a failed row
                    row = failed_row(task, e)
                done(task, row)
        except BaseException:  # Ctrl-C: stop the runs now instead of waiting for them
            pool.close(kill=True)
            raise
        if broken:
            pool.close(kill=True)
        started = [t for t in broken if (Path(marks) / t.run_id).exists()]
    return broken, started


def _ignore_interrupt() -> None:
    """Pool processes leave Ctrl-C to the parent, which stops them (no traceback from each)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _execute_marked(task: Task, marks: str) -> dict[str, Any]:
    mark = Path(marks) / task.run_id
    mark.touch()
    row = execute(task)
    mark.unlink()
    return row


def failed_row(task: Task, error: Exception, code: Errc | None = None) -> dict[str, Any]:
    """The table row of a run whose worker raised ``error``, or died (``code`` `Errc.worker_lost`,
    given by the engine that saw it die); else the code is the error's (`Errc.unexpected` for
    one that is not a `CosimError`)."""
    if code is None:
        code = error.code if isinstance(error, CosimError) else Errc.unexpected
    return {"run_id": task.run_id, "status": "failed", "message": f"{type(error).__name__}: {error}",
            "error": code.value,
            "wall_time": None, **run_metrics(None, task.metrics)}

