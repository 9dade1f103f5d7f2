"""Observers: record every connector at every communication point.

Recording is one role, `Observer` (``open(names)``, ``write(rows)``, ``close(metadata)``),
implemented by `CsvSink` (a CSV readable by ``fmpy.util.read_csv``) and `ParquetSink`, each
with a JSON metadata file beside it (`file_sink` picks one by the file's suffix), `MemorySink`
(for the Python API), `SystemOutputColumns` (the root system's output connectors appended,
`DerivedColumns`, then the rows handed on) and the run journal (`cosim.record.journal.RunJournal`).
`Recorder` fills a preallocated NumPy chunk (the journal's mapped window, with one) in the hot
loop and hands the new rows to its observers, so a run that fails half way has every flushed
sample on disk, and the recorder's memory is one chunk whatever the run's length.  Data flows
one way: execution -> recorder -> observers; no observer calls back.

A file sink writes to ``<name>.part`` beside the result (`cosim.safeio.partial_path`) and
renames it onto the result when it closes, then writes the JSON the same way: a reader sees
the previous result or the new one, never half of one, and a process killed mid-run leaves
the previous result as it was (`cosim.record.journal` keeps that run's rows).
"""
from __future__ import annotations

import errno
import functools
import json
import os
import re
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from .csvformat import format_rows
from ..model.transforms import Transform, from_json
from ..errors import OutOfMemory, OutputError
from ..extras import has_pyarrow, require_pyarrow
from ..safeio import partial_path, write_atomic

if TYPE_CHECKING:
    from ..model.structure import RecordedOutput

#: rows the recorder's buffer (and each journal window) holds; a full one is flushed
CHUNK_ROWS = 4096


@runtime_checkable
class Observer(Protocol):
    """What records a run: told the column names once, handed every new block of rows (float64,
    one row per communication point, in the order of the names, time first) and closed with the
    run's metadata, also when the run failed, so the rows handed before stay recorded."""

    def open(self, names: list[str]) -> None:
        """The columns of every row to come."""

    def write(self, rows: np.ndarray) -> None:
        """The rows recorded since the last call (a view: copy what must be kept)."""

    def close(self, metadata: dict) -> None:
        """The run ended (completed, stopped or failed) with ``metadata``."""


class WindowedObserver(Observer, Protocol):
    """An `Observer` that is also the `Recorder`'s buffer (the journal, `cosim.record.journal.RunJournal`):
    its ``write`` gets the rows as the buffer holds them, in place, and the recorder stores the
    number of rows recorded in `count` after every row."""

    #: the row counter (one int64)
    count: np.ndarray

    def window(self) -> np.ndarray:
        """The next block of buffer rows (rows x columns, float64)."""


def file_sink(path: str | Path) -> CsvSink | ParquetSink:
    """The sink for a result file: Parquet for a ``.parquet`` suffix (a `SetupError` naming the
    extra to install without pyarrow), else CSV."""
    if Path(path).suffix.lower() == ".parquet":
        require_pyarrow("a Parquet result", file=str(path))
        return ParquetSink(path)
    return CsvSink(path)


def describe_os_error(e: OSError) -> str:
    """What went wrong writing a file, for a message: "the disk is full" for ENOSPC (and EDQUOT)."""
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"the disk is full ({os.strerror(e.errno)})"
    if e.errno == errno.ENOMEM:
        return f"the process ran out of memory ({os.strerror(e.errno)})"
    return e.strerror or str(e)


def _write_error(text: str, e: OSError) -> OutputError:
    """The `OutputError` (`OutOfMemory` for ENOMEM: a mapping of the journal could not be made)
    of ``e``, ``text`` then what went wrong."""
    kind = OutOfMemory if e.errno == errno.ENOMEM else OutputError
    return kind(text.format(describe_os_error(e)), file=e.filename)


def _naming_the_file(method):
    """A sink method whose `OSError` names the sink's file: Arrow's errors name none, and give
    the errno only in their text ("... Detail: [errno 28] No space left on device")."""
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except OSError as e:
            if e.filename is not None:
                raise
            found = re.search(r"\[errno (\d+)\]", str(e))
            code = e.errno or (int(found.group(1)) if found else None)
            raise OSError(code, os.strerror(code) if code else str(e), str(self.path)) from e
    return wrapper


