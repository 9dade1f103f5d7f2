"""Load FMUs one after the other under fmpy in this process, as a user's script would (issue 25).

    python tests/under_fmpy.py FMU...

For each FMU: extract, instantiate (fmpy.fmi2.FMU2Slave), set up, initialise, three steps of
its DefaultExperiment step size, read its Real outputs, terminate, free the instance and unload
the library; prints ``loaded NAME OUTPUTS`` (the outputs as a Python list).  Last it prints
``libpython-files: N``, the number of distinct libpython files mapped into this process (a
second interpreter started by an FMU's loader would make it 2; a Python that links libpython
statically has 0).  Run by tests/slaves/test_pythons.py with each interpreter available.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

STEPS = 3


def run(fmu: Path) -> list[float]:
    """The Real outputs of ``fmu`` after STEPS steps."""
    md = read_model_description(str(fmu))
    folder = extract(str(fmu))
    try:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName=fmu.stem)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        step = float(md.defaultExperiment.stepSize) if md.defaultExperiment and md.defaultExperiment.stepSize else 0.1
        for k in range(STEPS):
            slave.doStep(currentCommunicationPoint=k * step, communicationStepSize=step)
        outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
        values = slave.getReal(outputs) if outputs else []
        slave.terminate()
        slave.freeInstance()
        slave.freeLibrary()
        return values
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def libpython_files() -> int:
    """Distinct libpython files in /proc/self/maps."""
    with open("/proc/self/maps") as maps:
        return len({line.split(None, 5)[5].strip() for line in maps if "libpython" in line})


if __name__ == "__main__":
    for path in sys.argv[1:]:
        print("loaded", Path(path).stem, run(Path(path)), flush=True)
    print("libpython-files:", libpython_files())
