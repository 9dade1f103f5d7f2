"""The Pythons a user may run us from, for the tests (issue 25): this environment's and Debian's,
and one with only what a user of our FMUs has (issue 39, `bare_venv`).

Debian's and Ubuntu's ``/usr/bin/python3`` link libpython statically (its symbols are exported
from the executable), unlike the ``python3`` the test machines put first on PATH (pyenv, with a
shared libpython).  The FMUs' loader must recognise either as the Python already running
(greyfmu/loader/platform.h, ``loaded_python``).  ``debian_venv`` makes a virtual environment
from ``/usr/bin/python3`` with the project installed (editable, with its ``parquet`` extra) and what the
first hour (docs/first-hour.md) installs, once: it is kept in ~/.cache/greyfmu/pythons/ (`CACHE`,
outside the tree: about 770 MB) and reused while its stamp (this repository, that Python's version, pyproject.toml) is unchanged.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

from cachelock import cache_lock

ROOT = Path(__file__).resolve().parents[1]
DEBIAN_PYTHON = Path("/usr/bin/python3")
CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "greyfmu" / "pythons"
"""Outside the tree (issue 45: the venv is 767 MB, more than the rest of a clone's build/): one
folder per checkout, since the venv installs this checkout editable."""
VENV = CACHE / hashlib.sha256(str(ROOT).encode()).hexdigest()[:12] / "debian-python3"
# pytest and gemseo-fmu (its OpenModelica FMUs, --no-deps as in docs/first-hour.md) for the first-hour commands
EXTRAS = (("pytest",), ("--no-deps", "gemseo-fmu==3.1.1"))
BARE = ROOT / "build" / "pythons" / "bare-fmpy"
BARE_PACKAGES = ("fmpy", "numpy", "scipy", "daqp")
"""What a user of our FMUs has (daqp: OSMMGPC's stated requirement); `bare_venv`."""


class Unavailable(RuntimeError):
    """Debian's python3 is missing or cannot make a virtual environment here."""


def _stamp() -> str:
    version = subprocess.run([str(DEBIAN_PYTHON), "-c", "import sys; print(sys.version)"], capture_output=True,
                             text=True, check=True).stdout.strip()
    pyproject = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    return f"{ROOT}\n{version}\n{pyproject}\n{EXTRAS!r}\n"


def debian_venv() -> Path:
    """The python of the cached virtual environment made from /usr/bin/python3 (made if needed,
    by one process while the others wait)."""
    if not DEBIAN_PYTHON.is_file():
        raise Unavailable(f"{DEBIAN_PYTHON} does not exist (not a Debian or Ubuntu machine)")
    # with pyarrow, as tests/run.sh installs it
    return cached_venv(DEBIAN_PYTHON, VENV, _stamp(), [["-e", f"{ROOT}[parquet]"], *map(list, EXTRAS)])


def bare_venv(base: Path | None = None) -> Path:
    """The python of a cached environment made from ``base`` (default: the Python running the
    tests) with only `BARE_PACKAGES` at this environment's versions and nothing of greyfmu: a user
    of our FMUs (issue 39, tests/slaves/test_together.py)."""
    base = Path(base or sys.executable)
    wanted = [f"{name}=={version(name)}" for name in BARE_PACKAGES]
    described = subprocess.run([str(base), "-c", "import sys; print(sys.version, sys.base_prefix)"],
                               capture_output=True, text=True, check=True).stdout
    folder = BARE.with_name(f"{BARE.name}-{hashlib.sha256(described.encode()).hexdigest()[:8]}")
    return cached_venv(base, folder, f"{described}{' '.join(wanted)}\n", [wanted])


def cached_venv(base: Path, folder: Path, stamp_text: str, installs: list[list[str]]) -> Path:
    """The python of the virtual environment ``folder`` made from ``base`` with each of ``installs``
    pip-installed, by one process while the others wait; kept while its stamp is ``stamp_text``."""
    python, stamp = folder / "bin" / "python", folder / "greyfmu-stamp.txt"
    with cache_lock(folder):
        if stamp.is_file() and stamp.read_text() == stamp_text and python.is_file():
            return python
        shutil.rmtree(folder, ignore_errors=True)
        made = subprocess.run([str(base), "-m", "venv", str(folder)], capture_output=True, text=True)
        if made.returncode != 0:
            raise Unavailable(f"{base} -m venv failed (Debian: apt-get install python3-venv):\n{made.stderr}")
        for install in installs:
            installed = subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                                        *install], capture_output=True, text=True)
            if installed.returncode != 0:
                raise Unavailable(f"pip install {' '.join(install)} failed:\n{installed.stderr[-2000:]}")
        stamp.write_text(stamp_text)
        return python


def is_debians(python: Path) -> bool:
    """Whether ``python`` (a venv's or not) runs Debian's /usr/bin/python3."""
    base = subprocess.run([str(python), "-c", "import sys; print(sys._base_executable)"], capture_output=True,
                          text=True, check=True).stdout.strip()
    return DEBIAN_PYTHON.is_file() and Path(base).resolve() == DEBIAN_PYTHON.resolve()


def another_python() -> Path:
    """A Python of another build than Debian's /usr/bin/python3, for checks across Pythons: the one
    running the tests unless it is Debian's (CI runs the suite with Debian's), else python3 or
    python on PATH outside the active virtual environment."""
    if not is_debians(Path(sys.executable)):
        return Path(sys.executable)
    venv = os.environ.get("VIRTUAL_ENV")
    path = os.pathsep.join(entry for entry in os.environ.get("PATH", "").split(os.pathsep)
                           if not (venv and entry.startswith(venv)))
    for name in ("python3", "python"):
        found = shutil.which(name, path=path)
        if found and not is_debians(Path(found)):
            return Path(found)
    raise Unavailable("no Python of another build than Debian's on PATH")


def libpython_files(python: Path) -> int:
    """The number of libpython files mapped into a bare ``python`` process: 0 where the executable
    links libpython statically (sysconfig cannot tell: Debian's says Py_ENABLE_SHARED = 1, for the
    shared library it also ships)."""
    script = "print(len({l.split(None, 5)[5] for l in open('/proc/self/maps') if 'libpython' in l}))"
    return int(subprocess.run([str(python), "-c", script], capture_output=True, text=True, check=True).stdout)
