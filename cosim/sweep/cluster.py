"""Running a sweep's runs on a Dask cluster whose workers share no filesystem with the client.

The scenario goes to the workers once, as a package broadcast by content hash (`.shipping`);
each run is submitted with Dask ``retries``: a run whose worker dies is run again on another
worker by the scheduler, and a run whose every try raised (or whose workers kept dying,
Dask's ``KilledWorker``, tried once more alone, since a dying worker takes the runs beside it
with it) is a failed row with the message.

Who may use the cluster: a ``local:N`` cluster speaks only TLS with a key and certificate made for
this sweep (`sweep_security`, kept in memory and handed to the worker processes by Dask), so
no other process of this machine, whichever its user, can connect to its scheduler, workers or
nannies and have them run its code.  A scheduler given by address is reached with the user's
own Dask security configuration (``distributed.comm.tls.*``), and `warn_if_open` says when
it is neither TLS nor on loopback.
"""
from __future__ import annotations

import ipaddress
import signal
import socket
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from typing import Any

from ..errors import Errc, SetupError
from .dispatch import Task, distributed, failed_row, is_cluster
from .shipping import (
    Package,
    deliver,
    execute_shipped,
    forget_package,
    input_table_bytes,
    parameter_set_bytes,
    publish_package,
)

#: tries of a run after its first that raised (a lost worker is rescheduled by the scheduler itself)
RETRIES = 2


def local_workers(executor: str) -> int:
    """N of ``local:N`` (a Dask LocalCluster of N worker processes)."""
    n = executor.split(":", 1)[1]
    if not n.isdigit() or int(n) < 1:
        raise SetupError(f"'{executor}': give local:N with N the number of worker processes.",
                         element="--scheduler")
    return int(n)


def sweep_security():
    """A Dask ``Security`` of a key and self-signed certificate made now, for one sweep's cluster:
    TLS required on every connection, both ends showing this certificate."""
    Security = distributed().Security
    try:
        return Security.temporary()
    except ImportError:   # Security.temporary makes the key with the package cryptography
        raise SetupError("a local:N cluster needs the package cryptography (for its TLS certificate), "
                         "which is not installed; install it with pip install 'greyfmu[dask]'.",
                         element="--scheduler") from None


@contextmanager
def local_cluster(workers: int):
    """A LocalCluster of ``workers`` processes on 127.0.0.1 reachable only with `sweep_security`.

    Its processes leave Ctrl-C to this one (they start with SIGINT ignored, which spawned
    Pythons keep), so Ctrl-C stops the sweep without a traceback from each.
    """
    from distributed import LocalCluster

    security = sweep_security()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        # no dashboard; the scheduler's HTTP server (health and metrics routes) on a free loopback
        # port, not Dask's fixed 8787, which a second sweep on the machine would find taken
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                               host="127.0.0.1", protocol="tls://", security=security)
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        yield cluster
    finally:
        cluster.close()


def dispatch_cluster(tasks: list[Task], executor, package: Package,
                     done: Callable[[Task, dict[str, Any]], None]) -> None:
    """Hand the runs to a Dask ``Client``, a ``local:N`` cluster or a scheduler address."""
    if not tasks:
        return
    with client_for(executor) as client:
        _collect(tasks, client, package, done)


@contextmanager
def client_for(executor):
    """A Dask ``Client`` of ``executor``: the Client itself, a ``local:N`` cluster made now (closed
    after), or the scheduler at an address."""
    Client = distributed().Client
    if isinstance(executor, Client):
        yield executor
    elif executor.startswith("local:"):
        with local_cluster(local_workers(executor)) as cluster, \
                Client(cluster, security=cluster.security) as client:
            yield client
    else:
        warn_if_open(executor)
        with _connect(executor) as client:
            yield client


