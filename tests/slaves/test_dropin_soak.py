"""Issue 13: no crash at exit or unload, counted over consecutive runs in fresh processes.

Each run is a new process: ``fmpy simulate`` of a plant (FOPDT), a controller (PID) and
OSMMGPC, and the C test host running Step -> PID <-> FOPDT.  The default suite runs
`RUNS` = 2 of each; ``GREYFMU_SOAK=1`` runs 200 of each, the count the issue asks for, and also
counts the same fmpy runs with pythonfmu's own linux64 library as the binary (the control:
pythonfmu 0.7.0 releases its interpreter state twice at unload, which is what aborted hosts).
The counts are printed (``-s``) and every run of ours must end with exit 0.
"""
from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from collections import Counter
from pathlib import Path

import pytest

from dropinhost import compile_host, environment, run_host, unzip
from greyfmu.loader import PLATFORMS

PYTHONFMU_LIBRARY = PLATFORMS[0].pythonfmu_library  # linux64

SOAK = os.environ.get("GREYFMU_SOAK") == "1"
RUNS = 200 if SOAK else 2
FMPY_RUNS = {"FOPDT": [], "PID": [], "OSMMGPC": ["--stop-time", "10"]}


def exit_codes(command: list[str], runs: int, cwd: Path, env: dict[str, str]) -> Counter:
    codes = Counter()
    for _ in range(runs):
        codes[subprocess.run(command, cwd=cwd, env=env, capture_output=True, timeout=300).returncode] += 1
    return codes


def fmpy_command(fmu: Path, options: list[str]) -> list[str]:
    return [str(Path(sys.executable).parent / "fmpy"), "simulate", str(fmu), *options]


@pytest.mark.parametrize("name", sorted(FMPY_RUNS))
def test_consecutive_fmpy_simulate_runs_all_exit_0(built_fmus, tmp_path, name):
    codes = exit_codes(fmpy_command(built_fmus[name], FMPY_RUNS[name]), RUNS, tmp_path, environment())
    print(f"\nfmpy simulate {name}: {RUNS} runs, exit codes {dict(codes)}")
    assert codes == Counter({0: RUNS})


def test_consecutive_c_host_runs_all_exit_0(built_fmus, tmp_path):
    host = compile_host(tmp_path)
    setpoint, controller, plant = (unzip(built_fmus[name], tmp_path / name) for name in ("Step", "PID", "FOPDT"))
    commands = ["connect", "0", str(setpoint.references["y"]), "1", str(controller.references["r"]),
                "connect", "2", str(plant.references["y"]), "1", str(controller.references["y"]),
                "connect", "1", str(controller.references["u"]), "2", str(plant.references["u"]),
                "record", "2", str(plant.references["y"]), "y"]
    codes = Counter()
    for _ in range(RUNS):
        codes[run_host(host, tmp_path / "out.csv", [setpoint, controller, plant], commands, 0.0, 10.0, 0.1).returncode] += 1
    print(f"\nC host Step->PID<->FOPDT: {RUNS} runs, exit codes {dict(codes)}")
    assert codes == Counter({0: RUNS})


def with_pythonfmu_binary(fmu: Path, target: Path) -> Path:
    """A copy of ``fmu`` whose linux64 binary is pythonfmu's own library again (no loader)."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as copy:
        names = source.namelist()
        identifier = next(name for name in names if name.startswith("binaries/linux64/") and
                          not name.endswith(PYTHONFMU_LIBRARY)).removeprefix("binaries/linux64/")
        for name in names:
            if name == f"binaries/linux64/{identifier}":
                continue
            data = source.read(name)
            copy.writestr(f"binaries/linux64/{identifier}" if name.endswith(PYTHONFMU_LIBRARY) else name, data)
    return target


@pytest.mark.skipif(not SOAK, reason="the control counts run with GREYFMU_SOAK=1")
@pytest.mark.parametrize("name", sorted(FMPY_RUNS))
def test_control_pythonfmu_library_without_the_loader(built_fmus, tmp_path, name):
    """Not an assertion on our FMUs: how often the same runs end abnormally with pythonfmu's
    library as the binary, to show what the loader removes."""
    control = with_pythonfmu_binary(built_fmus[name], tmp_path / f"{name}.fmu")
    codes = exit_codes(fmpy_command(control, FMPY_RUNS[name]), RUNS, tmp_path, environment())
    print(f"\ncontrol (pythonfmu's binary) fmpy simulate {name}: {RUNS} runs, exit codes {dict(codes)}")
    assert sum(codes.values()) == RUNS
