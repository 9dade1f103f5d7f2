"""`cosim run` in a child process watched by its parent: a crash loses nothing, a hang ends.

The parent forks after the system is prepared (`cosim.plan.prepare.prepare`); the child runs
it, its rows in the journal (`cosim.record.journal`) as they are recorded.  When the child ends
without having finished its result files (killed by a signal: ``abort()``, a segfault;
``_exit()`` from inside an FMU), the parent turns the journal into the CSV/Parquet and the
JSON with status ``crashed``, removes the child's FMU extraction folder, and exits 1.  The
parent forwards SIGINT and SIGTERM to the child, which stops at its next communication point
(`cosim.run.interrupts`); a second SIGINT or SIGTERM, or ``INTERRUPT_GRACE`` seconds after the
first without the child gone (an FMU call that does not return), abandons the call: the
parent kills the child, writes the journal's rows and the JSON with status ``interrupted``
and exits 128 + the signal's number.  With ``timeout`` the parent sends SIGALRM when it
expires (the child stops with status ``timeout``) and, if the child is still there ``GRACE``
seconds later, kills it and recovers the journal with status ``timeout``.
The child dies with its parent: ``PR_SET_PDEATHSIG`` (Linux) sends it SIGTERM when the parent
dies, and a pipe the parent holds open is the portable watch (`_watch_parent`): at its end the
child stops as on SIGTERM, and is ended ``INTERRUPT_GRACE`` seconds later if it did not.
The child's ``sys.stdout``/``sys.stderr`` are relayed through pipes, so the parent's streams
(a terminal, a file, a test's capture) get every line.
"""
from __future__ import annotations

import ctypes
import os
import selectors
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from ..record.journal import recover

#: seconds the child has to stop after the timeout's SIGALRM before it is killed
GRACE = 2.0
#: seconds the child has to stop after a SIGINT or SIGTERM before its FMU call is abandoned
INTERRUPT_GRACE = 5.0
#: prctl option: the signal this process gets when its parent thread ends (linux/prctl.h)
PR_SET_PDEATHSIG = 1


def supervise(child: Callable[[], int], journal: Path, *, timeout: float | None = None) -> int:
    """Run ``child()`` (returning an exit status) in a forked process; returns its status,
    or 1 (128 + N when stopped by signal N) after recovering ``journal`` when it did not finish."""
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    journal.unlink(missing_ok=True)  # an earlier run's, for the results this run writes over
    out_r, out_w = os.pipe()
    err_r, err_w = os.pipe()
    alive_r, alive_w = os.pipe()  # the parent holds the write end: its end tells the child the parent died
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: never returns
        for fd in (out_r, err_r, alive_w):
            os.close(fd)
        _child(child, out_w, err_w, parent, alive_r, journal)
    for fd in (out_w, err_w, alive_r):
        os.close(fd)
    try:
        return _parent(pid, {out_r: sys.stdout, err_r: sys.stderr}, journal, timeout)
    finally:
        os.close(alive_w)


def _child(child: Callable[[], int], out_w: int, err_w: int, parent: int, alive_r: int, journal: Path) -> None:
    from .instances import Unzipped

    code = 1
    try:
        sys.stdout = os.fdopen(out_w, "w", buffering=1)
        sys.stderr = os.fdopen(err_w, "w", buffering=1)
        _watch_parent(parent, alive_r, journal)
        Unzipped.adopt()
        code = child()
    except KeyboardInterrupt:  # SIGINT before the run's own handler was installed
        code = 130
    except MemoryError:  # outside the run (which reports its own, naming the result file): a plot, a report
        print("cosim: the run failed: the process ran out of memory (its address space: see ulimit -v).",
              file=sys.stderr)
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


