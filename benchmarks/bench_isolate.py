"""Cost of ``--isolate`` (issue 17): µs per communication step with every component in a
process of its own (`cosim.run.instances.isolated`) against the same run in one process.

    python benchmarks/bench_isolate.py [--steps 5000] [--repeat 7]

Two systems, run to memory (no file) through `cosim.run.simulation.run`, the stepping loop timed
(metadata ``loop_seconds``), in-process and isolated runs interleaved so a busy machine slows
both alike:

- ``pid_fopdt`` (4 of our pythonfmu FMUs: set-point, load, PID, FOPDT plant);
- a chain of 10 C FMUs (FMI 2.0, compiled here with tests/cfmus.py): y = x, x' = u − x by
  explicit Euler per step, no feedthrough, so per FMU and step one fmi2DoStep, one
  fmi2GetReal and one fmi2SetReal: each a round trip to the component's process under
  ``--isolate``.

Prints the median and the spread (min–max) of µs/step for each, the median of the pairwise
ratios isolated / in-process, the added µs per FMU call (the round trip), and the load average.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import cosim  # noqa: E402
from cfmus import build_c_fmu  # noqa: E402
from ssdgen import ssd_text, write_system  # noqa: E402

LAG = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Lag" guid="{9e0c0000-0000-4000-8000-0000000000a1}">
  <CoSimulation modelIdentifier="Lag" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input" variability="continuous"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output" variability="continuous" initial="exact">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""
LAG_BODY = """
static void start(S *s) { s->r[0] = 1.0; s->r[1] = 0.0; }
static void calculate(S *s) { }
static int step(S *s, double t, double h) { s->r[1] += h * (s->r[0] - s->r[1]); return 0; }
"""
N_LAGS = 10


def lag_chain(folder: Path) -> Path:
    fmu = build_c_fmu(folder / "fmu", "Lag", LAG, LAG_BODY, "2.0")
    comps = {f"c{i}": ("Lag.fmu", {"u": "input", "y": "output"}) for i in range(N_LAGS)}
    wires = [(f"c{i}", "y", f"c{i + 1}", "u") for i in range(N_LAGS - 1)]
    return write_system(folder / "chain", {"Lag.fmu": fmu}, ssd_text("lag_chain", comps, wires, stop=1.0, step=0.01))


def loop_us(path, steps: int, step: float, isolate: bool) -> float:
    prepared = cosim.prepare(path, stop_time=steps * step, step_size=step)
    try:
        _, meta = cosim.run.simulation.run(prepared, keep=[], isolate=isolate)
    finally:
        prepared.close()
    return meta["loop_seconds"] / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        systems = {"pid_fopdt (4 pythonfmu FMUs)": (str(ROOT / "ssp" / "pid_fopdt"), 0.1, 4),
                   f"chain of {N_LAGS} C FMUs": (lag_chain(Path(tmp)), 0.01, N_LAGS)}
        times = {name: {False: [], True: []} for name in systems}
        for _ in range(args.repeat):
            for name, (path, step, _) in systems.items():
                for isolate in (False, True):
                    times[name][isolate].append(loop_us(path, args.steps, step, isolate))
    print(f"--isolate, {args.steps} steps, {args.repeat} interleaved repeats; load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores")
    for name, (_, _, n) in systems.items():
        inproc, isolated = times[name][False], times[name][True]
        ratios = [b / a for a, b in zip(inproc, isolated)]
        added = statistics.median(isolated) - statistics.median(inproc)
        print(f"  {name}:")
        print(f"    in process: {statistics.median(inproc):8.1f} µs/step ({min(inproc):.1f}–{max(inproc):.1f})")
        print(f"    isolated:   {statistics.median(isolated):8.1f} µs/step ({min(isolated):.1f}–{max(isolated):.1f})")
        print(f"    isolated / in process: ×{statistics.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f}); "
              f"+{added:.0f} µs/step, +{added / n:.1f} µs per FMU and step")


if __name__ == "__main__":
    main()
