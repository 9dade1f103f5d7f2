"""Where a tuning's runs go, kept open for the whole tuning so each batch of evaluations (a
generation of the optimiser) pays no start-up: the worker processes, their kept scenario and
FMU instances (`cosim.sweep.worker`) and, on Dask, the scenario's package live from the first
batch to the last.  The same machinery as ``cosim sweep``'s: a run that fails or kills its
worker is a failed row (`cosim.sweep.dispatch`, `cosim.sweep.cluster`), never the end."""
from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from typing import Any, Protocol

from ..plan.prepare import Prepared
from ..sweep.dispatch import Executor, ProcessPool, Task, dispatch, is_cluster, run_serially
from ..sweep.worker import release

Done = Callable[[Task, dict[str, Any]], None]


class Engine(Protocol):
    """Runs a batch of tasks, calling ``done`` in this process as each finishes."""

    def run(self, tasks: list[Task], done: Done) -> None:
        """Every task of the batch, each ending in ``done`` (a failed one as a failed row)."""


class Serial:
    """The runs in this process, one after the other (its kept instances freed at the end)."""

    def run(self, tasks: list[Task], done: Done) -> None:
        run_serially(tasks, done)


class Pool:
    """A local pool of spawned processes kept across the batches (`cosim.sweep.dispatch.ProcessPool`)."""

    def __init__(self, pool: ProcessPool):
        self.pool = pool

    def run(self, tasks: list[Task], done: Done) -> None:
        dispatch(tasks, self.pool, None, done)


class Dask:
    """A Dask cluster with the scenario published once (`cosim.sweep.cluster.published`)."""

    def __init__(self, client, shipped):
        self.client, self.shipped = client, shipped

    def run(self, tasks: list[Task], done: Done) -> None:
        from ..sweep.cluster import run_published

        run_published(tasks, self.client, self.shipped, done)


@contextmanager
def engine(executor: Executor, workers: int | None, prepared: Prepared) -> Iterator[Engine]:
    """The engine of ``executor`` ("process", "serial", a Dask address, "local:N" or a Client),
    open for the block."""
    with ExitStack() as stack:
        if executor == "serial":
            stack.callback(release)
            yield Serial()
        elif executor == "process":
            yield Pool(stack.enter_context(ProcessPool(workers or os.cpu_count() or 1)))
        elif is_cluster(executor):
            from ..sweep.cluster import client_for, published
            from ..sweep.shipping import package_of

            client = stack.enter_context(client_for(executor))
            yield Dask(client, stack.enter_context(published(client, package_of(prepared))))
        else:
            from ..errors import SetupError
            raise SetupError(f"unknown executor {executor!r}: give 'process', 'serial', a Dask scheduler "
                             "address, 'local:N' or a distributed.Client.", element="--scheduler")
