"""Issue 13: our FMUs load and run in a host that is not Python (tests/dropin_host.c, compiled here).

The host dlopens an FMU's binaries/linux64 library, as Dymola, OMSimulator or an FMU checker
would; greyfmu's loader (greyfmu/loader/fmi2_loader.c) then finds a Python and starts it inside
the host.  Also: what the loader says when no usable Python is there, and our FMUs inside a
fmu-manipulation-toolbox container (a C++ host) under fmpy.
"""
from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from dropinhost import compile_host, default_experiment, environment, run_host, unzip
from greyfmu.build import fmu_names
from ssdgen import ssd_text, write_system

ALL = fmu_names()


@pytest.fixture(scope="session")
def host(tmp_path_factory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


def read_csv(path: Path) -> np.ndarray:
    return np.genfromtxt(path, delimiter=",", names=True)


@pytest.mark.parametrize("name", ALL)
def test_every_fmu_runs_its_default_experiment_in_a_host_without_python(host, built_fmus, tmp_path, name):
    fmu = unzip(built_fmus[name], tmp_path / name)
    completed = default_experiment(host, fmu, tmp_path / "out.csv")
    assert completed.returncode == 0, completed.stderr
    assert "python-before-instantiate: no" in completed.stdout  # the host had no Python before the FMU
    assert "python-after-instantiate: yes" in completed.stdout  # the loader started one
    result = read_csv(tmp_path / "out.csv")
    steps = round((fmu.stop - fmu.start) / fmu.step)
    assert len(result) == steps + 1 and result["time"][-1] == pytest.approx(fmu.stop)
    for output in fmu.outputs:
        assert np.all(np.isfinite(result[output])), output


def test_pid_fopdt_driven_by_the_c_host_matches_cosim(host, built_fmus, tmp_path):
    """The same closed loop (setpoint step, PID, FOPDT; Jacobi, h = 0.1 s) run by the C host and
    by cosim: the samples agree to rounding."""
    stop, step = 60.0, 0.1
    step_parameters = {"t_step": 1.0, "initial": 0.0, "final": 1.0}
    folder = write_system(
        tmp_path / "loop",
        {name: built_fmus[name.removesuffix(".fmu")] for name in ("Step.fmu", "PID.fmu", "FOPDT.fmu")},
        ssd_text(
            "loop",
            {"setpoint": ("Step.fmu", {"y": "output"}),
             "controller": ("PID.fmu", {"r": "input", "y": "input", "u": "output"}),
             "plant": ("FOPDT.fmu", {"u": "input", "y": "output"})},
            [("setpoint", "y", "controller", "r"), ("plant", "y", "controller", "y"),
             ("controller", "u", "plant", "u")],
            stop=stop, step=step, parameters={"setpoint": step_parameters},
        ),
    )
    expected = cosim.simulate(folder, algorithm="jacobi")
    setpoint, controller, plant = (unzip(built_fmus[name], tmp_path / name) for name in ("Step", "PID", "FOPDT"))
    commands = []
    for parameter, value in step_parameters.items():
        commands += ["set", "0", str(setpoint.references[parameter]), repr(value)]
    for source, output, target, target_input in [(0, setpoint.references["y"], 1, controller.references["r"]),
                                                 (2, plant.references["y"], 1, controller.references["y"]),
                                                 (1, controller.references["u"], 2, plant.references["u"])]:
        commands += ["connect", str(source), str(output), str(target), str(target_input)]
    commands += ["record", "1", str(controller.references["u"]), "u", "record", "2", str(plant.references["y"]), "y"]
    completed = run_host(host, tmp_path / "c.csv", [setpoint, controller, plant], commands, 0.0, stop, step)
    assert completed.returncode == 0, completed.stderr
    assert "python-before-instantiate: no" in completed.stdout
    result = read_csv(tmp_path / "c.csv")
    np.testing.assert_allclose(result["time"], expected["time"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(result["u"], expected["controller.u"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result["y"], expected["plant.y"], rtol=1e-12, atol=1e-12)
    assert result["y"][-1] > 0.9  # the loop did something: y rose from 0 towards r = 1


def make_venv(folder: Path, *extra_paths: str) -> Path:
    """A virtual environment without pip (and without the base interpreter's site-packages);
    each of ``extra_paths`` added to its sys.path by a .pth file."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True)
    site_packages = next(folder.glob("lib/python*/site-packages"))
    if extra_paths:
        (site_packages / "extra.pth").write_text("".join(f"{path}\n" for path in extra_paths))
    return folder / "bin" / "python"


def instantiate_pid(host, built_fmus, tmp_path, **env):
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    return run_host(host, tmp_path / "out.csv", [fmu], ["record", "0", str(fmu.references["u"]), "u"],
                    0.0, 1.0, 0.1, env=environment(**env))


def test_a_venv_named_by_greyfmu_python_is_used_with_its_own_site_packages(host, built_fmus, tmp_path):
    """A venv without numpy is refused although its base interpreter has numpy (the loader uses
    the venv's sys.path, not the base's); the same venv given the packages by a .pth file runs."""
    import numpy
    import scipy

    bare = make_venv(tmp_path / "bare")
    completed = instantiate_pid(host, built_fmus, tmp_path / "a", GREYFMU_PYTHON=str(bare))
    assert completed.returncode == 1
    assert f"{bare} cannot import numpy" in completed.stderr and "-m pip install numpy scipy" in completed.stderr
    assert "fmi2Instantiate of instance 0 returned NULL" in completed.stderr
    packages = {str(Path(module.__file__).parents[1]) for module in (numpy, scipy)}
    provided = make_venv(tmp_path / "provided", *sorted(packages))
    completed = instantiate_pid(host, built_fmus, tmp_path / "b", GREYFMU_PYTHON=str(provided))
    assert completed.returncode == 0, completed.stderr


def test_no_usable_python_is_one_message_and_null(host, built_fmus, tmp_path):
    """GREYFMU_PYTHON naming no interpreter, or a program that is not Python: fmi2Instantiate
    logs why and returns NULL; the host exits by itself (no abort, no hang)."""
    missing = tmp_path / "no" / "python3"
    completed = instantiate_pid(host, built_fmus, tmp_path / "a", GREYFMU_PYTHON=str(missing))
    assert completed.returncode == 1
    assert f"no usable Python: {missing} (GREYFMU_PYTHON) is not an executable file" in completed.stderr
    completed = instantiate_pid(host, built_fmus, tmp_path / "b", GREYFMU_PYTHON="/bin/true")
    assert completed.returncode == 1 and "/bin/true (GREYFMU_PYTHON): /bin/true did not run the check" in completed.stderr
    assert completed.stderr.count("greyfmu: ") == 1


def test_without_greyfmu_python_the_interpreter_that_built_the_fmu_is_used(host, built_fmus, tmp_path):
    completed = instantiate_pid(host, built_fmus, tmp_path, GREYFMU_PYTHON=None, PATH="/nonexistent")
    assert completed.returncode == 0, completed.stderr
    recorded = Path((tmp_path / "PID" / "resources" / "greyfmu_build_python.txt").read_text().strip())
    # the venv's interpreter, under whichever of its names (python, python3) the build ran
    assert recorded.parent == Path(sys.executable).parent and recorded.samefile(sys.executable), recorded


def test_then_python3_on_path(host, built_fmus, tmp_path):
    """With the building interpreter gone, python3 on PATH is tried; one that lacks the
    requirements is named in the message."""
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    (fmu.folder / "resources" / "greyfmu_build_python.txt").write_text(str(tmp_path / "gone" / "python3"))
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "python3").write_text(f'#!/bin/sh\nexec {make_venv(tmp_path / "bare")} "$@"\n')
    (bin_dir / "python3").chmod(0o755)
    completed = run_host(host, tmp_path / "out.csv", [fmu], [], 0.0, 1.0, 0.1,
                         env=environment(GREYFMU_PYTHON=None, PATH=str(bin_dir)))
    assert completed.returncode == 1
    assert f"{bin_dir / 'python3'} (python3 on PATH): " in completed.stderr and "cannot import numpy" in completed.stderr


NOT_UTF8 = os.fsdecode(b"caf\xe9")  # Latin-1 "cafe" with an acute accent: not UTF-8


def test_a_candidate_python_whose_path_is_not_utf8_runs(host, built_fmus, tmp_path):
    """Issue 29: the interpreter, its home and sys.path pass from the query to Python inside the
    host as the file system's bytes (before, as UTF-8 text)."""
    import numpy
    import scipy

    packages = {str(Path(module.__file__).parents[1]) for module in (numpy, scipy)}
    made = make_venv(tmp_path / "venv", *sorted(packages)).parents[1]  # venv cannot write its scripts there
    (tmp_path / NOT_UTF8).mkdir()
    python = made.rename(tmp_path / NOT_UTF8 / "venv") / "bin" / "python"
    completed = instantiate_pid(host, built_fmus, tmp_path / "run", GREYFMU_PYTHON=str(python))
    assert completed.returncode == 0, completed.stderr
    assert "python-after-instantiate: yes" in completed.stdout


def test_an_fmu_in_a_folder_whose_path_is_not_utf8_is_refused_not_a_crash(host, built_fmus, tmp_path):
    """Issue 29: pythonfmu 0.7.0 crashed the host (SIGSEGV) on a resources folder that is not
    UTF-8; the guard refuses it with one line, before Python starts."""
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")  # (fmpy cannot read it there)
    fmu = dataclasses.replace(fmu, folder=fmu.folder.rename(tmp_path / NOT_UTF8))
    completed = run_host(host, tmp_path / "out.csv", [fmu], [], 0.0, 1.0, 0.1)
    assert completed.returncode == 1, completed.stderr
    assert completed.stderr.count("whose path is not UTF-8 text, which pythonfmu 0.7.0 needs") == 1
    assert "fmi2Instantiate of instance 0 returned NULL" in completed.stderr


def test_target_check_refuses_a_python_older_than_3_10(tmp_path):
    """greyfmu_target.py as an old interpreter runs it: sys.version_info faked to 3.9 (no Python
    3.9 exists on this machine)."""
    from greyfmu.loader import TARGET_CHECK

    (tmp_path / "greyfmu_requirements.txt").write_text("numpy\n")
    script = tmp_path / "greyfmu_target.py"
    script.write_text(TARGET_CHECK.read_text())
    fake = ("import sys, runpy\n"
            "class V(tuple):\n"
            "    major, minor = 3, 9\n"
            "sys.version_info = V((3, 9, 18, 'final', 0))\n"
            f"runpy.run_path({str(script)!r}, run_name='__main__')\n")
    completed = subprocess.run([sys.executable, "-c", fake], capture_output=True, text=True, check=True)
    assert "greyfmu-problem=" in completed.stdout
    assert "is Python 3.9, older than 3.10: set GREYFMU_PYTHON" in completed.stdout


def test_osmmgpc_checks_daqp_up_front(host, built_fmus, tmp_path):
    """OSMMGPC needs daqp besides numpy and scipy: an interpreter without it is refused at
    instantiation, naming daqp, instead of failing mid-run."""
    import numpy
    import scipy

    packages = {str(Path(module.__file__).parents[1]) for module in (numpy, scipy)}
    no_daqp = make_venv(tmp_path / "no_daqp", *sorted(packages))
    # numpy's folder may hold daqp too: the venv's own site-packages (searched first) blocks it
    venv_site = next((tmp_path / "no_daqp").glob("lib/python*/site-packages"))
    (venv_site / "daqp.py").write_text("raise ImportError('daqp blocked for this test')\n")
    fmu = unzip(built_fmus["OSMMGPC"], tmp_path / "OSMMGPC")
    completed = run_host(host, tmp_path / "out.csv", [fmu], [], 0.0, 1.0, 1.0,
                         env=environment(GREYFMU_PYTHON=str(no_daqp)))
    assert completed.returncode == 1
    assert "cannot import daqp" in completed.stderr and "-m pip install daqp" in completed.stderr
    assert (fmu.folder / "resources" / "greyfmu_requirements.txt").read_text().split() == ["numpy", "scipy", "daqp"]


def test_fmus_run_inside_a_multithreaded_fmu_manipulation_toolbox_container(built_fmus, tmp_path):
    """Step -> PID <-> FOPDT in a fmu-manipulation-toolbox 2.0 container (its C++ host, parallel
    threads) simulated by fmpy in a fresh process."""
    for name in ("Step", "PID", "FOPDT"):
        (tmp_path / f"{name}.fmu").write_bytes(built_fmus[name].read_bytes())
    (tmp_path / "loop.csv").write_text(
        "rule;from_fmu;from_port;to_fmu;to_port\n"
        "FMU;Step.fmu;;;\nFMU;PID.fmu;;;\nFMU;FOPDT.fmu;;;\n"
        "LINK;Step.fmu;y;PID.fmu;r\nLINK;FOPDT.fmu;y;PID.fmu;y\nLINK;PID.fmu;u;FOPDT.fmu;u\n"
        "OUTPUT;FOPDT.fmu;y;;plant_y\nOUTPUT;PID.fmu;u;;controller_u\n"
    )
    tools = Path(sys.executable).parent
    subprocess.run([str(tools / "fmucontainer"), "-container", "loop.csv:0.1", "-mt"], cwd=tmp_path, check=True,
                   capture_output=True)
    completed = subprocess.run([str(tools / "fmpy"), "simulate", "loop.fmu", "--stop-time", "100",
                                "--output-file", "out.csv"], cwd=tmp_path, capture_output=True, text=True,
                               env=environment(), timeout=300)
    assert completed.returncode == 0, completed.stderr
    result = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    assert result["time"][-1] == pytest.approx(100.0)
    assert math.isfinite(result["plant_y"][-1]) and result["plant_y"][-1] == pytest.approx(1.0, abs=0.05)
