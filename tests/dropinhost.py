"""The C test host of tests/dropin_host.c: compile it, lay out an FMU for it, run an experiment.

The host is a separate process with no Python of its own; it loads the FMU's linux64 binary
by dlopen, as Dymola, OMSimulator or an FMU checker would.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

from fmpy import read_model_description

HOST_SOURCE = Path(__file__).resolve().parent / "dropin_host.c"


def compile_host(folder: Path, source: Path = HOST_SOURCE) -> Path:
    """tests/dropin_host.c (or another C host, benchmarks/step_host.c) compiled with the system
    compiler into ``folder``."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise RuntimeError(f"no C compiler (cc or gcc) on PATH: {source.name} cannot be built")
    host = folder / source.stem
    subprocess.run([compiler, "-O1", "-Wall", "-Werror", "-o", str(host), str(source), "-ldl"], check=True)
    return host


@dataclass(frozen=True)
class UnzippedFmu:
    """An FMU extracted for the host, with what the host's command line needs from its model description."""

    folder: Path
    identifier: str
    guid: str
    references: dict[str, int]
    outputs: list[str]
    start: float
    stop: float
    step: float

    def arguments(self) -> list[str]:
        return ["fmu", str(self.folder), self.identifier, self.guid]


def unzip(fmu: Path, folder: Path) -> UnzippedFmu:
    """Extract ``fmu`` into ``folder`` (binaries keep their execute permission)."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    for library in (folder / "binaries" / "linux64").iterdir():
        library.chmod(0o755)
    md = read_model_description(str(folder))
    experiment = md.defaultExperiment
    return UnzippedFmu(
        folder=folder,
        identifier=md.coSimulation.modelIdentifier,
        guid=md.guid,
        references={v.name: v.valueReference for v in md.modelVariables},
        outputs=[v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"],
        start=float(experiment.startTime or 0.0),
        stop=float(experiment.stopTime),
        step=float(experiment.stepSize),
    )


def environment(**changes: str | None) -> dict[str, str]:
    """This process's environment without PYTHONPATH/PYTHONHOME (a foreign host has neither), changed."""
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "PYTHONHOME")}
    for key, value in changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    return env


def run_host(host: Path, csv: Path, fmus: list[UnzippedFmu], commands: list[str], start: float, stop: float,
             step: float, env: dict[str, str] | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run the host on ``fmus`` (instances 0, 1, ... in this order) with ``commands`` (set/connect/record)."""
    arguments = [str(host), str(csv), repr(start), repr(stop), repr(step)]
    for fmu in fmus:
        arguments += fmu.arguments()
    # surrogateescape: a path in the host's messages need not be UTF-8 (test_dropin_host.py)
    return subprocess.run(arguments + commands, capture_output=True, text=True, errors="surrogateescape", timeout=timeout,
                          env=environment() if env is None else env, cwd=csv.parent)


def default_experiment(host: Path, fmu: UnzippedFmu, csv: Path,
                       env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``fmu`` alone over its DefaultExperiment, recording every Real output."""
    commands = []
    for name in fmu.outputs:
        commands += ["record", "0", str(fmu.references[name]), name]
    return run_host(host, csv, [fmu], commands, fmu.start, fmu.stop, fmu.step, env)
