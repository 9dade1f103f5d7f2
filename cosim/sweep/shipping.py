"""Sweeps on a cluster that shares no filesystem with the client.

The client packs the scenario once into an SSP archive (the SSD, every ``.ssv`` beside it and
every FMU, as ``cosim pack`` writes it: `package_of`), Dask hands it to every worker under a
key naming its SHA-256 (`publish_package`), and a worker unpacks it once into its own cache,
``$TMPDIR/cosim-sweep/<sha256>/`` (`unpacked`), removed from every worker still connected and
from the client's machine when the sweep ends (`forget_package`).  Each run carries the bytes of its parameter
sets (the sweep's ``--param-set`` files and the run's own ``.ssv``); the worker runs it in a
temporary folder and returns the table row with the run's result files (``<id>.csv`` and
``<id>.json``), which the client writes into ``OUTPUT/runs/`` (`deliver`).  A worker needs only
this package installed.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..present.pack import pack
from ..errors import SetupError
from ..safeio import extract_archive, file_name, write_atomic
from ..plan.prepare import Prepared
from ..read.ssp import SSD_NAME
from .dispatch import Task, execute


@dataclass(frozen=True)
class Package:
    """A scenario packed as an SSP archive, named by the SHA-256 of its bytes."""
    digest: str
    data: bytes

    @property
    def key(self) -> str:
        """The Dask key the package is broadcast under: equal scenarios share one copy."""
        return f"cosim-scenario-{self.digest}"


def package_of(prepared: Prepared) -> Package:
    """The prepared scenario packed as `cosim.present.pack.pack` writes it (FMUs already built)."""
    with tempfile.TemporaryDirectory(prefix="cosim-pack-") as tmp:
        data = pack(prepared.plan, Path(tmp) / "scenario.ssp").read_bytes()
    return Package(hashlib.sha256(data).hexdigest(), data)


def publish_package(client, package: Package):
    """``package`` as a Dask future every run depends on; each worker fetches it once (from the
    client or a peer) and keeps it.  It is a task returning the package rather than scattered
    data: the scheduler keeps the task, so a package lost with every worker that held it (a run
    that kills each worker it lands on) is made again instead of cancelling the sweep."""
    return client.submit(_package, package, key=package.key)


def _package(package: Package) -> Package:
    return package


def cache_folder() -> Path:
    return Path(tempfile.gettempdir()) / "cosim-sweep"


def forget(digest: str) -> None:
    """Remove this machine's unpacked copy of a package, the staging folders of a worker killed
    while unpacking it, and the cache folder itself once it is empty."""
    folder = cache_folder()
    for path in [folder / digest, *folder.glob(f"{digest}.*")]:
        shutil.rmtree(path, ignore_errors=True)
    try:
        folder.rmdir()
    except OSError:  # missing, or holding the copies of other scenarios
        pass


def forget_package(client, package: Package) -> None:
    """At the end of a sweep: the unpacked copies of ``package`` removed on every worker connected
    now (`forget` through ``client.run``) and on the client's machine (local workers share its
    temporary folder).  A worker that died or left during the sweep keeps its copy."""
    try:
        client.run(forget, package.digest)
    except Exception as e:  # noqa: BLE001 -- the sweep's rows are written; say what is left
        warnings.warn(f"the workers' copies of the scenario ({cache_folder()}/{package.digest} on each) "
                      f"could not be removed: {e}", RuntimeWarning, stacklevel=2)
    forget(package.digest)


def unpacked(package: Package, max_unpacked: int) -> Path:
    """This worker's unpacked copy of ``package`` (unpacked on first use, then reused)."""
    folder = cache_folder() / package.digest
    if (folder / SSD_NAME).is_file():
        return folder
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f"{package.digest}.", dir=folder.parent))
    try:
        archive = staging / "scenario.ssp"
        archive.write_bytes(package.data)
        if hashlib.sha256(archive.read_bytes()).hexdigest() != package.digest:
            raise OSError(f"the scenario package arrived damaged (SHA-256 is not {package.digest})")
        extract_archive(archive, staging / "scenario", max_unpacked, required=SSD_NAME)
        try:
            os.rename(staging / "scenario", folder)   # atomic: a worker racing us keeps its copy
        except OSError:
            if not (folder / SSD_NAME).is_file():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return folder


def execute_shipped(task: Task, package: Package, parameter_sets: tuple[bytes, ...],
                    input_table: bytes | None) -> tuple[dict[str, Any], dict[str, bytes]]:
    """Run ``task`` on a worker from the shipped package (with its parameter sets' and input
    table's contents); the row and the run's result files.  The sweep's shared parameter sets
    and input table are written once per content (`shared_file`), so every run of the sweep
    names the same files and the worker keeps the scenario across them (`cosim.sweep.worker`)."""
    scenario = unpacked(package, task.max_unpacked)
    with tempfile.TemporaryDirectory(prefix=f"cosim-run-{task.run_id}-") as tmp:
        sets = [str(shared_file(package, data, ".ssv")) for data in parameter_sets[:task.shared_sets]]
        for i, data in enumerate(parameter_sets[task.shared_sets:]):
            path = Path(tmp) / f"parameters_{i}.ssv"
            path.write_bytes(data)
            sets.append(str(path))
        table = None if input_table is None else shared_file(package, input_table, ".csv")
        here = replace(task, scenario=str(scenario), parameter_sets=tuple(sets), fmu_dirs=(),
                       csv=str(Path(tmp) / f"{task.run_id}.csv"), input_file=None if table is None else str(table))
        row = execute(here)
        files = {p.name: p.read_bytes() for p in Path(tmp).iterdir() if p.name.startswith(task.run_id)}
    return row, files


def shared_file(package: Package, data: bytes, suffix: str) -> Path:
    """``data`` as a file named by its SHA-256 beside this worker's copy of ``package``
    (``<digest>.shared/``, removed with it by `forget`), written once: to a file of this process's
    own, renamed into place, so workers of one machine writing it at once each leave it whole."""
    path = cache_folder() / f"{package.digest}.shared" / f"{hashlib.sha256(data).hexdigest()}{suffix}"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, part = tempfile.mkstemp(prefix=path.name + ".", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(part, path)
    return path


def parameter_set_bytes(task: Task) -> tuple[bytes, ...]:
    return tuple(Path(p).read_bytes() for p in task.parameter_sets)


def input_table_bytes(task: Task) -> bytes | None:
    """The ``--input-file`` table's contents, shipped to a worker that cannot read the path."""
    return None if task.input_file is None else Path(task.input_file).read_bytes()


def deliver(task: Task, files: dict[str, bytes]) -> None:
    """Write a run's result files where a local run would have written them, each replaced in
    one rename.  The names are the worker's: each must be a file name (`file_name`) of this
    run (``<run id>.<suffix>``), or nothing is written and the `SetupError` (naming the run and
    the file) makes the run's row failed."""
    folder = Path(task.csv).parent
    for name in files:
        file_name(name, what="the file a worker returned", element=f"sweep run {task.run_id}")
        if not name.startswith(f"{task.run_id}."):
            raise SetupError(f"a worker returned the file {name!r}, which is not one of this run's "
                             f"({task.run_id}.csv, {task.run_id}.json); nothing was written.",
                             element=f"sweep run {task.run_id}")
    for name, data in files.items():
        write_atomic(folder / name, data)
