"""Cost of the crash-safe journal (issue 17): ``pid_fopdt`` run to a CSV with and without
its memory-mapped journal (`cosim.journal`), and with and without the supervising parent
process of `cosim run` (`cosim.supervisor`: one fork per run, nothing per step).

    python benchmarks/bench_journal.py [--steps 50000] [--repeat 5]

Each number is the best of ``--repeat`` runs of the stepping loop (``loop_seconds`` of the
metadata: the recorder's per-row counter store and its window reservations are in it) and of
the whole `cosim run` command; prints µs per step and the ratios (the budget is 1.05).
"""
from __future__ import annotations

import argparse
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
        _, meta = cosim.simulation.run(prepared, output=output, journal=journal)
    finally:
        prepared.close()
    return meta["loop_seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    stop = args.steps * STEP
    with tempfile.TemporaryDirectory() as tmp:
        ssp = str(Path(tmp) / "pid_fopdt.ssp")
        cosim_main(["pack", str(ROOT / "ssp" / "pid_fopdt"), "-o", ssp])
        out = Path(tmp) / "r.csv"
        best = {"no journal": float("inf"), "journal": float("inf")}
        for _ in range(args.repeat):  # interleaved, so a busy machine slows both alike
            for name, journal in (("no journal", False), ("journal", True)):
                best[name] = min(best[name], loop_seconds(ssp, stop, out, journal))
        command = float("inf")
        for _ in range(args.repeat):
            started = time.perf_counter()
            cosim_main(["run", ssp, "-q", "--stop", str(stop), "-o", str(out)])
            command = min(command, time.perf_counter() - started)
    print(f"pid_fopdt, {args.steps} steps to a CSV, best of {args.repeat}:")
    for name, seconds in best.items():
        print(f"  loop, {name:10}: {seconds / args.steps * 1e6:7.2f} µs/step")
    print(f"  journal / no journal: {best['journal'] / best['no journal']:.3f}")
    print(f"  cosim run (supervised, journal), whole command: {command:.2f} s")


if __name__ == "__main__":
    main()
