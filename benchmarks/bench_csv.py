"""Issue 27: the cost per value of writing a result CSV, with and without pyarrow.

    python benchmarks/bench_csv.py [--rows 4096] [--columns 10] [--chunks 20] [--repeat 5]

Writes ``--chunks`` chunks of ``--rows`` x ``--columns`` float64 (a time column and random
walks, like a run's signals) to a CSV through `cosim.observers.CsvSink`, once with the rows
formatted by Arrow's C++ writer (the writer before issue 27, and the one used when pyarrow is
installed) and once by `cosim.csvformat.format_rows` (used without pyarrow); both write the same
bytes (tests/cosim/test_csvformat.py).  The two are timed ``--repeat`` times, interleaved pair by
pair so a busy machine slows both alike; prints the best time per value of each, the median and
spread of the pairwise ratios (Python / Arrow) and the load average before and after.
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from cosim import observers


def chunk(rows: int, columns: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    walks = np.cumsum(rng.normal(size=(rows, columns - 1)), axis=0)
    return np.column_stack([np.arange(rows) * 0.1, walks])


def seconds_per_value(arrow: bool, rows: np.ndarray, chunks: int, folder: Path) -> float:
    """The time writing ``chunks`` chunks takes, per value, with Arrow's writer or without."""
    observers.ARROW_CSV = arrow
    sink = observers.CsvSink(folder / "bench.csv")
    start = time.perf_counter()
    sink.open([f"c{i}" for i in range(rows.shape[1])])
    for _ in range(chunks):
        sink.write(rows)
    sink.close({})
    return (time.perf_counter() - start) / (rows.size * chunks)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=4096)
    parser.add_argument("--columns", type=int, default=10)
    parser.add_argument("--chunks", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    rows = chunk(args.rows, args.columns)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    pairs = []
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(args.repeat):
            pairs.append((seconds_per_value(True, rows, args.chunks, Path(folder)),
                          seconds_per_value(False, rows, args.chunks, Path(folder))))
    ratios = sorted(python / arrow for arrow, python in pairs)
    print(f"pyarrow writer: {min(a for a, _ in pairs) * 1e9:.0f} ns per value (best)")
    print(f"python writer:  {min(p for _, p in pairs) * 1e9:.0f} ns per value (best)")
    print(f"ratio python / pyarrow: median {statistics.median(ratios):.2f} (spread {ratios[0]:.2f}-{ratios[-1]:.2f})")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
