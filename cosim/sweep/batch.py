"""The sweep table rewritten in batches: after a burst of finished runs, not after each.

Rewriting ``sweep.csv`` and ``sweep.parquet`` (the whole table, replaced atomically,
`cosim.sweep.table.write_table`) after every finished run costs a sweep of N short runs
N rewrites of up to N rows, in the process that also hands the runs out.  `BatchedTable`
writes a finished row at once when the last rewrite is at least ``spacing`` times its own
duration ago (at most ``1 / (spacing + 1)`` of the time goes to rewriting, and a row waits for
a few rewrite durations), else within ``delay`` seconds at the latest (a timer) or with the
next finished run, and always at `close`: an interrupted sweep keeps every finished row.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

#: a rewrite waits until the last is this many of its durations ago
SPACING = 10.0
#: a finished row is in the table within this many seconds at the latest
DELAY = 1.0


class BatchedTable:
    """The finished rows by combination index, written with ``write(rows in index order)``."""

    def __init__(self, rows: dict[int, dict[str, Any]], write: Callable[[list[dict[str, Any]]], None],
                 spacing: float = SPACING, delay: float = DELAY):
        self.rows = rows
        self._write = write
        self._spacing, self._delay = spacing, delay
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None
        self._pending = False
        self._last_end = 0.0
        self._last_duration = 0.0
        #: what a rewrite on the timer's thread raised (a full disk), raised again by the next call here
        self._error: BaseException | None = None
        self.writes = 0

    def add(self, index: int, row: dict[str, Any]) -> None:
        """A finished run's row: written now, or soon (see the module docstring)."""
        with self._lock:
            self._raise_failed()
            self.rows[index] = row
            self._pending = True
            if time.perf_counter() - self._last_end >= self._spacing * self._last_duration:
                self._flush()
            elif self._timer is None:
                self._timer = threading.Timer(self._delay, self._flush_locked)
                self._timer.daemon = True
                self._timer.start()

    def flush(self) -> None:
        """Write the table now if rows are waiting."""
        with self._lock:
            self._flush()

    def close(self) -> None:
        """Write what is waiting and stop the timer."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            self._flush()

    def _flush_locked(self) -> None:
        with self._lock:
            self._timer = None
            try:
                self._flush()
            except BaseException as e:  # noqa: BLE001 -- not lost on the timer's thread: raised in the sweep's
                self._error = e

    def _raise_failed(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _flush(self) -> None:
        self._raise_failed()
        if not self._pending:
            return
        began = time.perf_counter()
        self._write([self.rows[i] for i in sorted(self.rows)])
        self._pending = False
        self._last_end = time.perf_counter()
        self._last_duration = self._last_end - began
        self.writes += 1
