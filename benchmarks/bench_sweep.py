"""Sweep speed-up: the same 20 runs one after the other in one process, then on a process pool.

    python benchmarks/bench_sweep.py [--scenario ssp/grey_noise] [--runs 20] [--stop 10000] [--workers 2]
                                     [--dask]

Both sweeps go through `cosim.sweep.sweep` with the same scenario and seeds 1..RUNS (the
scenario's band-limited white noise seed), so each run does the same work: prepare, run,
write the result CSV and metadata, compute the step metrics.  ``serial`` runs them in this
process; ``process`` hands them to a spawn-started pool of ``--workers`` processes
(``--dask`` also times a Dask LocalCluster of as many worker processes).  The default stop
time makes one ``grey_noise`` run (8 FMUs, 0.1 s step) take about 10 s on our 2-core
machine.  Prints the wall times, the speed-up and whether the two tables agree (same run
ids, same metrics).  Run it by hand on an otherwise idle machine; it takes minutes.  Before and
after, it times a pure-Python loop in WORKERS processes against the same loops one after the
other: that ratio is what the machine offers at that moment (less than WORKERS when other jobs
share the cores), against which the sweep's speed-up is to be read.
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cosim.sweep import sweep


def timed(label: str, scenario: str, runs: int, stop: float, executor, workers: int, out: Path):
    began = time.perf_counter()
    result = sweep(scenario, {}, seeds=list(range(1, runs + 1)), metrics=["measurement.y:u.y"],
                   stop_time=stop, output=out, executor=executor, workers=workers, force=True)
    wall = time.perf_counter() - began
    failed = [r for r in result.rows if r["status"] != "completed"]
    if failed:
        sys.exit(f"{label}: {len(failed)} runs did not complete: {failed[0]['message']}")
    per_run = sum(r["wall_time"] for r in result.rows) / len(result.rows)
    print(f"{label:>8}: {wall:7.1f} s for {runs} runs ({per_run:.2f} s per run inside the worker)")
    return wall, result


def _loop(n: int = 20_000_000) -> float:
    began = time.perf_counter()
    total = 0
    for i in range(n):
        total += i
    return time.perf_counter() - began


def machine_speedup(workers: int) -> float:
    """Serial / parallel wall time of WORKERS equal CPU-bound loops: the parallelism available now."""
    began = time.perf_counter()
    for _ in range(workers):
        _loop()
    serial = time.perf_counter() - began
    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        pool.apply(_loop, (1000,))      # start the processes before timing
        began = time.perf_counter()
        pool.map(_loop, [20_000_000] * workers)
        parallel = time.perf_counter() - began
    return serial / parallel


def same_tables(a, b) -> str:
    """Same metrics seed by seed, and whether the run ids match too (they differ when an FMU
    was rebuilt in between, since the id covers the FMU's contents)."""
    def metrics(result):
        return {r["seed"]: [None if isinstance(v, float) and math.isnan(v) else v
                            for k, v in r.items() if k.startswith("measurement.y:")] for r in result.rows}
    ids = [r["run_id"] for r in a.rows] == [r["run_id"] for r in b.rows]
    return f"same metrics: {metrics(a) == metrics(b)}, same run ids: {ids}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(ROOT / "ssp" / "grey_noise"))
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--stop", type=float, default=10000.0, help="stop time [s] of each run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dask", action="store_true", help="also time a Dask LocalCluster")
    args = parser.parse_args()
    print(f"machine: a CPU-bound loop in {args.workers} processes runs {machine_speedup(args.workers):.2f}x "
          "faster than one after the other")
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        serial, a = timed("serial", args.scenario, args.runs, args.stop, "serial", 1, Path(tmp) / "serial")
        pool, b = timed("process", args.scenario, args.runs, args.stop, "process", args.workers, Path(tmp) / "pool")
        print(f"speed-up process pool ({args.workers} workers) / serial: {serial / pool:.2f}x; "
              f"{same_tables(a, b)}")
        if args.dask:
            dask, c = timed("dask", args.scenario, args.runs, args.stop, f"local:{args.workers}", args.workers,
                            Path(tmp) / "dask")
            print(f"speed-up Dask LocalCluster ({args.workers} workers) / serial: {serial / dask:.2f}x; "
                  f"{same_tables(a, c)}")
    print(f"machine after: {machine_speedup(args.workers):.2f}x")


if __name__ == "__main__":
    main()
