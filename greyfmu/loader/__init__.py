"""The drop-in loader of the greyfmu FMUs (build side; not embedded in the FMUs).

``fmi2_loader.c`` (with its platform layer ``platform.h``, its guard ``guard.h`` and FMU states
``states.h``) becomes each FMU's ``binaries/linux64/<modelIdentifier>.so`` and
``binaries/win64/<modelIdentifier>.dll``: it finds a Python, loads its shared libpython and
forwards every fmi2 function to pythonfmu's library, shipped next to it as
``pythonfmu-export.so`` / ``.dll`` (see the C file's header).  On Linux ``process.c`` becomes
``binaries/linux64/greyfmu-process.so`` beside it: the lock and ready flag every loader in a
process shares, so Python starts once per process (`process_binary`).
``greyfmu_target.py`` is shipped as ``resources/greyfmu_target.py``: the check the loader runs
with a candidate Python.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

LOADER_SOURCE = Path(__file__).resolve().parent / "fmi2_loader.c"
LOADER_SOURCE3 = Path(__file__).resolve().parent / "fmi3_loader.c"
"""The FMI 3.0 loader: the same Python start, guard, FMU states and process lock (python.h, guard.h,
states.h, platform.h, process.c), forwarding to pythonfmu3's library (``pythonfmu3-export.so``/``.dll``)."""
PROCESS_SOURCE = Path(__file__).resolve().parent / "process.c"
PROCESS_LIBRARY = "greyfmu-process.so"
"""The file name process.c gets beside the linux64 loader (process.h GREYFMU_PROCESS_LIBRARY)."""
TARGET_CHECK = Path(__file__).resolve().parent / "greyfmu_target.py"


@dataclass(frozen=True)
class Platform:
    """How the loader is compiled for one FMI platform folder."""

    folder: str
    folder3: str
    """The FMI 3.0 platform tuple's folder (FMI 3.0 §2.5.1.1)."""
    suffix: str
    compilers: tuple[str, ...]
    flags: tuple[str, ...]
    libraries: tuple[str, ...]

    @property
    def pythonfmu_library(self) -> str:
        """The name pythonfmu's library gets inside the FMU, next to the loader."""
        return f"pythonfmu-export{self.suffix}"

    @property
    def pythonfmu3_library(self) -> str:
        """The name pythonfmu3's library gets inside an FMI 3.0 FMU, next to the loader."""
        return f"pythonfmu3-export{self.suffix}"


PLATFORMS = (
    Platform("linux64", "x86_64-linux", ".so", ("cc", "gcc", "clang"), ("-shared", "-fPIC", "-O2", "-fvisibility=hidden"),
             ("-ldl", "-lpthread")),
    Platform("win64", "x86_64-windows", ".dll", ("x86_64-w64-mingw32-gcc",), ("-shared", "-O2", "-static-libgcc"), ("-lpsapi",)),
)
WARNINGS_ENV = "GREYFMU_WERROR"


def warnings() -> tuple[str, ...]:
    """The warning flags of the loader's build: -Werror only when GREYFMU_WERROR=1 (our CI,
    .ci/run), so a user's build does not fail on a warning a newer compiler adds."""
    return ("-Wall", "-Wextra") + (("-Werror",) if os.environ.get(WARNINGS_ENV) == "1" else ())


def host_folder() -> str:
    """The FMI binaries folder of this machine: win64 on Windows, else linux64."""
    return "win64" if sys.platform == "win32" else "linux64"


def cross_compiler_notices() -> list[str]:
    """One line per other platform than this machine's (win64 on Linux) whose cross compiler is
    not on PATH: the FMUs' binary there is pythonfmu's.  Said only by ``greyfmu build``, where
    the user asked for the FMUs themselves (issue 27: the build behind a first ``cosim run`` on
    Linux says nothing of Windows; each FMU's documentation/index.html records it)."""
    return [f"greyfmu build: no {platform.compilers[0]} on PATH: the FMUs' {platform.folder} binary is "
            "pythonfmu's (needs Python on that host)"
            for platform in PLATFORMS if platform.folder != host_folder() and compiler(platform) is None]


class LoaderError(RuntimeError):
    """The loader could not be compiled."""


def compiler(platform: Platform) -> str | None:
    """The first of the platform's C compilers on PATH; None if there is none."""
    return next((found for name in platform.compilers if (found := shutil.which(name))), None)


@functools.cache
def loader_binary(platform: Platform, fmi: int = 2) -> bytes | None:
    """The compiled loader for ``platform``, once per process; None when there is no compiler for
    it: the FMU then keeps pythonfmu's library there.  That is said once on stderr for this
    machine's platform (the FMUs then need a host that runs Python); for another one (win64 on
    Linux: a cross compiler few have, which matters only to whoever ships the FMUs to Windows)
    only ``greyfmu build`` says it (`cross_compiler_notices`).  ``fmi``: 2 (fmi2_loader.c) or 3 (fmi3_loader.c)."""
    found = compiler(platform)
    if found is None:
        if platform.folder == host_folder():
            print(f"greyfmu build: no C compiler for {platform.folder} ({', '.join(platform.compilers)}) on PATH: "
                  f"the FMUs keep pythonfmu's {platform.folder} library, which loads only in a host that already "
                  "runs Python", file=sys.stderr)
        return None
    return _compiled(found, platform, LOADER_SOURCE if fmi == 2 else LOADER_SOURCE3)


@functools.cache
def process_binary() -> bytes | None:
    """greyfmu-process.so for linux64 (process.c), once per process; None where the loader has
    no compiler either (the FMU then has no loader to share it)."""
    found = compiler(PLATFORMS[0])
    return _compiled(found, PLATFORMS[0], PROCESS_SOURCE) if found is not None else None


def _compiled(found: str, platform: Platform, source: Path) -> bytes:
    with tempfile.TemporaryDirectory(prefix="greyfmu-loader-") as temp:
        library = Path(temp) / f"loader{platform.suffix}"
        completed = subprocess.run([found, *platform.flags, *warnings(), "-o", str(library), str(source),
                                    *platform.libraries], capture_output=True, text=True)
        if completed.returncode != 0:
            raise LoaderError(f"{found} could not compile {source} for {platform.folder}:\n{completed.stderr}")
        return library.read_bytes()
