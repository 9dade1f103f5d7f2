"""The unzip cache: each FMU file's content extracted once per machine (`cosim.read.fmucache`), else
once per process; checked as it is extracted."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ...read.fmucache import cache_root, unpacked
from ...record.journal import UNZIP_PREFIX
from ...safeio import extract_archive, temporary_folder


class Unzipped:
    """The extracted folder of each FMU file, looked up once per process (keyed by path, size
    and mtime): the shared cache entry of its content (`cosim.read.fmucache`), so runs in other
    processes do not unzip it again; with the cache off (``COSIM_FMU_CACHE=off``) or not
    writable, a folder of this process's own.  FMUs are
    archives from elsewhere: `cosim.safeio.extract_archive` checks member names, the
    compression ratio and the expanded size (the `--max-unpacked` limit) as it extracts."""

    _tmp: tempfile.TemporaryDirectory | None = None
    _dirs: dict[tuple, str] = {}
    _owner: int = os.getpid()

    @staticmethod
    def folder() -> str | None:
        """This process's extraction folder (None before the first FMU is extracted)."""
        return Unzipped._tmp.name if Unzipped._tmp is not None else None

    @staticmethod
    def adopt() -> None:
        """In a forked child (`cosim.run.supervisor`): keep using the FMUs the parent extracted, but
        extract new ones into a folder of the child's own, which the parent removes after a
        crash; the parent's folder is never removed from here, not even when collected."""
        if Unzipped._tmp is not None and os.getpid() != Unzipped._owner:
            Unzipped._tmp._finalizer.detach()
            Unzipped._tmp = None
        Unzipped._owner = os.getpid()

    @staticmethod
    def release() -> None:
        """Remove this process's own extraction folder (a forked child skips the finalizers)."""
        if Unzipped._tmp is not None and os.getpid() == Unzipped._owner:
            Unzipped._tmp.cleanup()
            Unzipped._tmp = None
            Unzipped._dirs = {}

    def __call__(self, path: Path) -> str:
        path = path.resolve()
        stat = path.stat()
        key = (path, stat.st_size, stat.st_mtime_ns)
        if key not in Unzipped._dirs:
            root = cache_root()
            if root is not None:
                try:
                    Unzipped._dirs[key] = str(unpacked(path, root))
                    return Unzipped._dirs[key]
                except OSError:   # a read-only or full cache folder: extract for this process only
                    pass
            if Unzipped._tmp is None:
                Unzipped._tmp = temporary_folder(UNZIP_PREFIX)
                Unzipped._owner = os.getpid()
            target = Path(Unzipped._tmp.name) / str(len(Unzipped._dirs))
            target.mkdir()
            extract_archive(path, target, required="modelDescription.xml")  # size, names, ratio checked
            Unzipped._dirs[key] = str(target)
        return Unzipped._dirs[key]
