"""The drop-in loader of the greyfmu FMUs (build side; not embedded in the FMUs).

``fmi2_loader.c`` becomes each FMU's ``binaries/linux64/<modelIdentifier>.so``: it finds a
Python, loads its shared libpython and forwards every fmi2 function to pythonfmu's library,
shipped next to it as ``pythonfmu-export.so`` (see the C file's header).  ``greyfmu_target.py``
is shipped as ``resources/greyfmu_target.py``: the check the loader runs with a candidate Python.
"""

from __future__ import annotations

import functools
import shutil
import subprocess
import tempfile
from pathlib import Path

LOADER_SOURCE = Path(__file__).resolve().parent / "fmi2_loader.c"
TARGET_CHECK = Path(__file__).resolve().parent / "greyfmu_target.py"
PYTHONFMU_LIBRARY = "pythonfmu-export.so"
"""The name pythonfmu's linux64 library gets inside the FMU, next to the loader."""
COMPILE = ["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror"]


class LoaderError(RuntimeError):
    """The loader could not be compiled."""


def c_compiler() -> str | None:
    """The system C compiler: ``cc``, else ``gcc``, else ``clang`` on PATH; None if there is none."""
    return next((found for name in ("cc", "gcc", "clang") if (found := shutil.which(name))), None)


@functools.cache
def loader_binary() -> bytes | None:
    """The compiled linux64 loader, once per process; None when there is no C compiler."""
    compiler = c_compiler()
    if compiler is None:
        return None
    with tempfile.TemporaryDirectory(prefix="greyfmu-loader-") as temp:
        library = Path(temp) / "loader.so"
        completed = subprocess.run([compiler, *COMPILE, "-o", str(library), str(LOADER_SOURCE), "-ldl", "-lpthread"],
                                   capture_output=True, text=True)
        if completed.returncode != 0:
            raise LoaderError(f"{compiler} could not compile {LOADER_SOURCE}:\n{completed.stderr}")
        return library.read_bytes()