class _FileSink:
    """A result file and the run's metadata JSON beside it (``<name>.json``)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.meta_path = self.path.with_suffix(".json")
        #: the file written until `close` renames it onto `path`
        self.part = partial_path(self.path)

    def publish(self, metadata_text: str | None) -> None:
        """Put the finished file in place, then its metadata JSON if any (each in one rename)."""
        os.replace(self.part, self.path)
        if metadata_text is not None:
            write_atomic(self.meta_path, metadata_text)

    @staticmethod
    def metadata_text(metadata: dict) -> str:
        return json.dumps(metadata, indent=2, default=str) + "\n"


#: whether result CSVs are formatted by Arrow's C++ writer (pyarrow installed) or by `cosim.record.csvformat`
ARROW_CSV = has_pyarrow()


def csv_header(names: Sequence[str]) -> str:
    """The header line of a result CSV: each name quoted as RFC 4180 quotes a field (its ``"``
    doubled), so a name may hold commas, quotes and line breaks; `cosim.record.results.read` reads
    every such header, ``fmpy.util.read_csv`` those whose names hold none of the three."""
    return ",".join('"' + n.replace('"', '""') + '"' for n in names) + "\n"


class CsvSink(_FileSink):
    """Writes chunks to a CSV as they come; the metadata goes to ``<name>.json`` beside it.

    A quoted header (`csv_header`), then one line per sample: each float64 in the shortest
    decimal form that reads back to the same bits (``-0``, ``inf``, ``nan`` included), laid out
    as Arrow's CSV writer lays it out, which ``fmpy.util.read_csv`` reads.  With pyarrow
    installed (``greyfmu[parquet]``) Arrow's C++ writer formats each chunk (without the GIL);
    without it `cosim.record.csvformat.format_rows` writes the same bytes (in C, about half Arrow's
    time per value; in Python without the compiled kernel library, about 5 times it:
    benchmarks/bench_csv.py).
    """

    def __init__(self, path: str | Path):
        super().__init__(path)
        self._file = None
        self._arrow = ARROW_CSV
        self._names: list[str] = []

    @_naming_the_file
    def open(self, names: list[str]) -> None:
        if self._arrow:   # imported now, not mid-run when memory may have run out
            import pyarrow as pa

            self._file = pa.OSFile(str(self.part), "wb")
        else:
            self._file = open(self.part, "wb", buffering=0)
        self._write_all(csv_header(names).encode())
        self._file.flush()
        self._names = names

    @_naming_the_file
    def write(self, rows: np.ndarray) -> None:
        end = self._file.tell()
        try:
            if self._arrow:
                self._write_arrow(rows)
            else:
                self._write_all(format_rows(rows))
            self._file.flush()
        except OSError:  # a full disk: drop the partly written chunk, so every line left is whole
            os.truncate(self.part, end)
            raise

    def _write_all(self, data: bytes) -> None:
        """Write every byte (an unbuffered write may take part of them)."""
        view = memoryview(data)
        while view:
            view = view[self._file.write(view):]

    def _write_arrow(self, rows: np.ndarray) -> None:
        import pyarrow as pa
        import pyarrow.csv as pcsv

        table = pa.Table.from_arrays(list(np.ascontiguousarray(rows.T)), names=self._names)
        pcsv.write_csv(table, self._file, pcsv.WriteOptions(include_header=False))

    @_naming_the_file
    def finish(self) -> None:
        """Close the file (no metadata)."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def close(self, metadata: dict) -> None:
        self.finish()
        self.publish(self.metadata_text(metadata))


