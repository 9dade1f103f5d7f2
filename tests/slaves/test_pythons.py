"""Issue 25: our FMUs in every Python a user may run us from, and never a second interpreter.

The FMUs' loader (greyfmu/loader/platform.h ``loaded_python``) must recognise the Python already
in the process however libpython is linked: statically into the executable (Debian's and
Ubuntu's /usr/bin/python3: before the fix a second libpython was loaded and the process aborted
with "double free or corruption"), a shared libpython (pyenv, the default here), or a shared
libpython a host embedding Python loaded RTLD_LOCAL (tests/dropin_host.c ``embed``).  Each
process here also counts the libpython files mapped into it: one at most.
"""
from __future__ import annotations

import csv
import math
import re
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from dropinhost import compile_host, environment, run_host, unzip
from greyfmu.build import fmu_names
from pythons import ROOT, libpython_files

ALL = fmu_names()
UNDER_FMPY = ROOT / "tests" / "under_fmpy.py"
DEBIAN_LIBPYTHON = Path("/usr/lib/x86_64-linux-gnu/libpython3.11.so.1.0")  # Debian 12's shared libpython3.11


@pytest.fixture(params=["default", "debian"])
def interpreter(request) -> Path:
    """The python running these tests, and one of a venv made from Debian's /usr/bin/python3."""
    return Path(sys.executable) if request.param == "default" else request.getfixturevalue("debian_python")


@pytest.fixture(scope="session")
def every_fmu_under_fmpy(built_fmus):
    """tests/under_fmpy.py run on every FMU, once per interpreter: interpreter -> CompletedProcess."""
    runs: dict[Path, subprocess.CompletedProcess] = {}

    def run(python: Path) -> subprocess.CompletedProcess:
        if python not in runs:
            runs[python] = subprocess.run([str(python), str(UNDER_FMPY), *(str(built_fmus[n]) for n in ALL)],
                                          capture_output=True, text=True, timeout=300, env=environment())
        return runs[python]

    return run


@pytest.mark.parametrize("name", ALL)
def test_every_fmu_runs_under_fmpy_from_each_interpreter(every_fmu_under_fmpy, interpreter, name):
    """Instantiate, initialise, three steps, terminate, free, unload: in one process per
    interpreter, all FMUs one after the other (as cosim loads them)."""
    done = every_fmu_under_fmpy(interpreter)
    line = re.search(rf"^loaded {name} (\[.*\])$", done.stdout, re.M)
    assert line, f"{interpreter}: {name} did not load (exit {done.returncode}):\n{done.stdout[-2000:]}{done.stderr[-4000:]}"
    assert all(math.isfinite(value) for value in eval(line.group(1))), line.group(0)


def test_one_python_in_the_process_whatever_the_interpreter(every_fmu_under_fmpy, interpreter):
    """After all 26 FMUs the process maps as many libpython files as a bare one of the same
    interpreter (0 if it links libpython statically, else its own), and exits 0."""
    done = every_fmu_under_fmpy(interpreter)
    assert done.returncode == 0, f"{interpreter}: exit {done.returncode}\n{done.stderr[-4000:]}"
    assert f"libpython-files: {libpython_files(interpreter)}\n" in done.stdout


def test_debian_python3_links_libpython_statically(debian_python):
    """The case these tests are for: no libpython mapped, its symbols are the executable's."""
    assert libpython_files(debian_python) == 0


