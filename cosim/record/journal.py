"""The run journal: every recorded row in the kernel's hands before the next FMU call.

The `cosim.record.observers.Recorder` fills its rows directly in a memory-mapped window of
``<output>.journal`` and stores the row count in the file's header after each row, so a
process that dies (``abort()``, a segfault, ``_exit()``, SIGKILL) loses none of the rows
it completed: the pages belong to the kernel's page cache the moment they are written.
`RunJournal` is the journal as a run's `cosim.record.observers.Observer` (the recorder's buffer).
`recover` turns a journal left behind into the result file beside it (CSV or Parquet) and
its JSON with status ``crashed`` (or the status given, e.g. ``timeout``); `cosim.run.supervisor` does
that for `cosim run` after its child process ended without finishing.  A run that ends
normally, fails or is interrupted writes its files itself and deletes the journal.

File layout (little-endian): ``COSIMJ02``; int64 row count; int64 columns; int64 offset of
the rows; int64 length of the JSON header; int64 ring rows; int64 which of the next two pairs
holds (the other is written, then this flips: one store); two pairs of int64 (rows in the
result's part file, bytes of it holding them); the JSON header (result path, column names in
journal order, the permutation to the result's order, derived columns, metadata so far);
then the rows, float64, in windows of ``chunk_rows`` reserved with ``posix_fallocate`` (a
full disk is an ``OSError`` when a window is reserved, never a SIGBUS when a row is written).
A journal beside a CSV is a ring of one window (ring rows: its ``chunk_rows``): the CSV's
``.part`` file holds every row flushed, and the recorder marks after each flush how many rows
and bytes it holds (`Journal.mark`), so the window is written over by the next rows and the
journal is one window, not every row (the journal was 20–28 % of a CSV run's recording
against a C loop writing the same CSV, issue 42); `recover` then keeps the ``.part``'s marked
bytes and appends the rows after them.  Beside a Parquet file (whose ``.part`` is unreadable
without its footer) every row stays in the journal.  ``COSIMJ01`` (no ring, no marks) is read.
"""
from __future__ import annotations

import json
import mmap
import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import Errc

if TYPE_CHECKING:
    from .observers import DerivedColumns

MAGIC = b"COSIMJ02"
_HEADER = 88
#: the layout before the ring (a journal a crashed older cosim left): 4 fields, no marks
_MAGIC_01, _HEADER_01 = b"COSIMJ01", 40
SUFFIX = ".journal"
#: the prefix of the FMU extraction folders (`cosim.run.instances.Unzipped`) a recovery removes
UNZIP_PREFIX = "cosim-fmu-"


#: Linux's MAP_POPULATE (Python 3.10+), else nothing
_POPULATE = getattr(mmap, "MAP_POPULATE", 0)


def journal_path(output: str | Path) -> Path:
    """The journal of a result file: ``<output>.journal`` beside it."""
    output = Path(output)
    return output.with_name(output.name + SUFFIX)


