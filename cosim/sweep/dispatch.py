"""Running a sweep's runs: one run in a worker (`execute`), and the local engines that hand
the runs out: serially in this process, a local process pool (``spawn``: FMUs loaded in the
parent are never forked) or any `concurrent.futures.Executor` (a Dask cluster: `.cluster`)."""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import CosimError, SetupError
from ..metrics import METRICS, step_metrics
from ..safeio import unpack_limit
from ..simulation import prepare, run
from .values import Metric


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


# --------------------------------------------------------------------------- one run (in a worker)

def execute(task: Task) -> dict[str, Any]:
    """Run one combination (in a worker process) and return its table row (without the swept values)."""
    began = time.perf_counter()
    row: dict[str, Any] = {"run_id": task.run_id, "status": "completed", "message": None}
    result = None
    try:
        with unpack_limit(task.max_unpacked):  # the FMUs are unpacked by run(): inside the limit too
            prepared = prepare(task.scenario, start_time=task.start, stop_time=task.stop, step_size=task.step,
                               algorithm=task.algorithm, parameter_sets=task.parameter_sets,
                               fmu_dirs=task.fmu_dirs)
            try:
                result, metadata = run(prepared, output=task.csv)
            finally:
                prepared.close()
        if metadata["status"] == "discarded":
            row.update(status="discarded", message=metadata["message"])
    except CosimError as e:
        row.update(status="failed", message=str(e))
    row["wall_time"] = time.perf_counter() - began
    row.update(run_metrics(result, task.metrics))
    return row


def run_metrics(result: np.ndarray | None, metrics: Sequence[Metric]) -> dict[str, float | None]:
    out: dict[str, float | None] = {}
    for m in metrics:
        values = (step_metrics(result["time"], result[m.signal], result[m.setpoint])
                  if result is not None and len(result) else {})
        out.update({f"{m.signal}:{k}": float(values[k]) if k in values else None for k in METRICS})
    return out


# --------------------------------------------------------------------------- engines

Executor = str | cf.Executor | Any   # "process", "serial", a Dask scheduler address, "local:N", or a Client


def dispatch(tasks: list[Task], executor: Executor, workers: int | None,
              done: Callable[[Task, dict[str, Any]], None]) -> None:
    """Hand the runs to the chosen engine; ``done`` is called in this process as each finishes."""
    if not tasks:
        return
    if executor == "serial":
        for task in tasks:
            try:
                row = execute(task)
            except Exception as e:  # noqa: BLE001 -- as in a worker: a failed row, not a stopped sweep
                row = failed_row(task, e)
            done(task, row)
    elif executor == "process":
        context = multiprocessing.get_context("spawn")
        pool = cf.ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, mp_context=context)
        try:
            _collect(tasks, pool, done)
        finally:             # on Ctrl-C, runs not started yet are dropped instead of awaited
            pool.shutdown(wait=True, cancel_futures=True)
    elif isinstance(executor, cf.Executor):
        _collect(tasks, executor, done)
    else:
        raise SetupError(f"unknown executor {executor!r}: give 'process', 'serial', a Dask scheduler "
                         "address, 'local:N', a concurrent.futures.Executor or a distributed.Client.")


def is_cluster(executor: Executor) -> bool:
    """Whether the runs go to Dask (an address, ``local:N`` or a Client) rather than a local engine."""
    if isinstance(executor, str):
        return executor not in ("process", "serial")
    if isinstance(executor, cf.Executor):
        return False
    from distributed import Client
    return isinstance(executor, Client)


def _collect(tasks: list[Task], engine: cf.Executor, done) -> None:
    """Submit every run; a worker that dies or raises makes that run a failed row, not a stopped sweep."""
    futures = {engine.submit(execute, task): task for task in tasks}
    for future in cf.as_completed(list(futures)):
        task = futures[future]
        try:
            row = future.result()
        except Exception as e:  # noqa: BLE001 -- a crashed worker process or a lost Dask worker
            row = failed_row(task, e)
        done(task, row)


def failed_row(task: Task, error: Exception) -> dict[str, Any]:
    return {"run_id": task.run_id, "status": "failed", "message": f"{type(error).__name__}: {error}",
            "wall_time": None, **run_metrics(None, task.metrics)}

