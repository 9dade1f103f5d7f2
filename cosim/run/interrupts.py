"""Stopping a run on a signal at the next communication point (no traceback, nothing lost).

`stop_on_signals` replaces the handlers of SIGINT, SIGTERM and SIGALRM (the whole-run
``--timeout`` of `cosim.run.supervisor`) by one that only records the signal in a `StopRequest`;
`cosim.run.execution.Execution` reads it after every recorded communication point and ends the
run with status ``interrupted`` (SIGINT, SIGTERM) or ``timeout`` (SIGALRM).  A signal that
arrives during an FMU call is handled when the call returns.
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

#: status of a run stopped by each signal
STATUS = {signal.SIGINT: "interrupted", signal.SIGTERM: "interrupted", signal.SIGALRM: "timeout"}


class StopRequest:
    """``flag`` is empty until a signal arrives, then holds its number (a list, so the
    stepping loop's test is one truth test); ``signals``: the signals that set it while
    `stop_on_signals` holds their handlers (the compiled loop then watches them itself,
    `cosim.kernel.Kernel.watch_signals`, since Python runs handlers only between its own calls)."""

    def __init__(self) -> None:
        self.flag: list[int] = []
        self.signals: tuple[int, ...] = ()

    @property
    def signum(self) -> int | None:
        return self.flag[0] if self.flag else None

    def status(self) -> str:
        return STATUS[self.flag[0]]

    def describe(self) -> str:
        return signal.Signals(self.flag[0]).name


@contextmanager
def stop_on_signals() -> Iterator[StopRequest]:
    """A `StopRequest` set by SIGINT, SIGTERM and SIGALRM while the block runs (only in the
    main thread, where Python delivers signals; elsewhere it is never set)."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum, frame):
        if not request.flag:
            request.flag.append(signum)

    previous = {s: signal.signal(s, handler) for s in STATUS}
    request.signals = tuple(STATUS)
    try:
        yield request
    finally:
        request.signals = ()
        for s, h in previous.items():
            signal.signal(s, h)