class Journal:
    """A journal being written: `window` hands out the next ``chunk_rows`` x ``columns``
    float64 block mapped onto the file (with ``ring``, the same block again: its rows are kept
    elsewhere by then, `mark`); `count` is the header's row counter."""

    def __init__(self, path: str | Path, header: dict, columns: int, chunk_rows: int, ring: bool = False):
        self.path = Path(path)
        text = json.dumps(header, default=str).encode()
        self.offset = -(-(_HEADER + len(text)) // mmap.ALLOCATIONGRANULARITY) * mmap.ALLOCATIONGRANULARITY
        self.columns, self.chunk_rows, self.ring = columns, chunk_rows, ring
        self._file = open(self.path, "w+b")
        fields = [0, columns, self.offset, len(text), chunk_rows if ring else 0, 0, 0, 0, 0, 0]
        head = MAGIC + np.array(fields, dtype="<i8").tobytes() + text
        try:
            self._file.write(head)
            self._file.flush()
        except OSError as e:
            raise self._named(e) from None
        self._reserve(0, self.offset)
        self._head = mmap.mmap(self._file.fileno(), _HEADER)
        #: the row counter in the mapped header (the recorder stores the rows done after each row)
        self.count = np.frombuffer(self._head, dtype="<i8", count=1, offset=8)
        #: which pair of the marks holds, and the two pairs (rows, bytes of the result's part file)
        self._marks = np.frombuffer(self._head, dtype="<i8", count=5, offset=48)
        self._windows = 0
        self._window: np.ndarray | None = None

    def mark(self, rows: int, part_bytes: int) -> None:
        """The result's part file holds the first ``rows`` rows in its first ``part_bytes`` bytes:
        written into the pair not in use, then that pair made the one (a process killed between
        two stores leaves a pair that holds)."""
        spare = 1 - int(self._marks[0])
        self._marks[1 + 2 * spare], self._marks[2 + 2 * spare] = rows, part_bytes
        self._marks[0] = spare

    def window(self) -> np.ndarray:
        """The next block of rows, reserved on disk (OSError ENOSPC if the disk is full)."""
        if self.ring and self._window is not None:
            return self._window
        nbytes = self.chunk_rows * self.columns * 8
        start = self.offset + self._windows * nbytes
        self._reserve(start, nbytes)
        self._windows += 1
        # a plain ndarray on the mapping (np.memmap's Python-level indexing would cost ~20 % of a step),
        # mapped from the page the window begins in (a window need not be a whole number of pages),
        # its pages mapped in one call (MAP_POPULATE) rather than faulted in one by one as rows come
        skip = start % mmap.ALLOCATIONGRANULARITY
        window = mmap.mmap(self._file.fileno(), skip + nbytes, flags=mmap.MAP_SHARED | _POPULATE,
                           offset=start - skip)
        self._window = np.frombuffer(window, dtype="<f8", offset=skip).reshape(self.chunk_rows, self.columns)
        return self._window

    def _reserve(self, start: int, nbytes: int) -> None:
        try:
            os.posix_fallocate(self._file.fileno(), start, nbytes)
        except OSError as e:
            raise self._named(e) from None

    def _named(self, e: OSError) -> OSError:
        """``e`` naming the journal (the message says which file could not grow)."""
        return OSError(e.errno, e.strerror, str(self.path))

    def close(self) -> None:
        """Delete the journal (the result files are complete); the mappings go with their
        last reference."""
        if self._file is not None:
            self._file.close()
            self._file = None
            self.path.unlink(missing_ok=True)


class RunJournal:
    """The journal of a run writing ``output``, as a `cosim.record.observers.Observer` of the rows as
    the recorder's buffer holds them (time, then the sources; ``open`` names them): `open`
    creates ``<output>.journal`` with the header `recover` needs without the plan (the result's
    ``names``, time first, the permutation to them, the ``derived`` columns, the run's
    ``metadata`` so far, the ``temporary`` FMU extraction folders), `window` hands the
    recorder its next block of ``chunk_rows`` rows (default: `cosim.record.observers.rows_per_chunk`
    of the row's width), `count` is the row counter it stores after every row, and `close`
    deletes the journal."""

    def __init__(self, output: str | Path, names: Sequence[str], derived: DerivedColumns, metadata: dict,
                 temporary: Sequence[str] = (), chunk_rows: int | None = None, durable=None):
        #: the CSV sink whose part file keeps the rows flushed (`cosim.record.observers.CsvSink`):
        #: the journal is then a ring of one window (see the module docstring)
        self.durable = durable
        self.output = Path(output)
        self.names = list(names)
        self.derived = derived
        self.metadata = metadata
        self.temporary = list(temporary)
        self.chunk_rows = chunk_rows
        self._journal: Journal | None = None

    def open(self, names: list[str]) -> None:
        """Create the journal for buffer rows laid out as ``names`` (OSError if it cannot be written)."""
        from .observers import column_order, rows_per_chunk

        permutation = column_order(names[1:], self.names[1:]).tolist()
        header = {"output": str(self.output.resolve()), "names": self.names, "permutation": permutation,
                  "derived": self.derived.header(), "metadata": self.metadata, "temporary": self.temporary}
        self._journal = Journal(journal_path(self.output), header, len(names),
                                self.chunk_rows or rows_per_chunk(len(names)), ring=self.durable is not None)

    @property
    def count(self) -> np.ndarray:
        """The row counter in the mapped header."""
        return self._journal.count

    def window(self) -> np.ndarray:
        """The next block of rows, mapped onto the journal (OSError ENOSPC if the disk is full)."""
        return self._journal.window()

    def write(self, rows: np.ndarray) -> None:
        """Nothing to copy: ``rows`` are the journal's own mapped window, filled in place and
        counted row by row, so they are in the kernel's page cache already."""

    def synced(self, rows: int) -> None:
        """The observers hold the first ``rows`` rows: marked with the durable sink's bytes."""
        if self.durable is not None and self._journal is not None:
            self._journal.mark(rows, self.durable.position())

    def close(self, metadata: dict) -> None:
        """Delete the journal: the run's own observers hold its rows and ``metadata`` now."""
        if self._journal is not None:
            self._journal.close()
            self._journal = None


def read_journal(path: str | Path) -> tuple[dict, np.ndarray]:
    """The header and the rows (journal column order) of a journal file."""
    data = Path(path).read_bytes()
    if data[:8] not in (MAGIC, _MAGIC_01):
        raise ValueError(f"{path}: not a cosim journal")
    rows, columns, offset, length = (int(v) for v in np.frombuffer(data, dtype="<i8", count=4, offset=8))
    ring = 0
    if data[:8] == MAGIC:
        ring, which, *pairs = (int(v) for v in np.frombuffer(data, dtype="<i8", count=6, offset=40))
        header = json.loads(data[_HEADER:_HEADER + length])
        header["part_rows"], header["part_bytes"] = pairs[2 * which], pairs[2 * which + 1]
    else:
        header = json.loads(data[_HEADER_01:_HEADER_01 + length])
    # a ring holds rows first .. count - 1 (the window of the last row), a journal every row
    first = (rows - 1) // ring * ring if ring and rows else 0
    available = max(0, (len(data) - offset) // (8 * columns))
    rows = min(rows - first, available)
    header["first_row"] = first
    table = np.frombuffer(data, dtype="<f8", count=rows * columns, offset=offset).reshape(rows, columns)
    return header, table


def recover(path: str | Path, status: str = "crashed", message: str = "") -> tuple[Path, int]:
    """Write the result file and JSON of a journal left by a run that did not finish, with
    ``status`` and ``message`` in the metadata; delete the journal and the FMU extraction
    folder it names.  Returns the result path and the number of rows."""
    from .observers import DerivedColumns, file_sink

    header, table = read_journal(path)
    derived = DerivedColumns.from_header(header.get("derived", []))
    rows = derived.extend(table[:, header["permutation"]])
    names = header["names"] + list(derived.names)
    output = result_of(Path(path))
    sink = file_sink(output)
    first, kept = header["first_row"], header.get("part_bytes", 0)
    if kept:   # a ring: the part file's marked bytes hold the rows before part_rows
        if not sink.part.exists() and output.exists():   # killed after its result was in place
            shutil.copyfile(output, sink.part)
        sink.resume(names, kept)
        new = rows[header["part_rows"] - first:]
    else:
        sink.open(names)
        new = rows
    if len(new):
        sink.write(new)
    metadata = dict(header.get("metadata", {}))
    samples = first + len(rows)
    metadata.update(status=status, message=message, error=Errc.run_process_lost.value, samples=samples,
                    last_time=float(rows[-1, 0]) if len(rows) else None)
    sink.close(metadata)
    Path(path).unlink()
    for folder in header.get("temporary", []):
        if _extraction_folder(Path(folder)):
            shutil.rmtree(folder, ignore_errors=True)
    return output, samples


def result_of(journal: Path) -> Path:
    """The result file a journal belongs to: beside it, its name without ``.journal``.  The
    header's own ``output`` is not used: a journal is a file on disk like any other, and what
    it says must not decide where a result is written."""
    if not journal.name.endswith(SUFFIX) or journal.name == SUFFIX:
        raise ValueError(f"{journal}: a journal's name ends in {SUFFIX} after its result's name")
    journal = journal.resolve()
    return journal.with_name(journal.name[:-len(SUFFIX)])


def _extraction_folder(folder: Path) -> bool:
    """True for a folder named as the FMU extraction folders of `cosim.run.instances.Unzipped` are
    (``cosim-fmu-<pid>-...``, in the crashed process's ``$TMPDIR``): the only folders a recovery
    removes, whatever the header names."""
    return folder.name.startswith(UNZIP_PREFIX) and folder.is_dir() and not folder.is_symlink()
