"""Observers: record every connector at every communication point.

Recording is one role, `Observer` (``open(names)``, ``write(rows)``, ``close(metadata)``),
implemented by `CsvSink` (a CSV readable by ``fmpy.util.read_csv``) and `ParquetSink`, each
with a JSON metadata file beside it (`file_sink` picks one by the file's suffix), `MemorySink`
(for the Python API) and the run journal (`cosim.record.journal.RunJournal`).  `Recorder`
fills rows in the result's column order (time, the components' connectors, then the root
system's output connectors, `DerivedColumns`, computed per chunk) straight into the memory they
are kept in: the journal's mapped window when there is one, else the `MemorySink`'s one
preallocated array when it keeps every column, else a chunk of at most `CHUNK_BYTES`; it hands
the new rows to its observers as views of that memory (no copy for the owner of the buffer,
one for the others), so a run that fails half way has every flushed sample on disk, and a file
sink's memory is one chunk whatever the run's length.  Data flows one way: execution ->
recorder -> observers; no observer calls back.

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

from .. import kernel
from .csvformat import RowText
from ..model.transforms import Transform, from_json
from ..errors import OutOfMemory, OutputError
from ..extras import has_pyarrow, require_pyarrow
from ..safeio import partial_path, write_atomic

if TYPE_CHECKING:
    from ..model.structure import RecordedOutput

#: rows the recorder's chunk (and each journal window) holds at most; a full one is flushed
CHUNK_ROWS = 4096
#: bytes a chunk holds at most: a wide row (a system of 1000 FMUs records 2001 columns, 16 kB a
#: row) makes a chunk of fewer rows
CHUNK_BYTES = 4 << 20


def rows_per_chunk(columns: int, rows: int | None = None) -> int:
    """The rows of a chunk of ``columns`` float64 columns: `CHUNK_ROWS`, fewer for rows so wide
    that a chunk would pass `CHUNK_BYTES`, and no more than the ``rows`` a run records."""
    fitting = max(1, min(CHUNK_ROWS, CHUNK_BYTES // (8 * max(1, columns))))
    return fitting if rows is None else max(1, min(fitting, rows))


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
    """An `Observer` that is also the `Recorder`'s buffer (the journal, `cosim.record.journal.RunJournal`;
    a `MemorySink` that keeps every column): its ``write`` gets the rows as the buffer holds them,
    in place."""

    def window(self) -> np.ndarray:
        """The next block of buffer rows (rows x columns, float64, C-contiguous)."""


class JournalObserver(WindowedObserver, Protocol):
    """The run journal's role for the `Recorder` (`cosim.record.journal.RunJournal`): a
    `WindowedObserver` whose row counter ``count`` the recorder stores after every row, told
    after each flush how many rows the other observers hold (`synced`)."""

    #: the row counter (one int64)
    count: np.ndarray

    def synced(self, rows: int) -> None:
        """The other observers hold the first ``rows`` rows."""


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


#: whether result CSVs are formatted by Arrow's C++ writer (True) or by `cosim.record.csvformat`
#: (False); None: by `cosim.record.csvformat` where the kernel library is built (in C, about half
#: Arrow's time per value, and no transposed copy of the chunk), else by Arrow if pyarrow is installed
ARROW_CSV: bool | None = None


def _arrow_csv() -> bool:
    if ARROW_CSV is not None:
        return ARROW_CSV
    return kernel.library()[0] is None and has_pyarrow()


def csv_header(names: Sequence[str]) -> str:
    """The header line of a result CSV: each name quoted as RFC 4180 quotes a field (its ``"``
    doubled), so a name may hold commas, quotes and line breaks; `cosim.record.results.read` reads
    every such header, ``fmpy.util.read_csv`` those whose names hold none of the three."""
    return ",".join('"' + n.replace('"', '""') + '"' for n in names) + "\n"


class CsvSink(_FileSink):
    """Writes chunks to a CSV as they come; the metadata goes to ``<name>.json`` beside it.

    A quoted header (`csv_header`), then one line per sample: each float64 in the shortest
    decimal form that reads back to the same bits (``-0``, ``inf``, ``nan`` included), laid out
    as Arrow's CSV writer lays it out, which ``fmpy.util.read_csv`` reads: by
    `cosim.record.csvformat.RowText` (in C, about half Arrow's time per value, block by block into
    one buffer), or, without the compiled kernel library, by Arrow's C++ writer where pyarrow is
    installed (``greyfmu[parquet]``), else in Python (about 5 times Arrow's time:
    benchmarks/bench_csv.py); all three write the same bytes (`ARROW_CSV`).
    """

    def __init__(self, path: str | Path):
        super().__init__(path)
        self._file = None
        self._arrow = _arrow_csv()
        self._names: list[str] = []
        self._text: RowText | None = None

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
        if not self._arrow:
            self._text = RowText(len(names))

    @_naming_the_file
    def resume(self, names: list[str], part_bytes: int) -> None:
        """Go on writing the part file a run left (its first ``part_bytes`` bytes kept: the header
        and whole rows, `cosim.record.journal.recover`) with rows laid out as ``names``."""
        os.truncate(self.part, part_bytes)
        if self._arrow:
            import pyarrow as pa

            self._file = pa.OSFile(str(self.part), "ab")
        else:
            self._file = open(self.part, "ab", buffering=0)
        self._names = names
        if not self._arrow:
            self._text = RowText(len(names))

    def position(self) -> int:
        """The bytes written to the part file (header and whole rows)."""
        return self._file.tell()

    @_naming_the_file
    def write(self, rows: np.ndarray) -> None:
        end = self._file.tell()
        try:
            if self._arrow:
                self._write_arrow(rows)
            else:
                for block in self._text.blocks(rows):
                    self._write_all(block)
            self._file.flush()
        except OSError:  # a full disk: drop the partly written chunk, so every line left is whole
            os.truncate(self.part, end)
            raise

    def _write_all(self, data: bytes | memoryview) -> None:
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
    """Keeps the rows in one array, preallocated for ``rows`` rows when the run says how many it
    records (grown by doubling when not); `array()` is a structured array like
    fmpy.simulate_fmu's, a view of that array (no copy).

    ``keep``: the columns to keep besides ``time`` (None: all), so a long run written to a
    file need not also hold every signal in memory.  Keeping all of them with ``rows`` known,
    it is `windowed`: the `Recorder` writes the rows straight into its array (`window`).
    """

    def __init__(self, keep: Sequence[str] | None = None, rows: int | None = None) -> None:
        self.keep = None if keep is None else set(keep)
        self.capacity = rows
        self.names: list[str] = []
        self.metadata: dict = {}
        #: the rows kept so far
        self.rows = 0
        self._columns: np.ndarray | None = None
        self._data: np.ndarray | None = None
        self._lent = self._dropped = False

    @property
    def windowed(self) -> bool:
        """Whether the recorder may fill this sink's array itself (`window`)."""
        return self.keep is None and self.capacity is not None

    def open(self, names: list[str]) -> None:
        if self.keep is None:
            self.names = names
            return
        unknown = self.keep.difference(names)
        if unknown:
            raise ValueError(f"MemorySink: no column named {', '.join(sorted(unknown))}")
        self._columns = np.array([i for i, name in enumerate(names) if i == 0 or name in self.keep], dtype=np.intp)
        self.names = [names[i] for i in self._columns]

    def _room(self, rows: int) -> np.ndarray:
        """The array with room for ``rows`` more rows (allocated, or grown by doubling)."""
        need = self.rows + rows
        if self._data is None or len(self._data) < need:
            size = max(need, self.capacity or 0) if self._data is None else max(need, 2 * len(self._data))
            grown = np.empty((size, len(self.names)))
            if self._data is not None:
                grown[:self.rows] = self._data[:self.rows]
            self._data = grown
        return self._data

    def window(self) -> np.ndarray:
        """The free rows of the array (the recorder writes there; ``write`` then counts them)."""
        self._lent = True
        return self._room(1)[self.rows:]

    def write(self, rows: np.ndarray) -> None:
        if self._dropped:
            return
        if self._lent:   # the rows of `window`, in place
            self.rows += len(rows)
            return
        data = self._room(len(rows))[self.rows:self.rows + len(rows)]
        if self._columns is None:
            data[...] = rows
        else:
            np.take(rows, self._columns, axis=1, out=data)
        self.rows += len(rows)

    def close(self, metadata: dict) -> None:
        self.metadata = metadata

    def clear(self) -> None:
        """Drop the rows kept, and keep no more (the process ran out of memory and a result file has them)."""
        self._data, self.rows, self._dropped = None, 0, True

    def array(self) -> np.ndarray:
        """The rows kept, as a structured array (a field per column) viewing the sink's array."""
        data = self._data[:self.rows] if self._data is not None else np.empty((0, len(self.names)))
        return data.view(np.dtype([(n, np.float64) for n in self.names]))[:, 0]


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
    ``Affine(0, its constant)`` of time): the one formula of the live run (`Recorder`, in place)
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

    def fill(self, rows: np.ndarray, first: int) -> None:
        """Compute the derived columns of ``rows`` into its columns ``first``, ``first + 1``, ..."""
        for k, (name, column, transform) in enumerate(zip(self.names, self.columns, self.transforms)):
            rows[:, first + k] = transform.apply_array(rows[:, column])
            if transform.partial and np.isnan(rows[:, first + k]).any():
                warnings.warn(f"root output connector '{name}': {transform.text()} names no target for some of "
                              "its source's values; its column holds NaN there.", RuntimeWarning, stacklevel=3)

    def extend(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` with the derived columns appended (``rows`` itself when there are none)."""
        if not self.names:
            return rows
        extended = np.empty((len(rows), rows.shape[1] + len(self.names)))
        extended[:, :rows.shape[1]] = rows
        self.fill(extended, rows.shape[1])
        return extended


class Recorder:
    """The rows of a run, filled from the execution's value arrays and handed to the observers.

    ``sources`` are the arrays (outputs and inputs of each type) whose values, named
    ``source_names`` in order, make a row; a row is the time, then ``names`` (component by
    component as the SSD lists them), then the ``derived`` columns (the root system's output
    connectors), which are computed per chunk when the rows are handed on.  The rows are filled
    in that order where they are kept (the buffer): the ``journal``'s mapped window (a
    `JournalObserver`: `cosim.record.journal.RunJournal`, whose row counter `count` is stored
    after every row, so a crash loses no row, and which is told after each flush how many rows
    the observers hold), else a `MemorySink` observer that keeps every
    column and knows the ``rows`` of the run (its array: no copy at all), else a chunk of
    ``chunk_rows`` rows (default `rows_per_chunk`).  The rows go out when the buffer is full or ``flush_seconds`` have passed
    (the clock is read at every row, so a slow run is flushed on time).  The interface
    `cosim.run.execution.Execution` feeds: `record` (the Python loop), `sources`, `width`,
    `window` and `filled` (the compiled one), `samples`.
    """

    def __init__(self, source_names: list[str], sources: list[np.ndarray], names: list[str],
                 observers: Sequence[Observer], chunk_rows: int | None = None, flush_seconds: float = 1.0,
                 journal: JournalObserver | None = None, *, derived: DerivedColumns | None = None,
                 rows: int | None = None):
        self.derived = derived if derived is not None else DerivedColumns((), (), ())
        self.names = ["time", *names, *self.derived.names]
        #: the columns of a row, and the first derived one
        self.width, self._first_derived = len(self.names), 1 + len(names)
        #: per source (a run of an array's values recorded): its address, length, whether it holds C
        #: ints and the column of each value (the compiled loop's, `cosim.kernel.Kernel.record`)
        self.sources: list[tuple[int, int, bool, np.ndarray]] = []
        self._copies: list[tuple[slice | np.ndarray, np.ndarray]] = []   # the Python loop's: columns, values
        self._layout(source_names, sources, names)
        self.observers = list(observers)
        self.journal = journal
        owner = journal if journal is not None else \
            next((o for o in self.observers if getattr(o, "windowed", False)), None)
        try:
            if journal is not None:
                journal.open(list(self.names))
            for observer in self.observers:
                observer.open(list(self.names))
            if journal is not None:
                journal.synced(0)
            self.buffer = owner.window() if owner is not None else \
                np.empty((chunk_rows or rows_per_chunk(self.width, rows), self.width))
        except OSError as e:
            if journal is not None:
                journal.close({})
            raise _write_error("the results cannot be written: {}.", e) from None
        self._owner = owner
        self._count = journal.count if journal is not None else np.zeros(1, dtype=np.int64)
        self._count_address = self._count.ctypes.data
        self._base = self.buffer.ctypes.data   # the addresses `window` hands out, found once a buffer
        self.rows = 0      # rows filled in the buffer
        self._written = 0  # rows of the buffer already handed to the observers
        self.flush_seconds = flush_seconds
        self._flush_at = time.monotonic() + flush_seconds
        self.samples = 0
        self.broken: OSError | None = None

    def _layout(self, source_names: list[str], sources: list[np.ndarray], names: list[str]) -> None:
        """`sources` and the Python loop's copies: each run of consecutive values of an array
        that ``names`` records, with their columns (a value ``names`` leaves out is not recorded)."""
        column = {n: i + 1 for i, n in enumerate(names)}
        known = set(source_names)
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValueError(f"Recorder: no source for {', '.join(unknown)}")
        offset = 0
        for array in sources:
            where = [column.get(n, 0) for n in source_names[offset:offset + len(array)]]
            offset += len(array)
            j = 0
            while j < len(where):
                if not where[j]:
                    j += 1
                    continue
                end = j
                while end < len(where) and where[end]:
                    end += 1
                values, columns = array[j:end], np.array(where[j:end], dtype=np.intc)
                self.sources.append((values.ctypes.data, len(values), values.dtype.kind in "iub", columns))
                consecutive = bool(np.all(np.diff(columns) == 1))
                self._copies.append((slice(int(columns[0]), int(columns[-1]) + 1) if consecutive
                                     else columns.astype(np.intp), values))
                j = end

    def record(self, t: float) -> None:
        if self.rows == len(self.buffer):
            self._next_buffer()
        row = self.buffer[self.rows]
        row[0] = t
        for columns, values in self._copies:
            row[columns] = values
        self.rows += 1
        self.samples += 1
        self._count[0] = self.samples
        if self.rows == len(self.buffer) or time.monotonic() > self._flush_at:
            self.flush()

    def window(self) -> tuple[int, int, int, float]:
        """Where the compiled loop (`cosim.kernel`) writes the next rows: the address of the
        first free row of the buffer, how many rows are free, the address of the row counter
        (int64) it stores after each row, and the monotonic time after which to flush."""
        if self.rows == len(self.buffer):
            self._next_buffer()
        free = len(self.buffer) - self.rows
        return self._base + self.rows * self.buffer.strides[0], free, self._count_address, self._flush_at

    def filled(self, rows: int, samples: int, due: bool) -> None:
        """After the compiled loop wrote ``rows`` rows (``samples`` rows in all, also in the row
        counter): flush when the buffer is full or ``due``, as `record` does."""
        self.rows += rows
        self.samples = samples
        if self.rows == len(self.buffer) or due:
            self.flush()

    def _next_buffer(self) -> None:
        """The buffer after a full one (flushed), taken when a row is to be written, not when the
        last one filled it: a run that fills its `MemorySink`'s array exactly, or its journal's last
        window, asks for no more.  A journal that cannot grow (a full disk) is an `OutputError`."""
        if self._owner is not None:
            try:
                self.buffer = self._owner.window()
            except OSError as e:
                raise self._broken_by(e) from None
            self._base = self.buffer.ctypes.data
        self.rows = self._written = 0

    def _broken_by(self, e: OSError) -> OutputError:
        """The error of a write that failed (``e``), after which no flush is tried."""
        self.broken = e
        return _write_error(f"writing the results failed after {self.samples} rows: {{}}; the rows written "
                            "before are kept.", e)

    def flush(self) -> None:
        """Compute the new rows' derived columns and hand the rows to the observers (and the
        journal) as a view of the buffer; an observer (or the journal) that cannot write (a full
        disk) is an `OutputError`, and no later flush is tried."""
        if self.broken is not None:
            return
        try:
            if self.rows > self._written:
                new = self.buffer[self._written:self.rows]
                self.derived.fill(new, self._first_derived)
                if self.journal is not None:
                    self.journal.write(new)
                for observer in self.observers:
                    observer.write(new)
                if self.journal is not None:
                    self.journal.synced(self.samples)
                self._written = self.rows
        except OSError as e:
            raise self._broken_by(e) from None
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
