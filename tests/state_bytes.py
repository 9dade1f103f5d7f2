"""FMUs' serialised states under this Python, and states restored under it (issue 39, item 9).

    python tests/state_bytes.py save FMU...     one JSON line per FMU: the hex of its serialised
                                                state after 12 steps, then its Real outputs after
                                                4 more steps
    python tests/state_bytes.py restore FILE    FILE: JSON {FMU: hex}; one JSON line per FMU: its
                                                Real outputs after restoring the state into a fresh
                                                instance and 4 more steps

Run by tests/slaves/test_fmu_state.py under two Pythons: Debian's 3.11.2 pickles enum members as
``getattr(class, name)``, other Pythons as ``class(value)``.
"""
from __future__ import annotations

import json
import math
import os
import sys

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

STEP = 0.1


def instance(path: str) -> tuple[FMU2Slave, list[int], list[int]]:
    description = read_model_description(path)
    slave = FMU2Slave(guid=description.guid, unzipDirectory=extract(path),
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="state")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    variables = description.modelVariables
    inputs = [v.valueReference for v in variables if v.causality == "input" and v.type == "Real"]
    outputs = [v.valueReference for v in variables if v.causality == "output" and v.type == "Real"]
    return slave, inputs, outputs


def steps(slave: FMU2Slave, inputs: list[int], first: int, count: int) -> None:
    for k in range(first, first + count):
        if inputs:
            slave.setReal(inputs, [1.0 + 0.5 * math.sin(0.7 * k + i) for i in range(len(inputs))])
        slave.doStep(k * STEP, STEP)


def run(path: str, saved: str | None) -> dict:
    slave, inputs, outputs = instance(path)
    answer = {"fmu": path}
    if saved is None:
        steps(slave, inputs, 0, 12)
        state = slave.getFMUstate()
        answer["state"] = bytes(slave.serializeFMUstate(state)).hex()
    else:
        state = slave.deSerializeFMUstate(bytes.fromhex(saved))
        slave.setFMUstate(state)
    steps(slave, inputs, 12, 4)
    answer["outputs"] = slave.getReal(outputs)
    slave.freeFMUstate(state)
    slave.terminate()
    slave.freeInstance()
    return answer


if __name__ == "__main__":
    if sys.argv[1] == "save":
        runs = [run(path, None) for path in sys.argv[2:]]
    else:
        with open(sys.argv[2]) as file:
            runs = [run(path, saved) for path, saved in json.load(file).items()]
    for answer in runs:
        print(json.dumps(answer))
    sys.stdout.flush()
    os._exit(0)
