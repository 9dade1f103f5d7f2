"""One Co-Simulation FMU at a small step: ``cosim run X.fmu`` against ``fmpy.simulate_fmu``.

    python benchmarks/bench_single.py [--steps 100000] [--repeat 3]

The FMU is the C ``Drive`` of tests/single_fmus.py (four inputs, five outputs, a state), run for
``--steps`` communication steps of 1 ms, once with its start values only and once with an input
table (tests/cosim/test_single.py's), in one process.  Each number is the best of ``--repeat``
whole calls (reading the model description, instantiating, stepping, results in memory, no
files): `cosim.plan.prepare.prepare` + `cosim.run.simulation.run`, and ``fmpy.simulate_fmu`` with the
same output interval.  Prints µs per step and the ratio cosim / fmpy.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # the root first: tests/cosim would shadow cosim

import fmpy  # noqa: E402
from fmpy.util import read_csv  # noqa: E402

from cosim.run.simulation import run  # noqa: E402
from cosim.plan.prepare import prepare  # noqa: E402
from single_fmus import build_drive  # noqa: E402

STEP = 1e-3
TABLE = "time,u,d,k,b\n0,0,0,0,0\n20,1,0.5,1,1\n50,1,2,3,1\n50,-1,4,5,0\n100,0.5,4,5,1\n"


def time_cosim(fmu: Path, stop: float, table: Path | None) -> tuple[float, str]:
    started = time.perf_counter()
    prepared = prepare(fmu, stop_time=stop, output_interval=STEP, input_file=table)
    try:
        _, meta = run(prepared)
    finally:
        prepared.close()
    return time.perf_counter() - started, meta["kernel"]


def time_fmpy(fmu: Path, stop: float, table: Path | None) -> float:
    signals = read_csv(str(table)) if table is not None else None
    started = time.perf_counter()
    fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=STEP, input=signals)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    stop = args.steps * STEP
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_drive(Path(tmp))
        table = Path(tmp) / "in.csv"
        table.write_text(TABLE)
        print(f"Drive.fmu (C, FMI 2.0 CS), {args.steps} steps of {STEP:g} s, best of {args.repeat}")
        for label, inputs in (("start values only", None), ("with an input table", table)):
            ours, theirs, kernel = float("inf"), float("inf"), ""
            for _ in range(args.repeat):   # interleaved, so a load change hits both
                seconds, kernel = time_cosim(fmu, stop, inputs)
                ours = min(ours, seconds)
                theirs = min(theirs, time_fmpy(fmu, stop, inputs))
            print(f"  {label:20} cosim ({kernel} kernel) {ours / args.steps * 1e6:7.2f} µs/step   "
                  f"fmpy {theirs / args.steps * 1e6:7.2f} µs/step   cosim / fmpy {ours / theirs:.2f}")


if __name__ == "__main__":
    main()
