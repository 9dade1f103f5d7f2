"""`cosim run` in a child process watched by its parent: a crash loses nothing, a hang ends.

The parent forks after the system is validated (`cosim.simulation.prepare`); the child runs
it, its rows in the journal (`cosim.journal`) as they are recorded.  When the child ends
without having finished its result files (killed by a signal: ``abort()``, a segfault;
``_exit()`` from inside an FMU), the parent turns the journal into the CSV/Parquet and the
JSON with status ``crashed``, removes the child's FMU extraction folder, and exits 1.  The
parent forwards SIGINT and SIGTERM to the child, which stops at its next communication point
(`cosim.interrupts`).  With ``timeout`` the parent sends SIGALRM when it expires (the child
stops with status ``timeout``) and, if the child is still there ``grace`` seconds later (an
FMU call that does not return), kills it and recovers the journal with status ``timeout``.
The child's ``sys.stdout``/``sys.stderr`` are relayed through pipes, so the parent's streams
(a terminal, a file, a test's capture) get every line.
"""
from __future__ import annotations

import os
import selectors
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path

from .journal import recover

#: seconds the child has to stop after the timeout's SIGALRM before it is killed
GRACE = 2.0


def supervise(child: Callable[[], int], journal: Path, *, timeout: float | None = None) -> int:
    """Run ``child()`` (returning an exit status) in a forked process; returns its status,
    or 1 after recovering ``journal`` when it did not finish."""
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    journal.unlink(missing_ok=True)  # an earlier run's, for the results this run writes over
    out_r, out_w = os.pipe()
    err_r, err_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns
        os.close(out_r)
        os.close(err_r)
        _child(child, out_w, err_w)
    os.close(out_w)
    os.close(err_w)
    return _parent(pid, {out_r: sys.stdout, err_r: sys.stderr}, journal, timeout)


def _child(child: Callable[[], int], out_w: int, err_w: int) -> None:
    from .instances import Unzipped

    code = 1
    try:
        sys.stdout = os.fdopen(out_w, "w", buffering=1)
        sys.stderr = os.fdopen(err_w, "w", buffering=1)
        Unzipped.adopt()
        code = child()
    except KeyboardInterrupt:  # SIGINT before the run's own handler was installed
        code = 130
    except BaseException:
        import traceback
        traceback.print_exc()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
            Unzipped.release()
        finally:
            os._exit(code)


def _relay(stream, data: bytes) -> None:
    """Pass the child's output on; a reader that has gone (``cosim run | head -1``) gets no more,
    and the child runs on."""
    try:
        stream.write(data.decode(errors="replace"))
        stream.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())


def _parent(pid: int, pipes: dict, journal: Path, timeout: float | None) -> int:
    def forward(signum, frame):
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass

    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    selector = selectors.DefaultSelector()
    for fd in pipes:
        selector.register(fd, selectors.EVENT_READ)
    deadline = time.monotonic() + timeout if timeout is not None else None
    alarmed = killed = False
    try:
        while pipes:
            wait = None if deadline is None else max(0.0, deadline - time.monotonic())
            for key, _ in selector.select(wait):
                data = os.read(key.fd, 65536)
                if data:
                    _relay(pipes[key.fd], data)
                else:
                    selector.unregister(key.fd)
                    os.close(key.fd)
                    del pipes[key.fd]
            if deadline is not None and time.monotonic() >= deadline:
                if not alarmed:
                    alarmed, deadline = True, time.monotonic() + GRACE
                    forward(signal.SIGALRM, None)
                else:
                    killed, deadline = True, None
                    forward(signal.SIGKILL, None)
        _, status = os.waitpid(pid, 0)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        selector.close()
    if not journal.exists():  # finished, or killed before recording began
        code = os.waitstatus_to_exitcode(status)
        return code if code >= 0 else 128 - code
    if killed:
        how, state = (f"the run did not stop within {GRACE:g} s of the {timeout:g} s timeout (an FMU call "
                      "that does not return); the process was killed"), "timeout"
    elif os.WIFSIGNALED(status):
        how, state = f"the process was killed by {signal.Signals(os.WTERMSIG(status)).name}", "crashed"
    else:
        how, state = f"the process exited with status {os.WEXITSTATUS(status)} during the run", "crashed"
    try:
        output, rows = recover(journal, state, how + ".")
    except OSError as e:
        print(f"cosim: the run {'timed out' if state == 'timeout' else 'crashed'}: {how}; its journal {journal} "
              f"could not be turned into results ({e.strerror or e}).", file=sys.stderr)
        return 1
    print(f"cosim: the run {'timed out' if state == 'timeout' else 'crashed'}: {how}; "
          f"{rows} rows recovered from the journal into {output} (status '{state}' in "
          f"{output.with_suffix('.json')}).", file=sys.stderr)
    return 1
