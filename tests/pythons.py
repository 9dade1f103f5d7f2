"""The Pythons a user may run us from, for the tests (issue 25): this environment's and Debian's.

Debian's and Ubuntu's ``/usr/bin/python3`` link libpython statically (its symbols are exported
from the executable), unlike the ``python3`` the test machines put first on PATH (pyenv, with a
shared libpython).  The FMUs' loader must recognise either as the Python already running
(greyfmu/loader/platform.h, ``loaded_python``).  ``debian_venv`` makes a virtual environment
from ``/usr/bin/python3`` with the project installed (editable, with its ``parquet`` extra) and what the README's first hour
installs, once: it is kept in ~/.cache/greyfmu/pythons/ (`CACHE`, outside the tree: about 770 MB)
and reused while its stamp (this repository, that Python's version, pyproject.toml) is unchanged.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

from cachelock import cache_lock

ROOT = Path(__file__).resolve().parents[1]
DEBIAN_PYTHON = Path("/usr/bin/python3")
CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "greyfmu" / "pythons"
"""Outside the tree (issue 45: the venv is 767 MB, more than the rest of a clone's build/): one
folder per checkout, since the venv installs this checkout editable."""
VENV = CACHE / hashlib.sha256(str(ROOT).encode()).hexdigest()[:12] / "debian-python3"
# pytest and gemseo-fmu (its OpenModelica FMUs, --no-deps as in the README) for the first-hour commands
EXTRAS = (("pytest",), ("--no-deps", "gemseo-fmu==3.1.1"))


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
    with cache_lock(VENV):
        return _made_venv()


def _made_venv() -> Path:
    python, stamp = VENV / "bin" / "python", VENV / "greyfmu-stamp.txt"
    expected = _stamp()
    if stamp.is_file() and stamp.read_text() == expected and python.is_file():
        return python
    shutil.rmtree(VENV, ignore_errors=True)
    made = subprocess.run([str(DEBIAN_PYTHON), "-m", "venv", str(VENV)], capture_output=True, text=True)
    if made.returncode != 0:
        raise Unavailable(f"{DEBIAN_PYTHON} -m venv failed (Debian: apt-get install python3-venv):\n{made.stderr}")
    pip = [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check"]
    subprocess.run(pip + ["-e", f"{ROOT}[parquet]"], check=True)   # with pyarrow, as tests/run.sh installs it
    for extra in EXTRAS:
        subprocess.run(pip + list(extra), check=True)
    stamp.write_text(expected)
    return python


def libpython_files(python: Path) -> int:
    """The number of libpython files mapped into a bare ``python`` process: 0 where the executable
    links libpython statically (sysconfig cannot tell: Debian's says Py_ENABLE_SHARED = 1, for the
    shared library it also ships)."""
    script = "print(len({l.split(None, 5)[5] for l in open('/proc/self/maps') if 'libpython' in l}))"
    return int(subprocess.run([str(python), "-c", script], capture_output=True, text=True, check=True).stdout)
