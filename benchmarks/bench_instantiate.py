"""The cost of fmi2Instantiate of our FMUs, next to a C FMU's (issue 25, "Fast instantiation").

    python benchmarks/bench_instantiate.py [--fmus PID FOPDT Step Sum] [--repeat 50]

* ``in-process``: in a fresh Python process that has imported fmpy (what cosim runs in), each
  FMU is extracted once and instantiated ``--repeat + 1`` times through fmpy's FMU2Slave,
  freeing the instance (and, as fmpy does, unloading the library) after each: ``first`` is the
  first instantiation of that FMU in the process (the first FMU also imports numpy and scipy
  and the greyfmu numerics), ``warm`` the median of the later ones.  Timed around
  ``instantiate()`` alone.
* ``C FMU``: the same for a C FMU compiled here (tests/cfmus.py, as the Reference FMUs are
  written: fmi2Instantiate is one calloc).
* ``cold C host``: the wall time of a fresh tests/dropin_host.c process that loads the FMU,
  instantiates, initialises and makes one step (the loader finds a Python, starts it and
  imports the numerics), minus the same process with the C FMU; the best of ``--cold`` runs.

Printed: milliseconds, and each cost as a ratio to the C FMU's.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

C_FMU = "CGain"
"""The C FMU's model identifier: y = u, one input and one output."""


def build_c_fmu_for_comparison(folder: Path) -> Path:
    """A minimal FMI 2.0 CS FMU in C (tests/cfmus.py): y = u."""
    from cfmus import build_c_fmu, fmi2_description

    description = fmi2_description(C_FMU, [("u", 0, "input", 0.0), ("y", 1, "output", None)], {"y": ["u"]},
                                   "{00000000-0000-0000-0000-000000000025}")
    description = description.replace("<ModelVariables>",  # the C host runs the default experiment's step
                                      '<DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/><ModelVariables>')
    body = ("static void start(S *s) {}\nstatic void calculate(S *s) { s->r[1] = s->r[0]; }\n"
            "static int step(S *s, double t, double h) { return 0; }\n")
    return build_c_fmu(folder, C_FMU, description, body)


def in_process(fmus: list[Path], repeat: int) -> dict[str, dict[str, float]]:
    """First and warm instantiate times (s) of each FMU, measured in a fresh Python process."""
    code = f"""
import json, statistics, sys, time
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
result = {{}}
for fmu in {[str(path) for path in fmus]!r}:
    description = read_model_description(fmu)
    folder = extract(fmu)
    times = []
    for k in range({repeat} + 1):
        slave = FMU2Slave(guid=description.guid, unzipDirectory=folder, instanceName=f"i{{k}}",
                          modelIdentifier=description.coSimulation.modelIdentifier)
        start = time.perf_counter()
        slave.instantiate()
        times.append(time.perf_counter() - start)
        slave.freeInstance()
    result[description.modelName] = {{"first": times[0], "warm": statistics.median(times[1:])}}
print(json.dumps(result))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(done.stdout.strip().splitlines()[-1])


def cold_host(host: Path, fmu: Path, folder: Path, runs: int) -> float:
    """The best wall time (s) of a fresh C host process making one step of ``fmu``."""
    from dropinhost import run_host, unzip

    unzipped = unzip(fmu, folder / fmu.stem)
    best = float("inf")
    for _ in range(runs):
        start = time.perf_counter()
        done = run_host(host, folder / f"{fmu.stem}.csv", [unzipped], [], 0.0, unzipped.step, unzipped.step)
        elapsed = time.perf_counter() - start
        if done.returncode != 0:
            raise RuntimeError(f"{fmu.name} in the C host: exit {done.returncode}: {done.stderr[-2000:]}")
        best = min(best, elapsed)
    return best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmus", nargs="+", default=["PID", "FOPDT", "Step", "Sum"])
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--cold", type=int, default=3)
    arguments = parser.parse_args(argv)

    from dropinhost import compile_host
    from greyfmu.build import build_fmus

    ours = {path.stem: path for path in build_fmus(arguments.fmus)}
    with tempfile.TemporaryDirectory(prefix="bench-instantiate-") as temp:
        folder = Path(temp)
        c_fmu = build_c_fmu_for_comparison(folder)
        warm = in_process([ours[name] for name in arguments.fmus] + [c_fmu], arguments.repeat)
        host = compile_host(folder)
        c_cold = cold_host(host, c_fmu, folder, arguments.cold)
        reference = warm[C_FMU]["warm"]
        print(f"{'FMU':<10} {'first ms':>10} {'warm ms':>9} {'warm/C':>8} {'cold host ms':>13} {'cold/C warm':>12}")
        print(f"{C_FMU:<10} {warm[C_FMU]['first'] * 1e3:>10.3f} {reference * 1e3:>9.3f} {1:>8.0f} "
              f"{c_cold * 1e3:>13.1f} {'(floor)':>12}")
        for name in arguments.fmus:
            cold = cold_host(host, ours[name], folder, arguments.cold) - c_cold
            print(f"{name:<10} {warm[name]['first'] * 1e3:>10.1f} {warm[name]['warm'] * 1e3:>9.2f} "
                  f"{warm[name]['warm'] / reference:>8.0f} {cold * 1e3:>13.0f} {cold / reference:>12.0f}")
        print(f"median warm instantiate of ours: {statistics.median(warm[n]['warm'] for n in arguments.fmus) * 1e3:.2f} ms "
              f"(target 10 ms); cold host: the process's wall time minus the C FMU's ({c_cold * 1e3:.1f} ms)")


if __name__ == "__main__":
    main()
