"""A tuning's cost against its loops' (issue 44): ``cosim tune`` on ssp/pid_fopdt should take
within 1.5x of (evaluations x one run's loop time / workers + one start-up).

    python benchmarks/bench_tune.py [--evaluations 240] [--workers 2] [--stop 100] [--repeat 3] [--polish 0.2]

The tuning: Kc, Ti, Td of ssp/pid_fopdt (log scales), ITAE of plant.y, stopped at STOP s
(STOP/0.1 steps a run), differential evolution (popsize 8: 24 points a generation; its
Nelder-Mead polish on the last fifth, one point at a time), the local pool of WORKERS
processes, no report (the table and best.ssv only).  The floor, measured
in this process between the tunings: one run's loop time (``loop_seconds`` of the run's
metadata, the median of 20 runs on reused instances, `cosim.run.simulation.run` with a pool) and
one start-up (the wall time of a tuning of a single evaluation, Nelder-Mead with
max_evaluations=1, on the same engine, less one loop time: reading and planning the scenario,
spawning the pool, a worker's imports, its first instantiation, the table).  Prints, best of
REPEAT interleaved rounds, the tuning's wall time, the floor and their ratio (target <= 1.5), and
the same in CPU seconds (this process and its children: ``resource.getrusage``), which a loaded
machine does not distort: evaluations x the run's CPU time (prepare + run, in this process) + the
one-evaluation tuning's CPU time.  With WORKERS > 1 the polish alone, serial, puts the wall floor
1.2x below what the tuning can reach on 2 workers (0.8/2 + 0.2 against 1/2); ``--workers 1``
measures the overhead without it.  On a shared machine WORKERS processes may not get WORKERS cores:
each round also times a pure-Python loop in WORKERS processes at once against one (`parallelism`),
and prints the wall ratio against the floor at that parallelism too.
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cosim.tune import DifferentialEvolution, NelderMead, tune  # noqa: E402

SCENARIO = ROOT / "ssp" / "pid_fopdt"
BOUNDS = {"controller.Kc": (4.0, 60.0, "log"), "controller.Ti": (5.0, 100.0, "log"), "controller.Td": (0.2, 5.0, "log")}


def cpu() -> float:
    """CPU seconds of this process and of its children that have ended (the pool's, after the tuning)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def timed_tuning(method, evaluations: int, workers: int, stop: float) -> tuple[float, float, int]:
    """Wall and CPU seconds of one tuning, and its evaluations."""
    with tempfile.TemporaryDirectory() as tmp:
        wall, used = time.perf_counter(), cpu()
        result = tune(SCENARIO, BOUNDS, objective="ITAE:plant.y", stop_time=stop, method=method,
                      max_evaluations=evaluations, workers=workers, output=tmp, report=False)
        return time.perf_counter() - wall, cpu() - used, len(result.evaluations)


def _spin(n: int) -> int:
    total = 0
    for i in range(n):
        total += i * i
    return total


def parallelism(workers: int, n: int = 3_000_000) -> float:
    """How many cores WORKERS processes get now: WORKERS times one loop's wall time over the wall
    time of WORKERS such loops in WORKERS spawned processes at once (the pool started first)."""
    import concurrent.futures as cf
    import multiprocessing

    with cf.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        list(pool.map(_spin, [1000] * workers))
        began = time.perf_counter()
        list(pool.map(_spin, [n] * workers))
        together = time.perf_counter() - began
        began = time.perf_counter()
        pool.submit(_spin, n).result()
        alone = time.perf_counter() - began
    return workers * alone / together


def one_run(stop: float, runs: int = 20) -> tuple[float, float]:
    """Median loop seconds of ``runs`` runs on reused instances, and the median CPU seconds of one
    run with its preparation (what a worker does for an evaluation)."""
    from cosim.run.instances.reuse import InstancePool
    from cosim.run.simulation import run
    from cosim.plan.prepare import load_scenario, prepare_scenario

    loops, cpus = [], []
    with load_scenario(SCENARIO) as scenario:
        pool = InstancePool()
        try:
            for i in range(runs + 1):
                used = time.process_time()
                prepared = prepare_scenario(scenario, start_values=[f"controller.Kc={4.0 + i * 0.1!r}"], stop_time=stop)
                outcome = run(prepared, pool=pool)
                if i:       # the first instantiates
                    loops.append(outcome.metadata["loop_seconds"])
                    cpus.append(time.process_time() - used)
        finally:
            pool.close()
    return statistics.median(loops), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--evaluations", type=int, default=240)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--stop", type=float, default=100.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--polish", type=float, default=DifferentialEvolution.polish,
                        help="differential evolution's Nelder-Mead share (0: a generation to a batch throughout)")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    best = None
    for round_ in range(args.repeat):
        cores = parallelism(args.workers)
        loop, run_cpu = one_run(args.stop)
        start_wall, start_cpu, _ = timed_tuning(NelderMead(), 1, args.workers, args.stop)
        wall, used, n = timed_tuning(DifferentialEvolution(popsize=8, polish=args.polish), args.evaluations, args.workers, args.stop)
        floor_wall = n * loop / args.workers + (start_wall - loop)
        floor_cpu = n * run_cpu + start_cpu
        floor_here = n * loop / min(cores, args.workers) + (start_wall - loop)
        line = (f"round {round_ + 1}: {n} evaluations, tuning {wall:.2f} s wall / {used:.2f} s CPU; one run's loop "
                f"{1000 * loop:.1f} ms ({1000 * run_cpu:.1f} ms CPU with its preparation), start-up "
                f"{start_wall - loop:.2f} s ({start_cpu:.2f} s CPU); floor {floor_wall:.2f} s wall, {floor_cpu:.2f} s "
                f"CPU; ratio {wall / floor_wall:.2f} wall, {used / floor_cpu:.2f} CPU; the {args.workers} processes "
                f"got {cores:.2f} cores: wall ratio {wall / floor_here:.2f} against that floor")
        print(line, flush=True)
        if best is None or wall / floor_wall < best[0]:
            best = (wall / floor_wall, used / floor_cpu, line)
    print(f"best of {args.repeat}: ratio {best[0]:.2f} wall, {best[1]:.2f} CPU (target <= 1.5); "
          f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
