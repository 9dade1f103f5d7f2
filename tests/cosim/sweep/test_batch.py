"""The sweep table rewritten in batches (cosim.sweep.batch): a burst of finished rows costs one
rewrite, none waits longer than the delay, close writes what waits, and a rewrite that failed on
the timer's thread is raised in the sweep's."""
from __future__ import annotations

import time

import pytest

from cosim.sweep.batch import BatchedTable


def test_a_burst_is_one_rewrite_and_the_last_row_arrives_within_the_delay():
    written: list[list[int]] = []

    def write(rows):
        time.sleep(0.05)        # a slow rewrite: the next 0.5 s (spacing 10) only gather rows
        written.append([r["i"] for r in rows])

    table = BatchedTable({}, write, spacing=10.0, delay=0.2)
    for i in range(5):
        table.add(i, {"i": i})
    assert written == [[0]]                      # the first at once, the burst waits
    time.sleep(0.5)
    assert written == [[0], [0, 1, 2, 3, 4]]     # the timer wrote the rest, once
    table.close()
    assert len(written) == 2                     # nothing waited: no rewrite


def test_close_writes_what_waits_and_a_failed_rewrite_on_the_timer_is_raised():
    calls = []

    def write(rows):
        calls.append(len(rows))
        if len(calls) == 2:
            raise OSError("No space left on device")
        time.sleep(0.02)

    table = BatchedTable({}, write, spacing=100.0, delay=0.05)
    table.add(0, {})
    table.add(1, {})              # waits for the timer, whose rewrite fails
    time.sleep(0.3)
    with pytest.raises(OSError, match="No space left"):
        table.add(2, {})
    table.close()
    assert calls == [1, 2, 2]     # close wrote the rows the failed rewrite had (the raising add kept none)
