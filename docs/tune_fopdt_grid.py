"""The dense grid search a tuning of ssp/pid_fopdt is checked against (docs/tuning.md,
tests/scenarios/tune/test_known_answers.py).

    python docs/tune_fopdt_grid.py [--workers 2]

The PID of ssp/pid_fopdt (its controller.ssv: N = 10, Ts = 0.1 s, derivative on the
measurement) on the FOPDT plant K = 0.2, T = 20 s, tau = 4 s; the set-point step 0 -> 1 at
10 s, runs stopped at 100 s (before the load step at 150 s).  ITAE of plant.y over the step's
window, on a grid of 20 x 20 x 20 = 8000 points evenly spaced in log10 of Kc in [4, 60], Ti in
[5, 100] s and Td in [0.2, 5] s, run with cosim sweep (no result files).  Writes
docs/data/tune_fopdt_grid.csv: Kc, Ti, Td and ITAE (repr of each float) of every point.
"""
from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "data" / "tune_fopdt_grid.csv"
#: the grid: (parameter, low, high), 20 points each, evenly in log10
AXES = (("controller.Kc", 4.0, 60.0), ("controller.Ti", 5.0, 100.0), ("controller.Td", 0.2, 5.0))
POINTS = 20
STOP = 100.0


def axis(low: float, high: float) -> list[float]:
    """The grid's values of one parameter (what the test recomputes)."""
    return [float(v) for v in np.logspace(np.log10(low), np.log10(high), POINTS)]


def main() -> None:
    from cosim.sweep import sweep

    parser = argparse.ArgumentParser()
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        result = sweep(ROOT / "ssp" / "pid_fopdt", {name: axis(lo, hi) for name, lo, hi in AXES},
                       metrics=["plant.y:setpoint.y"], stop_time=STOP, output=tmp, run_files=False,
                       workers=args.workers, progress=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with open(OUT, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["Kc", "Ti", "Td", "ITAE"])
        for row in result.rows:
            writer.writerow([repr(row[n]) for n, _, _ in AXES] + [repr(row["plant.y:ITAE"])])
    best = min(result.rows, key=lambda r: r["plant.y:ITAE"])
    print(f"{len(result.rows)} runs in {time.perf_counter() - began:.0f} s; failed {len(result.failed)}; best ITAE "
          f"{best['plant.y:ITAE']:.6g} at " + ", ".join(f"{n} = {best[n]:.4g}" for n, _, _ in AXES))


if __name__ == "__main__":
    main()