def _connect(address: str):
    """A Client of the scheduler at ``address``, with the user's Dask security configuration
    (Dask's own default: ``distributed.comm.tls.*``, ``distributed.client.security-loader``)."""
    Client = distributed().Client
    try:
        return Client(address, timeout=10)
    except OSError as e:
        raise SetupError(f"cannot reach the Dask scheduler ({e}).", element="--scheduler",
                         hint="Start one with TLS as docs/sweeps.md's \"Whom a cluster obeys\" shows ('dask scheduler' "
                              "and 'dask worker' with --tls-ca-file, --tls-cert, --tls-key), or use --scheduler "
                              "local:N.") from None
    except TypeError as e:
        if "TLS" not in str(e):
            raise
        # tls:// without a certificate in Dask's configuration
        raise SetupError(f"cannot talk TLS to the Dask scheduler ({e}).", element="--scheduler",
                         hint="Give Dask the cluster's CA and a client certificate and key: "
                              "distributed.comm.tls.ca-file, .client.cert and .client.key in its "
                              "configuration, or DASK_DISTRIBUTED__COMM__TLS__CA_FILE, ..._CLIENT__CERT "
                              "and ..._CLIENT__KEY.") from None


def check_scheduler(executor) -> None:
    """Refuse a ``local:N`` without a count, or a scheduler address Dask cannot read, before any run."""
    if isinstance(executor, str) and is_cluster(executor):
        if executor.startswith("local:"):
            local_workers(executor)
        else:
            _scheme_and_host(executor)


def _scheme_and_host(address: str) -> tuple[str, str]:
    """The protocol and host of a scheduler address, as Dask reads it (``HOST:PORT`` is tcp)."""
    distributed()
    from distributed.comm import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        return scheme, parse_host_port(location)[0] if location else ""
    except ValueError as e:
        raise SetupError(f"'{address}' is not a Dask scheduler address ({e}): give tls://HOST:PORT, "
                         "tcp://HOST:PORT or local:N.", element="--scheduler") from None


def is_open(address: str) -> bool:
    """Whether the scheduler at ``address`` is one anybody who can reach it may use: not TLS (so
    not authenticated by certificate) and not on this machine's loopback (a host name counts
    as loopback only when every address it resolves to is)."""
    scheme, host = _scheme_and_host(address)
    if scheme in ("tls", "wss", "inproc"):
        return False
    try:
        return not ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        resolved = {info[4][0] for info in socket.getaddrinfo(host, None)}
    except (OSError, UnicodeError):
        return True
    return not all(ipaddress.ip_address(a.split("%", 1)[0]).is_loopback for a in resolved)


def warn_if_open(address: str) -> None:
    """A RuntimeWarning naming ``address`` when it is an open scheduler (`is_open`)."""
    if is_open(address):
        warnings.warn(f"the Dask scheduler {address} is neither TLS nor on loopback: anyone who can reach it "
                      "can run code on its workers, as their user (see the TLS recipe in docs/sweeps.md).",
                      RuntimeWarning, stacklevel=3)


def _collect(tasks: list[Task], client, package: Package, done) -> None:
    """Every run at once (`run_published`), then the workers' unpacked copies of the scenario
    are removed (`forget_package`)."""
    with published(client, package) as shipped:
        run_published(tasks, client, shipped, done)


@contextmanager
def published(client, package: Package):
    """``package`` published to the cluster (`publish_package`) for the runs inside the block,
    then forgotten by every worker (`forget_package`)."""
    shipped = publish_package(client, package)
    try:
        yield shipped
    finally:
        forget_package(client, package)


def run_published(tasks: list[Task], client, shipped, done) -> None:
    """Every run at once; those that ended in ``KilledWorker`` again one at a time (see `_run`)."""
    suspects = [task for task, _ in _run(tasks, client, shipped, done)]
    for task in suspects:
        for _, outcome in _run([task], client, shipped, done):
            row = failed_row(task, outcome, Errc.worker_lost)
            done(task, {**row, "message": f"{row['message']} Rerun alone, it killed its workers again."})


def _run(tasks: list[Task], client, shipped, done) -> list[tuple[Task, Exception]]:
    """Submit ``tasks``; ``done`` for each that returned or raised, the tasks whose workers kept dying.

    A worker that dies takes every run it held with it, and each of those counts a try: a run
    that kills its workers (an FMU that aborts) can make the runs beside it ``KilledWorker`` too,
    so those are returned to be tried again alone.
    """
    from distributed import KilledWorker, as_completed

    # a run writes files, so it is never "pure" (Dask would reuse the result of an equal call)
    futures = {client.submit(execute_shipped, task, shipped, parameter_set_bytes(task), input_table_bytes(task),
                             pure=False, retries=RETRIES): task for task in tasks}
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
