"""Issue 27: the cost per value of writing a result CSV, with and without pyarrow.

    python benchmarks/bench_csv.py [--rows 4096] [--columns 10] [--chunks 20] [--repeat 5]

Writes ``--chunks`` chunks of ``--rows`` x ``--columns`` float64 (a time column and random
walks, like a run's signals) to a CSV through `cosim.record.observers.CsvSink`, with the rows formatted
by Arrow's C++ writer (the writer before issue 27, and the one used when pyarrow is installed),
by `cosim.record.csvformat.format_rows` (used without pyarrow: C, ``cosim/kernel/csvrows.c``) and by
its Python fallback `cosim.record.csvformat.format_rows_python` (no compiled kernel library); all write
the same bytes (tests/cosim/test_csvformat.py).  The three are timed ``--repeat`` times,
interleaved so a busy machine slows them alike; prints the best time per value of each, the
median and spread of the ratios to Arrow and the load average before and after.
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from cosim.record import csvformat

from cosim.record import observers

#: the formatters compared: Arrow's writer, then `format_rows` (C) and its Python fallback
WRITERS = {"pyarrow": None, "compiled": csvformat.format_rows,
           "python": lambda rows: csvformat.format_rows_python(rows).encode()}


def chunk(rows: int, columns: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    walks = np.cumsum(rng.normal(size=(rows, columns - 1)), axis=0)
    return np.column_stack([np.arange(rows) * 0.1, walks])


def seconds_per_value(writer: str, rows: np.ndarray, chunks: int, folder: Path) -> float:
    """The time writing ``chunks`` chunks takes, per value, with one of `WRITERS`."""
    observers.ARROW_CSV = WRITERS[writer] is None
    observers.format_rows = WRITERS[writer] or csvformat.format_rows
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
    times: dict[str, list[float]] = {w: [] for w in WRITERS}
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(args.repeat):
            for writer in WRITERS:
                times[writer].append(seconds_per_value(writer, rows, args.chunks, Path(folder)))
    for writer, seconds in times.items():
        print(f"{writer + ' writer:':18s}{min(seconds) * 1e9:4.0f} ns per value (best)")
    for writer in ("compiled", "python"):
        ratios = sorted(t / a for t, a in zip(times[writer], times["pyarrow"]))
        print(f"ratio {writer} / pyarrow: median {statistics.median(ratios):.2f} "
              f"(spread {ratios[0]:.2f}-{ratios[-1]:.2f})")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
