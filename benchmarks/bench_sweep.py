"""Sweep speed-up: the same 20 runs one after the other in one process, then on a process pool;
and (``--throughput``) a sweep's throughput against its loops' (issue 28).

    python benchmarks/bench_sweep.py [--scenario ssp/grey_noise] [--runs 20] [--stop 10000] [--workers 2]
                                     [--dask] [--cluster]
    python benchmarks/bench_sweep.py --throughput [--runs 200] [--steps 1000] [--workers 2] [--dask] [--fmus-from DIR]

``--throughput``: ``ssp/pid_fopdt`` swept over RUNS values of controller.Kc, STEPS steps of its
0.1 s step each, on the local pool of WORKERS processes (``--dask``: also a Dask LocalCluster of as
many), three ways: ``fresh`` (``reuse=False``: every run read, checked and instantiated afresh,
the path before issue 28), ``reused`` (the default: each worker keeps the scenario and its reset
instances, `cosim.sweep.worker`; per-run files written) and ``table only`` (``run_files=False``).
Each prints runs/s and its wall time against the loop-only ideal: the sum of the runs' loop
times (``loop_seconds`` of their metadata; the table-only sweep writes none, the reused sweep's
stand in) over WORKERS, plus one start-up (the wall time of a one-run sweep on the same engine
less its loop: the parent's preparation, a worker's spawn, imports and first instantiation).
Target: within 2x of the ideal.

Both sweeps go through `cosim.sweep.sweep` with the same scenario and seeds 1..RUNS (the
scenario's band-limited white noise seed), so each run does the same work: prepare, run,
write the result CSV and metadata, compute the step metrics.  ``serial`` runs them in this
process; ``process`` hands them to a spawn-started pool of ``--workers`` processes
(``--dask`` also times a Dask LocalCluster of as many worker processes; ``--cluster`` a real
``dask scheduler`` with ``--workers`` separate ``dask worker`` processes reached by address, the
scenario shipped to them as a package, and the per-run cost of that shipping: the time
`cosim.sweep.shipping` adds around one run -- pickling the run and its parameter sets, the
worker's unpacked copy of the package, writing the parameter sets, reading the result files
back and writing them on the client -- for the first run, which unpacks the package, and the
mean of the others, against a 1 s run).  The default stop
time makes one ``grey_noise`` run (8 FMUs, 0.1 s step) take about 10 s on our 2-core
machine.  Prints the wall times, the speed-up and whether the two tables agree (same run
ids, same metrics).  Run it by hand on an otherwise idle machine; it takes minutes.  Before and
after, it times a pure-Python loop in WORKERS processes against the same loops one after the
other: that ratio is what the machine offers at that moment (less than WORKERS when other jobs
share the cores), against which the sweep's speed-up is to be read.
"""
from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import pickle
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
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


@contextmanager
def dask_cluster(workers: int, folder: Path):
    """A ``dask scheduler`` and WORKERS ``dask worker`` processes (one thread each); yields the address."""
    dask = str(Path(sys.executable).with_name("dask"))
    file = folder / "scheduler.json"
    processes = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                   "--scheduler-file", str(file)], stderr=subprocess.DEVNULL)]
    try:
        while not (file.is_file() and file.read_text()):
            time.sleep(0.2)
        address = json.loads(file.read_text())["address"]
        processes += [subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-nanny",
                                        "--no-dashboard"], stderr=subprocess.DEVNULL) for _ in range(workers)]
        from distributed import Client
        with Client(address) as client:
            client.wait_for_workers(workers, timeout=120)
        yield address
    finally:
        for p in processes:
            p.terminate()
            p.wait()


def shipping_overhead(scenario: str, runs: int, stop: float, folder: Path) -> tuple[float, float, float]:
    """Seconds shipping adds around the first run and (mean) around the others, and a run's own seconds."""
    from cosim.safeio import max_unpacked_bytes
    from cosim.plan.prepare import prepare
    from cosim.model.structure import ParameterValue
    from cosim.sweep.dispatch import Task
    from cosim.sweep.shipping import deliver, execute_shipped, package_of, parameter_set_bytes
    from cosim.sweep.values import Metric, write_ssv

    prepared = prepare(scenario, stop_time=stop)
    try:
        package, grid, algorithm = package_of(prepared), prepared.grid, prepared.algorithm
    finally:
        prepared.close()
    tempfile.tempdir = str(folder / "worker_tmp")     # this "worker" starts with an empty cache
    Path(tempfile.tempdir).mkdir()
    (folder / "runs").mkdir()
    overheads, walls = [], []
    for seed in range(1, runs + 1):
        ssv = folder / "runs" / f"run{seed}.ssv"
        write_ssv(ssv, [ParameterValue("noise.seed", "Integer", seed, "bench", 0)], name="bench")
        task = Task(f"run{seed}", scenario, (str(ssv),), (), grid.start, grid.stop, grid.step, algorithm,
                    str(folder / "runs" / f"run{seed}.csv"), (Metric("measurement.y", "u.y"),),
                    max_unpacked_bytes()[0])
        began = time.perf_counter()
        shipped_task, sets = pickle.loads(pickle.dumps((task, parameter_set_bytes(task))))
        row, files = pickle.loads(pickle.dumps(execute_shipped(shipped_task, package, sets)))
        deliver(task, files)
        total = time.perf_counter() - began
        if row["status"] != "completed":
            sys.exit(f"shipped run {seed}: {row['message']}")
        overheads.append(total - row["wall_time"])
        walls.append(row["wall_time"])
    tempfile.tempdir = None
    return overheads[0], sum(overheads[1:]) / max(1, len(overheads) - 1), sum(walls) / len(walls)


