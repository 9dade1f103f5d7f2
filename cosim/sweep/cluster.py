"""Running a sweep's runs on a Dask cluster whose workers share no filesystem with the client.

The scenario goes to the workers once, as a package broadcast by content hash (`.shipping`);
each run is submitted with Dask ``retries``: a run whose worker dies is run again on another
worker by the scheduler, and a run whose every try raised (or whose workers kept dying,
Dask's ``KilledWorker``, tried once more alone, since a dying worker takes the runs beside it
with it) is a failed row with the message.
"""
from __future__ import annotations

import signal
from collections.abc import Callable
from contextlib import contextmanager
from typing import Any

from ..errors import SetupError
from .dispatch import Task, distributed, failed_row
from .shipping import Package, deliver, execute_shipped, forget_package, parameter_set_bytes, publish_package

#: tries of a run after its first that raised (a lost worker is rescheduled by the scheduler itself)
RETRIES = 2


def local_workers(executor: str) -> int:
    """N of ``local:N`` (a Dask LocalCluster of N worker processes)."""
    n = executor.split(":", 1)[1]
    if not n.isdigit() or int(n) < 1:
        raise SetupError(f"'{executor}': give local:N with N the number of worker processes.",
                         element="--scheduler")
    return int(n)


@contextmanager
def _local_cluster(workers: int):
    """A LocalCluster of ``workers`` processes that leave Ctrl-C to this one (they start with SIGINT
    ignored, which spawned Pythons keep), so Ctrl-C stops the sweep without a traceback from each."""
    from distributed import LocalCluster

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        yield cluster
    finally:
        cluster.close()


def dispatch_cluster(tasks: list[Task], executor, package: Package,
                     done: Callable[[Task, dict[str, Any]], None]) -> None:
    """Hand the runs to a Dask ``Client``, a ``local:N`` cluster or a scheduler address."""
    Client = distributed().Client
    if not tasks:
        return

    if isinstance(executor, Client):
        _collect(tasks, executor, package, done)
    elif executor.startswith("local:"):
        with _local_cluster(local_workers(executor)) as cluster, Client(cluster) as client:
            _collect(tasks, client, package, done)
    else:
        try:
            client = Client(executor, timeout=10)
        except OSError as e:
            raise SetupError(f"cannot reach the Dask scheduler ({e}).", element="--scheduler",
                             hint="Start one with 'dask scheduler' and workers with 'dask worker "
                                  "ADDRESS', or use --scheduler local:N.") from None
        with client:
            _collect(tasks, client, package, done)


def _collect(tasks: list[Task], client, package: Package, done) -> None:
    """Every run at once; those that ended in ``KilledWorker`` again one at a time (see `_run`);
    then the workers' unpacked copies of the scenario are removed (`forget_package`)."""
    shipped = publish_package(client, package)
    try:
        suspects = [task for task, _ in _run(tasks, client, shipped, done)]
        for task in suspects:
            for _, outcome in _run([task], client, shipped, done):
                row = failed_row(task, outcome)
                done(task, {**row, "message": f"{row['message']} Rerun alone, it killed its workers again."})
    finally:
        forget_package(client, package)


def _run(tasks: list[Task], client, shipped, done) -> list[tuple[Task, Exception]]:
    """Submit ``tasks``; ``done`` for each that returned or raised, the tasks whose workers kept dying.

    A worker that dies takes every run it held with it, and each of those counts a try: a run
    that kills its workers (an FMU that aborts) can make the runs beside it ``KilledWorker`` too,
    so those are returned to be tried again alone.
    """
    from distributed import KilledWorker, as_completed

    # a run writes files, so it is never "pure" (Dask would reuse the result of an equal call)
    futures = {client.submit(execute_shipped, task, shipped, parameter_set_bytes(task), pure=False,
                             retries=RETRIES): task for task in tasks}
    killed: list[tuple[Task, Exception]] = []
    try:
        for future in as_completed(list(futures)):
            task = futures[future]
            try:
                row, files = future.result()
                deliver(task, files)
            except KilledWorker as e:
                killed.append((task, e))
                continue
            except Exception as e:  # noqa: BLE001 -- every try raised
                row = failed_row(task, e)
            done(task, row)
    finally:          # on Ctrl-C the runs not finished are cancelled, not left on the cluster
        client.cancel(list(futures))
    return killed
