"""The unzip cache: each FMU file extracted once per process, checked as it is extracted."""
from __future__ import annotations

import tempfile
from pathlib import Path

from ..safeio import extract_archive


class Unzipped:
    """Extracts each FMU file once per process (keyed by path, size and mtime), so repeated
    runs of the same system (tests, sweeps, benchmarks) do not unzip again.  FMUs are
    archives from elsewhere: `cosim.safeio.extract_archive` checks member names, the
    compression ratio and the expanded size (the `--max-unpacked` limit) as it extracts."""

    _tmp: tempfile.TemporaryDirectory | None = None
    _dirs: dict[tuple, str] = {}

    def __call__(self, path: Path) -> str:
        path = path.resolve()
        stat = path.stat()
        key = (path, stat.st_size, stat.st_mtime_ns)
        if key not in Unzipped._dirs:
            if Unzipped._tmp is None:
                Unzipped._tmp = tempfile.TemporaryDirectory(prefix="cosim-fmu-")
            target = Path(Unzipped._tmp.name) / str(len(Unzipped._dirs))
            target.mkdir()
            extract_archive(path, target, required="modelDescription.xml")  # size, names, ratio checked
            Unzipped._dirs[key] = str(target)
        return Unzipped._dirs[key]