class ParquetSink(_FileSink):
    """Writes chunks to a Parquet file as they come, one row group per chunk, float64 columns
    named as the CSV's; the run metadata goes into the file's key-value metadata (key
    ``cosim``, JSON: ``pyarrow.parquet.read_metadata(path).metadata[b"cosim"]``) and to
    ``<name>.json`` beside it.

    Parquet's footer (schema, row-group index, metadata) is written by `close`, which the
    master calls after a failed run too, so the rows flushed before a failure stay readable;
    a process killed mid-run leaves a ``.part`` with no footer and no readable rows, where a
    CSV's ``.part`` keeps them (the journal has them either way).
    """

    def __init__(self, path: str | Path):
        super().__init__(path)
        self._writer = None
        self._schema = None

    @_naming_the_file
    def open(self, names: list[str]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._schema = pa.schema([(name, pa.float64()) for name in names])
        # no dictionary encoding: sampled signals rarely repeat values, and trying it costs
        # 4x the write time (Snappy compression still shrinks constant columns)
        self._writer = pq.ParquetWriter(self.part, self._schema, use_dictionary=False)

    @_naming_the_file
    def write(self, rows: np.ndarray) -> None:
        import pyarrow as pa

        columns = np.ascontiguousarray(rows.T)
        self._writer.write_table(pa.Table.from_arrays(list(columns), schema=self._schema))

    @_naming_the_file
    def finish(self, metadata_text: str | None = None) -> None:
        """Write the footer (with the run metadata, if any) and close the file."""
        if self._writer is not None:
            if metadata_text is not None:
                self._writer.add_key_value_metadata({"cosim": metadata_text})
            self._writer.close()
            self._writer = None

    def close(self, metadata: dict) -> None:
        text = self.metadata_text(metadata)
        self.finish(text)
        self.publish(text)


class MemorySink:
    """Keeps the chunks; `array()` joins them into a structured array like fmpy.simulate_fmu's.

    ``keep``: the columns to keep besides ``time`` (None: all), so a long run written to a
    file need not also hold every signal in memory.
    """

    def __init__(self, keep: Sequence[str] | None = None) -> None:
        self.keep = None if keep is None else set(keep)
        self.names: list[str] = []
        self.chunks: list[np.ndarray] = []
        self.metadata: dict = {}
        self._columns: np.ndarray | None = None

    def open(self, names: list[str]) -> None:
        if self.keep is None:
            self.names = names
            return
        unknown = self.keep.difference(names)
        if unknown:
            raise ValueError(f"MemorySink: no column named {', '.join(sorted(unknown))}")
        self._columns = np.array([i for i, name in enumerate(names) if i == 0 or name in self.keep], dtype=np.intp)
        self.names = [names[i] for i in self._columns]

    def write(self, rows: np.ndarray) -> None:
        self.chunks.append(rows.copy() if self._columns is None else rows[:, self._columns])

    def close(self, metadata: dict) -> None:
        self.metadata = metadata

    def array(self) -> np.ndarray:
        data = np.concatenate(self.chunks) if self.chunks else np.empty((0, len(self.names)))
        result = np.empty(len(data), dtype=[(n, np.float64) for n in self.names])
        for i, n in enumerate(self.names):
            result[n] = data[:, i]
        return result


def column_order(source_names: Sequence[str], names: Sequence[str]) -> np.ndarray:
    """The permutation from a buffer row (time, then ``source_names``) to a result row (time,
    then ``names``)."""
    position = {n: i + 1 for i, n in enumerate(source_names)}
    return np.array([0] + [position[n] for n in names], dtype=np.intp)


@dataclass(frozen=True)
class DerivedColumns:
    """The root system's output connectors, each its ``transform`` of ``rows[:, column]``
    (`cosim.model.structure.RecordedOutput`: the composed unit conversions and transformations
    of SSP 1.0, sec. 5.3.4 and 5.3.5, `cosim.model.transforms`; an undriven one is
    ``Affine(0, its constant)`` of time): the one formula of the live run (`SystemOutputColumns`)
    and of a journal's recovery (`cosim.record.journal.recover`), computed per chunk, never in the
    stepping loop.  A value a mapping table on the way names no target for is NaN in the column,
    with a `RuntimeWarning` naming the connector (the column records; it drives no FMU)."""

    names: tuple[str, ...]
    #: each one's source column in the rows it extends
    columns: tuple[int, ...]
    transforms: tuple[Transform, ...]

    @classmethod
    def of(cls, outputs: Sequence[RecordedOutput], names: Sequence[str]) -> DerivedColumns:
        """The columns of ``outputs`` on rows laid out as ``names`` (time first)."""
        names = list(names)
        return cls(tuple(o.name for o in outputs), tuple(names.index(o.source) for o in outputs),
                   tuple(o.transform for o in outputs))

    @classmethod
    def from_header(cls, entries: Sequence[dict]) -> DerivedColumns:
        """The columns a journal's header lists (`header`)."""
        return cls(tuple(d["name"] for d in entries), tuple(int(d["column"]) for d in entries),
                   tuple(from_json(d["transform"]) for d in entries))

    def header(self) -> list[dict]:
        """What a journal's header holds of them (JSON)."""
        return [{"name": n, "column": c, "transform": t.as_json()}
                for n, c, t in zip(self.names, self.columns, self.transforms)]

    def extend(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` with the derived columns appended (``rows`` itself when there are none)."""
        if not self.names:
            return rows
        derived = np.empty((len(rows), len(self.names)))
        for k, (name, column, transform) in enumerate(zip(self.names, self.columns, self.transforms)):
            derived[:, k] = transform.apply_array(rows[:, column])
            if transform.partial and np.isnan(derived[:, k]).any():
                warnings.warn(f"root output connector '{name}': {transform.text()} names no target for some of "
                              "its source's values; its column holds NaN there.", RuntimeWarning, stacklevel=2)
        return np.hstack([rows, derived])


class SystemOutputColumns:
    """An `Observer` that appends the `DerivedColumns` to every chunk and hands it on to its own
    observers (``derived`` laid out on the names this one is opened with)."""

    def __init__(self, derived: DerivedColumns, observers: Sequence[Observer]):
        self.derived = derived
        self.observers = list(observers)

    def open(self, names: list[str]) -> None:
        for observer in self.observers:
            observer.open(names + list(self.derived.names))

    def write(self, rows: np.ndarray) -> None:
        rows = self.derived.extend(rows)
        for observer in self.observers:
            observer.write(rows)

    def close(self, metadata: dict) -> None:
        for observer in self.observers:
            observer.close(metadata)


class Recorder:
    """Sample buffer fed from the execution's value arrays, fanning the rows out to observers.

    ``sources`` are the arrays (outputs and inputs of each type) copied into a
    row in the order of ``source_names``; rows are handed to the ``observers`` in ``names``
    order (time first, then component by component as the SSD lists them).
    The rows go out when ``chunk_rows`` are filled or ``flush_seconds``
    have passed (the clock is read at every row, so a slow run is flushed on time).
    With ``journal`` (a `WindowedObserver`: `cosim.record.journal.RunJournal`) the buffer is the
    journal's mapped window and the row counter is stored after every row, so a crash loses
    no row.  The interface `cosim.run.execution.Execution` feeds: `record`
    (the Python loop), `window` and `filled` (the compiled one), `samples`.
    """

    def __init__(self, source_names: list[str], sources: list[np.ndarray], names: list[str],
                 observers: Sequence[Observer], chunk_rows: int = CHUNK_ROWS, flush_seconds: float = 1.0,
                 journal: WindowedObserver | None = None):
        self.sources = []
        col = 1
        for arr in sources:
            self.sources.append((col, col + len(arr), arr))
            col += len(arr)
        self.names = ["time", *names]
        self.permutation = column_order(source_names, names)
        self.observers = list(observers)
        self.journal = journal
        try:
            if journal is not None:
                journal.open(["time"] + list(source_names))
                self.buffer = journal.window()
            else:
                self.buffer = np.empty((chunk_rows, col))
            for observer in self.observers:
                observer.open(self.names)
        except OSError as e:
            if journal is not None:
                journal.close({})
            raise _write_error("the results cannot be written: {}.", e) from None
        self._count = journal.count if journal is not None else np.zeros(1, dtype=np.int64)
        self._count_address = self._count.ctypes.data
        self._base = self.buffer.ctypes.data   # the addresses `window` hands out, found once a buffer
        self.rows = 0      # rows filled in the buffer
        self._written = 0  # rows of the buffer already handed to the observers
        self.flush_seconds = flush_seconds
        self._flush_at = time.monotonic() + flush_seconds
        self.samples = 0
        self.broken: OSError | None = None

    def record(self, t: float) -> None:
        row = self.buffer[self.rows]
        row[0] = t
        for a, b, arr in self.sources:
            row[a:b] = arr
        self.rows += 1
        self.samples += 1
        self._count[0] = self.samples
        if self.rows == len(self.buffer) or time.monotonic() > self._flush_at:
            self.flush()

    def window(self) -> tuple[int, int, int, float]:
        """Where the compiled loop (`cosim.kernel`) writes the next rows: the address of the
        first free row of the buffer, how many rows are free, the address of the row counter
        (int64) it stores after each row, and the monotonic time after which to flush."""
        free = len(self.buffer) - self.rows
        return self._base + self.rows * self.buffer.strides[0], free, self._count_address, self._flush_at

    def filled(self, rows: int, samples: int, due: bool) -> None:
        """After the compiled loop wrote ``rows`` rows (``samples`` rows in all, also in the row
        counter): flush when the buffer is full or ``due``, as `record` does."""
        self.rows += rows
        self.samples = samples
        if self.rows == len(self.buffer) or due:
            self.flush()

    def flush(self) -> None:
        """Hand the new rows to the observers (the journal as the buffer holds them, the others
        in result order); an observer (or the journal) that cannot write (a full disk) is an
        `OutputError`, and no later flush is tried."""
        if self.broken is not None:
            return
        try:
            if self.rows > self._written:
                new = self.buffer[self._written:self.rows]
                if self.journal is not None:
                    self.journal.write(new)
                chunk = new[:, self.permutation]
                for observer in self.observers:
                    observer.write(chunk)
                self._written = self.rows
            if self.rows == len(self.buffer):
                if self.journal is not None:
                    self.buffer = self.journal.window()
                    self._base = self.buffer.ctypes.data
                self.rows = self._written = 0
        except OSError as e:
            self.broken = e
            raise _write_error(f"writing the results failed after {self.samples} rows: {{}}; the rows written "
                               "before are kept.", e) from None
        self._flush_at = time.monotonic() + self.flush_seconds

    def close(self, metadata: dict) -> None:
        """Flush, close the observers (writing ``metadata``) and then the journal (deleted: it is
        no longer needed, even when an observer fails here)."""
        try:
            self.flush()
            for observer in self.observers:
                observer.close(metadata)
        except OSError as e:
            raise _write_error("closing the results failed: {}.", e) from None
        finally:
            if self.journal is not None:
                self.buffer = None
                self.journal.close(metadata)
