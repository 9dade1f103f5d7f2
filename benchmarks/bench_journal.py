"""Cost of the crash-safe journal (issue 17): ``pid_fopdt`` run to a CSV with and without
its memory-mapped journal (`cosim.record.journal`), and with and without the supervising parent
process of `cosim run` (`cosim.run.supervisor`: one fork per run, nothing per step).

    python benchmarks/bench_journal.py [--steps 50000] [--repeat 15]

The stepping loop (``loop_seconds`` of the metadata: the recorder's per-row counter store and
its window reservations are in it) is timed ``--repeat`` times with and without the journal,
the two interleaved pair by pair so a busy machine slows both alike; prints the median and the
spread (min–max) of µs per step, the median and spread of the pairwise ratios journal / no
journal (the budget is 1.05), the load average before and after, and the best whole `cosim
run` command.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

import cosim  # noqa: E402
from cosim.cli import main as cosim_main  # noqa: E402

STEP = 0.1


def loop_seconds(ssp: str, stop: float, output: Path, journal: bool) -> float:
    prepared = cosim.prepare(ssp, stop_time=stop, use_providers=False)
    try:
        _, meta = cosim.run.simulation.run(prepared, output=output, journal=journal)
    finally:
        prepared.close()
    return meta["loop_seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    stop = args.steps * STEP
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        ssp = str(Path(tmp) / "pid_fopdt.ssp")
        cosim_main(["pack", str(ROOT / "ssp" / "pid_fopdt"), "-o", ssp])
        out = Path(tmp) / "r.csv"
        runs: dict[str, list[float]] = {"no journal": [], "journal": []}
        for k in range(args.repeat):  # interleaved, so a busy machine slows both alike; the order alternates
            order = (("no journal", False), ("journal", True))
            for name, journal in order if k % 2 == 0 else order[::-1]:
                runs[name].append(loop_seconds(ssp, stop, out, journal) / args.steps * 1e6)
        command = float("inf")
        for _ in range(min(args.repeat, 3)):
            started = time.perf_counter()
            cosim_main(["run", ssp, "-q", "--stop", str(stop), "-o", str(out)])
            command = min(command, time.perf_counter() - started)
    ratios = [j / n for n, j in zip(runs["no journal"], runs["journal"])]
    print(f"pid_fopdt, {args.steps} steps to a CSV, {args.repeat} interleaved pairs; load average "
          f"{' '.join(f'{x:.2f}' for x in load_before)} before, {' '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"after, {os.cpu_count()} cores:")
    for name, us in runs.items():
        print(f"  loop, {name:10}: median {statistics.median(us):7.2f} µs/step ({min(us):.2f}–{max(us):.2f}), "
              f"best {min(us):.2f}")
    print(f"  journal / no journal: median ×{statistics.median(ratios):.3f} ({min(ratios):.3f}–{max(ratios):.3f}); "
          f"of the bests ×{min(runs['journal']) / min(runs['no journal']):.3f}")
    print(f"  cosim run (supervised, journal), whole command: best {command:.2f} s")


if __name__ == "__main__":
    main()
