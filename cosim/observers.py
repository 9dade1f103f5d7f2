"""Observers: record every connector at every communication point.

`Recorder` fills a preallocated NumPy chunk in the hot loop and hands full
chunks to its sinks, so a run that fails half way has every flushed sample on
disk.  Sinks: `CsvSink` (a CSV readable by ``fmpy.util.read_csv`` plus a JSON
metadata file beside it) and `MemorySink` (for the Python API).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np


class CsvSink:
    """Writes chunks to a CSV as they come; the metadata goes to ``<name>.json`` beside it."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.meta_path = self.path.with_suffix(".json")
        self._file = None

    def open(self, names: list[str]) -> None:
        self._file = open(self.path, "w", newline="\n")
        self._file.write(",".join(f'"{n}"' for n in names) + "\n")
        self._file.flush()

    def write(self, rows: np.ndarray) -> None:
        np.savetxt(self._file, rows, fmt="%.17g", delimiter=",")
        self._file.flush()

    def close(self, metadata: dict) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        self.meta_path.write_text(json.dumps(metadata, indent=2, default=str) + "\n")


class MemorySink:
    """Keeps the chunks; `array()` joins them into a structured array like fmpy.simulate_fmu's."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.chunks: list[np.ndarray] = []
        self.metadata: dict = {}

    def open(self, names: list[str]) -> None:
        self.names = names

    def write(self, rows: np.ndarray) -> None:
        self.chunks.append(rows.copy())

    def close(self, metadata: dict) -> None:
        self.metadata = metadata

    def array(self) -> np.ndarray:
        data = np.concatenate(self.chunks) if self.chunks else np.empty((0, len(self.names)))
        result = np.empty(len(data), dtype=[(n, np.float64) for n in self.names])
        for i, n in enumerate(self.names):
            result[n] = data[:, i]
        return result


class Recorder:
    """Preallocated sample buffer fed from the execution's value arrays.

    ``sources`` are the arrays (outputs and inputs of each type) copied into a
    row in the order of ``source_names``; rows are written out in ``names``
    order (time first, then component by component as the SSD lists them).
    """

    def __init__(self, source_names: list[str], sources: list[np.ndarray], names: list[str],
                 sinks: list, chunk_rows: int = 4096, flush_seconds: float = 1.0):
        self.sources = []
        col = 1
        for arr in sources:
            self.sources.append((col, col + len(arr), arr))
            col += len(arr)
        position = {n: i + 1 for i, n in enumerate(source_names)}
        self.names = ["time"] + names
        self.permutation = np.array([0] + [position[n] for n in names], dtype=np.intp)
        self.buffer = np.empty((chunk_rows, col))
        self.rows = 0
        self.sinks = sinks
        self.flush_seconds = flush_seconds
        self._last_flush = time.monotonic()
        self.samples = 0
        for sink in sinks:
            sink.open(self.names)

    def record(self, t: float) -> None:
        row = self.buffer[self.rows]
        row[0] = t
        for a, b, arr in self.sources:
            row[a:b] = arr
        self.rows += 1
        self.samples += 1
        if self.rows == len(self.buffer) or (self.rows & 255 == 0
                                             and time.monotonic() - self._last_flush > self.flush_seconds):
            self.flush()

    def flush(self) -> None:
        if self.rows:
            chunk = self.buffer[:self.rows][:, self.permutation]
            for sink in self.sinks:
                sink.write(chunk)
            self.rows = 0
        self._last_flush = time.monotonic()

    def close(self, metadata: dict) -> None:
        self.flush()
        for sink in self.sinks:
            sink.close(metadata)