def _watch_parent(parent: int, alive_r: int, journal: Path) -> None:
    """Make the child die with its parent: SIGTERM from the kernel when the parent dies (Linux's
    ``PR_SET_PDEATHSIG``), and a thread that reads the pipe the parent holds open; at its end
    (the parent has gone, on any system) the thread sends SIGTERM (the run stops at its next
    communication point and writes its files) and, if the process is still there
    ``INTERRUPT_GRACE`` seconds later (an FMU call that does not return), writes the journal's
    rows with status ``interrupted`` and ends the process."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)

    def watch() -> None:
        try:
            os.read(alive_r, 1)  # nothing is ever written: returns at the pipe's end
        except OSError:
            pass
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(INTERRUPT_GRACE)
        try:
            if journal.exists():
                recover(journal, "interrupted", "the supervising cosim process died and an FMU call did not "
                                                f"return within {INTERRUPT_GRACE:g} s; the process was ended.")
        finally:
            os._exit(128 + signal.SIGTERM)

    threading.Thread(target=watch, name="cosim-parent-watch", daemon=True).start()
    if os.getppid() != parent:  # the parent died before the watch began
        os.kill(os.getpid(), signal.SIGTERM)


def _relay(stream, data: bytes) -> None:
    """Pass the child's output on; a reader that has gone (``cosim run | head -1``) gets no more,
    and the child runs on."""
    try:
        stream.write(data.decode(errors="replace"))
        stream.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())


class _Watch:
    """The parent's deadlines for the child: the timeout's SIGALRM, and the moment it is killed
    (``GRACE`` after the SIGALRM, ``INTERRUPT_GRACE`` after the first SIGINT/SIGTERM forwarded,
    at once on the second); ``killed`` says why ("timeout", "grace", "second")."""

    def __init__(self, pid: int, timeout: float | None):
        self.pid = pid
        self.timeout = timeout
        self.alarm_at = time.monotonic() + timeout if timeout is not None else None
        self.kill_at: float | None = None
        self.kill_reason = ""
        self.signum: int | None = None  # the first SIGINT or SIGTERM
        self.killed: str | None = None

    def send(self, signum: int) -> None:
        try:
            os.kill(self.pid, signum)
        except ProcessLookupError:
            pass

    def interrupted(self, signum: int) -> None:
        """A SIGINT or SIGTERM reached the parent: forward the first, kill on the second."""
        if self.signum is None:
            self.signum = signum
            self.send(signum)
            self._kill_by(time.monotonic() + INTERRUPT_GRACE, "grace")
        elif self.killed is None:
            self._kill("second")

    def wait(self) -> float | None:
        """Seconds until the next deadline (None: none)."""
        due = [t for t in (self.alarm_at, self.kill_at) if t is not None]
        return max(0.0, min(due) - time.monotonic()) if due else None

    def tick(self) -> None:
        """Act on the deadlines that have passed."""
        now = time.monotonic()
        if self.alarm_at is not None and now >= self.alarm_at:
            self.alarm_at = None
            self.send(signal.SIGALRM)
            self._kill_by(now + GRACE, "timeout")
        if self.kill_at is not None and now >= self.kill_at:
            self._kill(self.kill_reason)

    def _kill_by(self, when: float, reason: str) -> None:
        if self.kill_at is None or when < self.kill_at:
            self.kill_at, self.kill_reason = when, reason

    def _kill(self, reason: str) -> None:
        self.killed, self.kill_at, self.alarm_at = reason, None, None
        self.send(signal.SIGKILL)

    def outcome(self) -> tuple[str, str]:
        """Why a killed child did not finish, and the run's status."""
        if self.killed == "timeout":
            return (f"the run did not stop within {GRACE:g} s of the {self.timeout:g} s timeout (an FMU call "
                    "that does not return); the process was killed"), "timeout"
        name = signal.Signals(self.signum).name
        when = (f"a second {name} abandoned it" if self.killed == "second"
                else f"it was abandoned {INTERRUPT_GRACE:g} s after the {name}")
        return f"an FMU call did not return and {when}", "interrupted"


def _parent(pid: int, pipes: dict, journal: Path, timeout: float | None) -> int:
    watch = _Watch(pid, timeout)
    wake_r, wake_w = os.pipe()  # written on every signal (set_wakeup_fd): the select below wakes up
    for fd in (wake_r, wake_w):
        os.set_blocking(fd, False)
    previous = {s: signal.signal(s, lambda signum, frame: watch.interrupted(signum))
                for s in (signal.SIGINT, signal.SIGTERM)}
    previous_wakeup = signal.set_wakeup_fd(wake_w)
    selector = selectors.DefaultSelector()
    for fd in (*pipes, wake_r):
        selector.register(fd, selectors.EVENT_READ)
    try:
        while pipes:
            for key, _ in selector.select(watch.wait()):
                if key.fd == wake_r:
                    os.read(wake_r, 512)
                    continue
                data = os.read(key.fd, 65536)
                if data:
                    _relay(pipes[key.fd], data)
                else:
                    selector.unregister(key.fd)
                    os.close(key.fd)
                    del pipes[key.fd]
            watch.tick()
        _, status = os.waitpid(pid, 0)
    finally:
        signal.set_wakeup_fd(previous_wakeup)
        for s, h in previous.items():
            signal.signal(s, h)
        selector.close()
        os.close(wake_r)
        os.close(wake_w)
    return _conclude(watch, status, journal)


def _conclude(watch: _Watch, status: int, journal: Path) -> int:
    """The exit status of the command once the child has ended, after recovering its journal
    when it did not finish its result files."""
    # killed when an FMU call did not return (not a child that had just ended by itself)
    stopped = watch.killed in ("grace", "second") and os.WIFSIGNALED(status)
    code = 128 + watch.signum if stopped else 1
    if not journal.exists():  # finished, or ended before recording began
        if stopped:
            how, _ = watch.outcome()
            print(f"cosim: the run was stopped by {signal.Signals(watch.signum).name}: {how}, before any row "
                  "was recorded; the process was killed.", file=sys.stderr)
            return code
        code = os.waitstatus_to_exitcode(status)
        return code if code >= 0 else 128 - code
    if stopped or watch.killed == "timeout":
        how, state = watch.outcome()
    elif os.WIFSIGNALED(status):
        how, state = f"the process was killed by {signal.Signals(os.WTERMSIG(status)).name}", "crashed"
    else:
        how, state = f"the process exited with status {os.WEXITSTATUS(status)} during the run", "crashed"
    what = {"timeout": "the run timed out", "crashed": "the run crashed",
            "interrupted": f"the run was stopped by {signal.Signals(watch.signum or signal.SIGINT).name}"}
    try:
        output, rows = recover(journal, state, how + ".")
    except OSError as e:
        print(f"cosim: {what[state]}: {how}; its journal {journal} could not be turned into results "
              f"({e.strerror or e}).", file=sys.stderr)
        return code
    print(f"cosim: {what[state]}: {how}; {rows} rows recovered from the journal into {output} (status "
          f"'{state}' in {output.with_suffix('.json')}).", file=sys.stderr)
    return code