def test_readme_command_1_runs_with_debian_python3(debian_python, tmp_path):
    """README command 1's run, from a venv of /usr/bin/python3: exit 0 and all four results."""
    cosim = debian_python.parent / "cosim"
    done = subprocess.run([str(cosim), "run", str(ROOT / "ssp" / "pid_fopdt"), "--plot", "--report"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300, env=environment(MPLBACKEND="Agg"))
    assert done.returncode == 0, done.stdout + done.stderr
    for suffix in (".csv", ".json", ".png", ".html"):
        assert (tmp_path / "results" / f"pid_fopdt{suffix}").stat().st_size > 0, suffix
    assert "cosim: report: results/pid_fopdt.html" in done.stdout + done.stderr


def test_fmpy_simulate_runs_with_debian_python3(debian_python, built_fmus, tmp_path):
    """`fmpy simulate build/fmus/Step.fmu` (the issue's second abort): the step from `initial` to
    `final` at `t_step`, over the whole DefaultExperiment."""
    out = tmp_path / "step.csv"
    done = subprocess.run([str(debian_python.parent / "fmpy"), "simulate", str(built_fmus["Step"]), "--output-file",
                           str(out)], capture_output=True, text=True, timeout=300, env=environment(MPLBACKEND="Agg"))
    assert done.returncode == 0, done.stdout + done.stderr
    md = read_model_description(str(built_fmus["Step"]))
    start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    with open(out) as f:
        rows = [(float(r["time"]), float(r["y"])) for r in csv.DictReader(f)]
    assert rows[-1][0] == pytest.approx(float(md.defaultExperiment.stopTime))
    assert {y for t, y in rows if t < start["t_step"] - 1e-9} == {start["initial"]}
    assert {y for t, y in rows if t > start["t_step"] + 1e-9} == {start["final"]}


# ---- a host that embeds Python (tests/dropin_host.c `embed`: its libpython loaded RTLD_LOCAL) ----

@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


def shared_libpython() -> Path:
    """The shared libpython of the interpreter running the tests (skips if it links it statically)."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip(f"{sys.executable} has no shared libpython to embed")
    return Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("INSTSONAME")


def run_pid(host: Path, built_fmus, folder: Path, embedding: list[str], **env: str) -> subprocess.CompletedProcess:
    """PID with r = 1 for 1 s in the C host, after the `embed` command ``embedding``; u in out.csv."""
    fmu = unzip(built_fmus["PID"], folder / "PID")
    return run_host(host, folder / "out.csv", [fmu],
                    embedding + ["set", "0", str(fmu.references["r"]), "1", "record", "0", str(fmu.references["u"]), "u"],
                    0.0, 1.0, 0.1, env=environment(**env))


@pytest.fixture(scope="module")
def loader_started(host, built_fmus, tmp_path_factory) -> np.ndarray:
    """u of the same run where the loader started Python itself (no embedding)."""
    folder = tmp_path_factory.mktemp("plain")
    done = run_pid(host, built_fmus, folder, [])
    assert done.returncode == 0, done.stderr
    return np.genfromtxt(folder / "out.csv", delimiter=",", names=True)["u"]


def test_an_embedding_hosts_initialised_python_is_the_one_used(host, built_fmus, tmp_path, loader_started):
    """The host's Python runs the FMU: no candidate is looked for (GREYFMU_PYTHON names nothing
    that exists, which would be an error if the loader searched), one libpython, same u."""
    purelib = sysconfig.get_paths()["purelib"]  # numpy and scipy, for the host's interpreter
    done = run_pid(host, built_fmus, tmp_path, ["embed", str(shared_libpython()), "init"],
                   PYTHONPATH=purelib, GREYFMU_PYTHON=str(tmp_path / "no-such-python"))
    assert done.returncode == 0, done.stderr
    assert "libpython-files: 1\n" in done.stdout
    u = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)["u"]
    np.testing.assert_array_equal(u, loader_started)
    assert u[-1] > 0  # the controller acted on r = 1


def test_a_loaded_uninitialised_libpython_is_initialised_not_doubled(host, built_fmus, tmp_path, loader_started):
    done = run_pid(host, built_fmus, tmp_path, ["embed", str(shared_libpython()), "load"])
    assert done.returncode == 0, done.stderr
    assert "libpython-files: 1\n" in done.stdout
    np.testing.assert_array_equal(np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)["u"], loader_started)


def test_another_pythons_loaded_libpython_is_refused_or_initialised_with_its_python(host, built_fmus, tmp_path,
                                                                                   debian_python):
    """Debian's shared libpython loaded, not initialised: with GREYFMU_PYTHON naming a Python of
    another build (another libpython; the one running the tests unless it is Debian's, as under
    CI, which runs the suite with Debian's) instantiate refuses with one message naming both;
    naming a Python of that libpython, that libpython is initialised.  (Until issue 39 the first
    half used the FMU's default candidate, the Python that built it: Debian's own under CI.)"""
    from pythons import Unavailable, another_python, bare_venv

    if not DEBIAN_LIBPYTHON.is_file():
        pytest.skip(f"no {DEBIAN_LIBPYTHON} (Debian: apt-get install libpython3.11)")
    try:
        other = bare_venv(another_python())
    except Unavailable as why:
        pytest.skip(str(why))
    refused = run_pid(host, built_fmus, tmp_path / "refused", ["embed", str(DEBIAN_LIBPYTHON), "load"],
                      GREYFMU_PYTHON=str(other))
    assert refused.returncode == 1 and "python-after-instantiate" not in refused.stdout
    assert "this process already has a libpython, not initialised, that is not" in refused.stderr
    assert "set GREYFMU_PYTHON to the Python of the host's libpython" in refused.stderr
    assert "fmi2Instantiate of instance 0 returned NULL" in refused.stderr
    used = run_pid(host, built_fmus, tmp_path / "used", ["embed", str(DEBIAN_LIBPYTHON), "load"],
                   GREYFMU_PYTHON=str(debian_python))
    assert used.returncode == 0, used.stderr
    assert "libpython-files: 1\n" in used.stdout