def _loops(out: Path) -> list[float]:
    return [json.loads(p.read_text())["loop_seconds"] for p in (out / "runs").glob("*.json")]


def throughput(runs: int, steps: int, workers: int, dask: bool, fmus_from: Path | None = None) -> None:
    """The ``--throughput`` benchmark (see the module docstring); ``fmus_from``: a folder of FMUs the
    scenario takes its FMUs from (copied into its resources/) instead of the FMU provider's build/fmus."""
    scenario = str(ROOT / "ssp" / "pid_fopdt")
    stop = steps * 0.1
    gains = [2.0 + 6.0 * i / max(1, runs - 1) for i in range(runs)]
    engines = [("process", "process")] + ([("dask", f"local:{workers}")] if dask else [])
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        if fmus_from is not None:
            scenario = str(shutil.copytree(scenario, Path(tmp) / "pid_fopdt"))
            (Path(scenario) / "resources").mkdir(exist_ok=True)
            for name in ("Step", "PID", "FOPDT"):
                shutil.copy(fmus_from / f"{name}.fmu", Path(scenario) / "resources")
        sweep(scenario, {"controller.Kc": gains[:1]}, stop_time=stop, output=Path(tmp) / "warm",
              executor="serial")     # our FMUs built, the FMU cache filled: not timed
        for label, executor in engines:
            one = Path(tmp) / f"{label}-one"
            began = time.perf_counter()
            sweep(scenario, {"controller.Kc": gains[:1]}, stop_time=stop, output=one, executor=executor,
                  workers=workers, force=True)
            startup = time.perf_counter() - began - sum(_loops(one))
            print(f"{label}: start-up (a one-run sweep less its loop) {startup:.2f} s")
            loops_of: dict[str, list[float]] = {}
            for case, options in (("fresh", dict(reuse=False)), ("reused", {}),
                                  ("table only", dict(run_files=False))):
                out = Path(tmp) / f"{label}-{case}"
                began = time.perf_counter()
                result = sweep(scenario, {"controller.Kc": gains}, stop_time=stop, output=out, executor=executor,
                               workers=workers, force=True, **options)
                wall = time.perf_counter() - began
                bad = [r for r in result.rows if r["status"] != "completed"]
                if bad:
                    sys.exit(f"{label} {case}: {len(bad)} runs did not complete: {bad[0]['message']}")
                loops_of[case] = _loops(out) or loops_of["reused"]
                loops = loops_of[case]
                ideal = sum(loops) / workers + startup
                per_run = statistics.median(r["wall_time"] for r in result.rows)   # not a worker's first
                print(f"{label:>8} {case:>10}: {wall:6.2f} s = {runs / wall:6.1f} runs/s; ideal {ideal:5.2f} s "
                      f"(loops {sum(loops):.2f} s / {workers} + start-up) -> {wall / ideal:.2f}x the ideal; "
                      f"a run {per_run * 1e3:.1f} ms in its worker (median), its loop {statistics.median(loops) * 1e3:.1f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(ROOT / "ssp" / "grey_noise"))
    parser.add_argument("--runs", type=int, help="runs of the sweep (default 20; --throughput: 200)")
    parser.add_argument("--stop", type=float, default=10000.0, help="stop time [s] of each run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dask", action="store_true", help="also time a Dask LocalCluster")
    parser.add_argument("--cluster", action="store_true",
                        help="also time a dask scheduler and --workers dask worker processes, and the shipping")
    parser.add_argument("--throughput", action="store_true",
                        help="pid_fopdt runs/s: fresh instances, reused, table only, against the loops' ideal")
    parser.add_argument("--steps", type=int, default=1000, help="--throughput: steps of each run")
    parser.add_argument("--fmus-from", type=Path, help="--throughput: take pid_fopdt's FMUs from this folder "
                                                       "(e.g. built at another commit) instead of build/fmus")
    args = parser.parse_args()
    if args.throughput:
        print(f"machine: a CPU-bound loop in {args.workers} processes runs {machine_speedup(args.workers):.2f}x "
              "faster than one after the other")
        throughput(args.runs or 200, args.steps, args.workers, args.dask, args.fmus_from)
        print(f"machine after: {machine_speedup(args.workers):.2f}x")
        return
    args.runs = args.runs or 20
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
        if args.cluster:
            with dask_cluster(args.workers, Path(tmp)) as address:
                cluster, d = timed("cluster", args.scenario, args.runs, args.stop, address, args.workers,
                                   Path(tmp) / "cluster")
            print(f"speed-up Dask cluster ({args.workers} dask worker processes, scenario shipped) / serial: "
                  f"{serial / cluster:.2f}x, / process pool: {pool / cluster:.2f}x; {same_tables(a, d)}")
            (Path(tmp) / "shipping").mkdir()
            first, after, run_seconds = shipping_overhead(args.scenario, min(args.runs, 6), args.stop,
                                                          Path(tmp) / "shipping")
            print(f"shipping: {first * 1e3:.1f} ms around the first run (unpacking the package), "
                  f"{after * 1e3:.1f} ms around each later one = {after / 1.0:.2%} of a 1 s run "
                  f"(these runs: {run_seconds:.2f} s, overhead {after / run_seconds:.2%})")
    print(f"machine after: {machine_speedup(args.workers):.2f}x")


if __name__ == "__main__":
    main()
