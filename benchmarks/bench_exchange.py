"""Per-call cost of fmi2GetReal / fmi2SetReal on our pythonfmu slaves, before and after the
compiled exchange of ``fmus/_slave.py``.

    python benchmarks/bench_exchange.py [--calls 20000] [--repeat 5]

Two builds of the same benchmark FMU (benchmarks/fmus/Exchange.py: 16 Real inputs, 16 Real
outputs y_i = u_i): ``Exchange`` uses ``GreyfmuSlave``'s exchange, ``ExchangeGeneric``
pythonfmu 0.7.0's generic ``Fmi2Slave.get_real``/``set_real``.  Both are called as
cosim.run.execution calls them: fmpy's raw ctypes function with a preallocated array of 1, 4 or
16 value references and a value array, one batched call per exchange.  Each figure is the
best of ``--repeat`` loops of ``--calls`` calls, in µs per call, including the ctypes call
and pythonfmu's C++ wrapper (list building, method lookup, log buffer), which are the same
for both builds; the builds alternate within each repeat.  The ``doStep`` row is the same
``GreyfmuSlave.do_step`` in both builds (16 input and 16 output checks): the reference for
what one call of the wrapper costs around a slave's own work.
"""
from __future__ import annotations

import argparse
import ctypes
import shutil
import sys
import tempfile
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from pythonfmu.builder import FmuBuilder

from greyfmu.build import SLAVE_FILES

HERE = Path(__file__).resolve().parent / "fmus"
WIDTHS = (1, 4, 16)


def build(dest: Path) -> dict[str, Path]:
    """The fast and the generic build of the benchmark FMU."""
    sys.path.insert(0, str(SLAVE_FILES[0].parent))  # the build imports the slave module
    fast = FmuBuilder.build_FMU(HERE / "Exchange.py", dest=dest, project_files=SLAVE_FILES, needsExecutionTool="false")
    generic = FmuBuilder.build_FMU(HERE / "ExchangeGeneric.py", dest=dest,
                                   project_files=[*SLAVE_FILES, HERE / "Exchange.py"], needsExecutionTool="false")
    return {"generic": Path(generic), "fast": Path(fast)}


def per_call(function, component, vrs, n: int, values, calls: int) -> float:
    """µs per call over one loop of ``calls`` calls."""
    started = time.perf_counter()
    for _ in range(calls):
        function(component, vrs, n, values)
    seconds = time.perf_counter() - started
    status = function(component, vrs, n, values)
    if status != 0:
        raise RuntimeError(f"the FMI call returned status {status}")
    return seconds / calls * 1e6


def open_slave(path: Path, unzipped: str) -> tuple[FMU2Slave, dict[str, int]]:
    md = read_model_description(str(path))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=md.modelName)
    slave.instantiate(loggingOn=False)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    return slave, {v.name: v.valueReference for v in md.modelVariables}


def calls_of(slave: FMU2Slave, vr: dict[str, int]) -> dict[str, tuple]:
    """The timed calls: (function, component, value references, n, values) by label."""
    raw, c = slave._functions, slave.component
    calls = {}
    for n in WIDTHS:
        inputs = (ctypes.c_uint * n)(*[vr[f"u{i}"] for i in range(1, n + 1)])
        outputs = (ctypes.c_uint * n)(*[vr[f"y{i}"] for i in range(1, n + 1)])
        values = (ctypes.c_double * n)(*[0.5 * i for i in range(n)])
        calls[f"set {n}"] = (raw["fmi2SetReal"], c, inputs, n, values)
        calls[f"get {n}"] = (raw["fmi2GetReal"], c, outputs, n, values)
    return calls


def measure(fmus: dict[str, Path], calls: int, repeat: int) -> dict[str, dict[str, float]]:
    """Best of ``repeat`` for every call of both builds, the builds alternating within each
    repeat so that both see the same load on a shared machine."""
    unzipped = {kind: extract(str(path)) for kind, path in fmus.items()}
    slaves = {kind: open_slave(path, unzipped[kind]) for kind, path in fmus.items()}
    try:
        timed = {kind: calls_of(*opened) for kind, opened in slaves.items()}
        best = {kind: {} for kind in fmus}
        for _ in range(repeat):
            for label in timed["fast"]:
                for kind in fmus:
                    us = per_call(*timed[kind][label], calls)
                    best[kind][label] = min(best[kind].get(label, float("inf")), us)
            for kind, (slave, _) in slaves.items():
                do_step, c = slave._functions["fmi2DoStep"], slave.component
                started = time.perf_counter()
                for k in range(calls):
                    do_step(c, k * 0.01, 0.01, 1)
                us = (time.perf_counter() - started) / calls * 1e6
                best[kind]["doStep"] = min(best[kind].get("doStep", float("inf")), us)
        for slave, _ in slaves.values():
            slave.terminate()
            slave.freeInstance()
    finally:
        for folder in unzipped.values():
            shutil.rmtree(folder, ignore_errors=True)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        figures = measure(build(Path(tmp)), args.calls, args.repeat)
    print(f"µs per call, best of {args.repeat} × {args.calls} calls (raw ctypes, one batched call)")
    print(f"{'call':10} {'generic':>9} {'compiled':>9} {'speed-up':>9}")
    for key in figures["fast"]:
        before, after = figures["generic"][key], figures["fast"][key]
        print(f"{key:10} {before:9.2f} {after:9.2f} {before / after:9.2f}")


if __name__ == "__main__":
    main()
