"""What tests/slaves/test_together.py needs to run FMUs together in one process as a user does
(issue 39): a Python with only fmpy, numpy and scipy, other vendors' FMUs named like ours,
another release of ours, and the C host tests/together_host.c.

The Python of those hosts is tests/pythons.py bare_venv: fmpy, numpy, scipy and daqp, nothing of
greyfmu, so every import of the FMUs' code must be served by the FMUs themselves.
"""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

from dropinhost import environment, unzip

ROOT = Path(__file__).resolve().parents[1]
VENDOR = Path(__file__).resolve().parent / "fmus" / "vendor"
HOST_SOURCE = Path(__file__).resolve().parent / "together_host.c"
TOGETHER_FMPY = Path(__file__).resolve().parent / "together_fmpy.py"


def build_vendor_fmus(dest: Path) -> dict[str, Path]:
    """Another vendor's plain pythonfmu FMUs PID and Step and pythonfmu3 FMU PID3 (tests/fmus/vendor/)."""
    from pythonfmu.builder import FmuBuilder
    from pythonfmu3.builder import FmuBuilder as Fmu3Builder

    built = {}
    for script in sorted(VENDOR.glob("*.py")):
        built[script.stem] = Path(FmuBuilder.build_FMU(script, dest=dest / "fmi2", needsExecutionTool="false"))
    for script in sorted((VENDOR / "fmi3").glob("*.py")):
        built[script.stem] = Path(Fmu3Builder.build_FMU(script, dest=dest / "fmi3"))
    return built


RELEASE_EDIT = '''

# Another release (tests/together.py): every PID output doubled.
_released_step = PID.step


def _doubled_step(self, r, y):
    _released_step(self, r, y)
    self.u = 2.0 * self.u
    return self.u


PID.step = _doubled_step
'''


def other_greyfmu(dest: Path) -> Path:
    """A copy of the greyfmu package whose PID doubles its output: another release's numerics
    (``dest/greyfmu``); ``dest`` is the folder to put on a path."""
    import greyfmu.build as build

    package = dest / "greyfmu"
    shutil.copytree(build.PACKAGE_DIR, package, ignore=shutil.ignore_patterns(*build.BUILD_ONLY))
    pid = package / "control" / "pid.py"
    pid.write_text(pid.read_text() + RELEASE_EDIT)
    return dest


def build_other_release(names: list[str], greyfmu_folder: Path, dest: Path) -> dict[str, Path]:
    """``names`` built from the sources with the greyfmu of ``greyfmu_folder`` (`other_greyfmu`):
    the same models as build/fmus, other code, so another private package."""
    import greyfmu.build as build

    dest.mkdir(parents=True, exist_ok=True)
    kept = build.PACKAGE_DIR
    build.PACKAGE_DIR = greyfmu_folder / "greyfmu"
    try:
        return {path.stem: path for path in build.build_fmus(names, out_dir=dest, force=True)}
    finally:
        build.PACKAGE_DIR = kept


def run_fmpy(python: Path, fmus: list[Path], *options: str, timeout: float = 600) -> tuple[list[dict], dict]:
    """tests/together_fmpy.py under ``python``: one dict per FMU run, then what was left; AssertionError
    with the process's output if it did not run them all."""
    done = subprocess.run([str(python), str(TOGETHER_FMPY), *options, *map(str, fmus)], capture_output=True,
                          text=True, timeout=timeout, env=environment())
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    assert done.returncode == 0 and len(lines) == len(fmus) + 1, \
        f"exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return lines[:-1], lines[-1]


def compile_host(folder: Path) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise RuntimeError("no C compiler (cc or gcc) on PATH to build tests/together_host.c")
    host = folder / "together_host"
    subprocess.run([compiler, "-O1", "-Wall", "-Wextra", "-Werror", "-o", str(host), str(HOST_SOURCE), "-ldl",
                    "-lpthread"], check=True)
    return host


HOST_INPUTS = {"r": "1.5", "u": "2"}
"""Inputs the host sets where an FMU has them (PID's set-point, FOPDT's input), so outputs move."""


def host_spec(fmu: Path, folder: Path, output: str | None = None) -> list[str]:
    """The host's ``[set VR VALUE]... fmu DIR IDENTIFIER GUID VR`` for ``fmu`` extracted into
    ``folder`` (VR: ``output``, by default the first Real output; `HOST_INPUTS` set)."""
    unzipped = unzip(fmu, folder)
    sets = [item for name, value in HOST_INPUTS.items() if name in unzipped.references and name not in unzipped.outputs
            for item in ("set", str(unzipped.references[name]), value)]
    return [*sets, "fmu", str(unzipped.folder), unzipped.identifier, unzipped.guid,
            str(unzipped.references[output or unzipped.outputs[0]])]


def bare_environment(python: Path) -> dict[str, str]:
    """A C host's environment with nothing of ours: PATH and the Python to use (no greyfmu in it)."""
    return {"PATH": "/usr/bin:/bin", "GREYFMU_PYTHON": str(python)}


def run_host(host: Path, mode: str, count: int, specs: list[str], python: Path,
             timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([str(host), mode, str(count), *specs], capture_output=True, text=True, timeout=timeout,
                          env=bare_environment(python))


def results(done: subprocess.CompletedProcess) -> dict[tuple[int, str], str]:
    """The host's ``result FMU WHAT VALUE`` lines, by (FMU, WHAT)."""
    found = {}
    for line in done.stdout.splitlines():
        if line.startswith("result "):
            _, fmu, what, value = line.split(" ", 3)
            found[int(fmu), what] = value
    return found
