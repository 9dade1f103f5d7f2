"""FMUs one after the other in one fmpy process, as a user's script runs them (issue 39).

    python tests/together_fmpy.py [--host-greyfmu DIR] [--cycles N] FMU...

Run by tests/slaves/test_together.py with a Python that has only fmpy, numpy and scipy (no
greyfmu).  Each FMU is run by ``fmpy.simulate_fmu`` (extracted into a new folder, which fmpy
deletes afterwards) from 0 to 2 s by 0.1 s with inputs r = 2 and y = 0.5 where it has them, and one JSON
line per run gives its outputs at the end: ``{"fmu": path, "outputs": {name: value}}``.  Last, one
JSON line says what the runs left in the process: ``path_added`` (sys.path entries),
``public_added`` (new top-level-public sys.modules names whose module is no file of the host's
Python: the standard library's or its site-packages'), ``private`` (names an FMU added under
``_greyfmu_``), and ``host_greyfmu`` (the file of the host's own greyfmu.control.pid, when one is
imported first with ``--host-greyfmu DIR``).

With ``--cycles N`` each FMU is instead instantiated, initialised, stepped once and freed (library
unloaded, as fmpy does) N times after 20 warm-up cycles, and the line gives ``rss_per_cycle``: the
growth of the process's resident memory per cycle, in bytes.
"""
from __future__ import annotations

import json
import os
import sys
import sysconfig

import fmpy
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

INPUTS = {"r": 2.0, "y": 0.5}


def _unload_plain_pythonfmu_safely() -> None:
    """Another vendor's plain pythonfmu 0.7.0 FMU frees its interpreter state twice when fmpy
    unloads its library (the heap is then corrupt): its finalizePythonInterpreter is called first,
    as a careful host does (cosim.instances.pythonfmu_state).  Our FMUs' loader does it itself and
    does not export the function, so they are unloaded as fmpy does."""
    from fmpy.fmi1 import _FMU

    unload = _FMU.freeLibrary

    def free_library(self) -> None:
        finalize = getattr(self.dll, "finalizePythonInterpreter", None)
        if finalize is not None:
            finalize()
        unload(self)

    _FMU.freeLibrary = free_library


def run(path: str) -> dict[str, float]:
    description = read_model_description(path)
    names = {variable.name for variable in description.modelVariables if variable.causality == "input"}
    outputs = [variable.name for variable in description.modelVariables if variable.causality == "output"]
    result = fmpy.simulate_fmu(path, stop_time=2.0, output_interval=0.1, step_size=0.1, output=outputs,
                               start_values={name: value for name, value in INPUTS.items() if name in names})
    return {name: float(result[name][-1]) for name in outputs}


def resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def rss_per_cycle(path: str, cycles: int) -> float:
    description = read_model_description(path)
    folder = extract(path)

    def cycle() -> None:
        slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                          modelIdentifier=description.coSimulation.modelIdentifier, instanceName="cycled")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.doStep(0.0, 0.1)
        slave.terminate()
        slave.freeInstance()  # fmpy unloads the library here

    for _ in range(20):
        cycle()
    before = resident_bytes()
    for _ in range(cycles):
        cycle()
    return (resident_bytes() - before) / cycles


def hosts_own(module: object) -> bool:
    """Whether ``module`` is the host Python's own: built in, or a file of its standard library or
    of its environment's site-packages (not an FMU's folder)."""
    file = getattr(module, "__file__", None)
    roots = {sysconfig.get_paths()[key] for key in ("stdlib", "platstdlib", "purelib", "platlib")}
    return file is None or any(os.path.abspath(file).startswith(root + os.sep) for root in roots)


def main(arguments: list[str]) -> None:
    host_greyfmu, cycles = None, 0
    while arguments and arguments[0].startswith("--"):
        option, value, *arguments = arguments
        if option == "--host-greyfmu":
            sys.path.insert(0, value)
            import greyfmu.control.pid  # the host's own greyfmu, before any FMU

            host_greyfmu = greyfmu.control.pid
        else:
            cycles = int(value)
    _unload_plain_pythonfmu_safely()
    path_before, modules_before = list(sys.path), dict(sys.modules)
    for path in arguments:
        if cycles:
            print(json.dumps({"fmu": path, "rss_per_cycle": rss_per_cycle(path, cycles)}), flush=True)
        else:
            print(json.dumps({"fmu": path, "outputs": run(path)}), flush=True)
    added = {name: module for name, module in sys.modules.items() if name not in modules_before}
    print(json.dumps({
        "path_added": [entry for entry in sys.path if entry not in path_before],
        "path_removed": [entry for entry in path_before if entry not in sys.path],
        "modules_replaced": sorted(name for name, module in modules_before.items() if sys.modules.get(name) is not module),
        "public_added": sorted(name for name, module in added.items()
                               if not name.startswith("_") and not hosts_own(module)),
        "private": sorted(name for name in added if name.startswith("_greyfmu_")),
        "host_greyfmu": getattr(host_greyfmu, "__file__", None),
        "host_greyfmu_kept": host_greyfmu is None or sys.modules.get("greyfmu.control.pid") is host_greyfmu,
    }), flush=True)
    os._exit(0)  # another vendor's plain pythonfmu FMU aborts at exit without our loader (tests/slaves/test_slave_exchange.py)


if __name__ == "__main__":
    main(sys.argv[1:])
