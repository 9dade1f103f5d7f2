"""A workaround for pythonfmu 0.7.0 (and pythonfmu3 0.3.4) libraries, which can corrupt the
heap when they are unloaded: empty their interpreter state first."""
from __future__ import annotations

import atexit
import ctypes
import os
import sys
from pathlib import Path


def release_pythonfmu_state(library: ctypes.CDLL) -> bool:
    """Empty the interpreter state a pythonfmu 0.7.0 library keeps, before it is unloaded.

    Such a library keeps its state in a static ``std::shared_ptr`` that the C++ runtime
    destroys when the library is unloaded (or at exit) and that the library's
    ``__attribute__((destructor))`` then assigns ``nullptr`` again (pythonfmu-export
    ``PySlaveInstance.cpp``, ``onLibraryUnload``): the second release writes into freed
    memory, and glibc aborts the process with "corrupted double-linked list" when that memory
    was reused (seen here in test runs and ``fmpy simulate`` processes).  Calling the
    library's exported ``finalizePythonInterpreter`` first empties the pointer, so both later
    releases are no-ops.  In a Python host the state holds nothing an instance still uses
    (the next instantiation makes a new one).  Returns whether the library is such a one.
    """
    release = getattr(library, "finalizePythonInterpreter", None)
    if release is None:
        return False
    release()
    return True


def release_pythonfmu_libraries() -> list[str]:
    """At exit: `release_pythonfmu_state` for every pythonfmu library still loaded (found
    in /proc/self/maps and opened with RTLD_NOLOAD, so nothing new is loaded)."""
    released: list[str] = []
    try:
        maps = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return released
    for line in maps:
        parts = line.split(None, 5)
        path = parts[5].strip().removesuffix(" (deleted)") if len(parts) == 6 else ""
        if not path.endswith(".so") or path in released:
            continue
        try:
            library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD)
        except OSError:
            continue
        if release_pythonfmu_state(library):
            released.append(path)
    return released


if sys.platform.startswith("linux"):
    atexit.register(release_pythonfmu_libraries)
