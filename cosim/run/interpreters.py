"""The two interpreters of a step's program (`cosim.run.program`): Python's and the compiled loop's.

Both run the same operations in the same order on the same exchange buffers and record a row
after each step; both stop at the same places and say so with an `Event`: an FMI status above
Warning (or a doStep's post-step asking to end, FMI 3.0's terminateSimulation) at an operation
index, for `cosim.run.stepping` to handle and then resume the step at the operation after it; a
stop request after a recorded row; or the end of the steps asked for.

* `PythonInterpreter` calls each operation's Python form.  It runs where the compiled loop is
  not built or not wanted (``--kernel python``), makes the exchange of initialisation, and
  makes the operations the compiled loop hands back.
* `NativeInterpreter` runs the program in the compiled loop (`cosim.kernel`), which writes
  each row straight into the recorder's buffer; at an operation without a C form it returns,
  Python makes that operation (and the Python-only operations after it), and the loop goes on
  from the next one.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple, Protocol

from .. import kernel as native
from ..errors import SetupError
from ..plan.prepare import ALGORITHMS
from ..model.grid import Grid
from .interrupts import StopRequest
from ..record.observers import Recorder
from .link import LinkedProgram

#: why an interpreter returned: the steps asked for are done, an FMI status to handle, a stop request
END, STATUS, STOP = "end", "status", "stop"
#: which interpreter runs the step (``--kernel``)
KERNELS = ("auto", "native", "python")

_NOTICES: set[str] = set()


class Event(NamedTuple):
    """Why `Interpreter.advance` returned: ``reason`` (END, STATUS, STOP) and ``k``, the step
    reached (every step before it recorded); on STATUS, step k stopped at operation ``op`` with
    ``status`` (after the operation's post-step)."""
    reason: str
    k: int
    op: int = -1
    status: int = 0


class Interpreter(Protocol):
    """Runs a program step after step (see the module docstring)."""
    name: str
    #: the step under way: every row up to t_k is recorded
    k: int

    def start(self, recorder: Recorder, stop: StopRequest) -> None:
        """Before the first step: where rows go, and the stop request to watch."""
        ...

    def advance(self, k: int, k_end: int, first: int) -> Event:
        """Steps k .. k_end - 1, step k from its operation ``first``."""
        ...

    def finish(self) -> None:
        """After the last step (also after an error): stop watching signals."""
        ...

    def close(self) -> None:
        """Release what the interpreter holds (the compiled loop's threads)."""
        ...


class PythonInterpreter:
    """The program in Python: each operation's ``call``."""

    name = "python"

    def __init__(self, program: LinkedProgram, grid: Grid):
        self.program, self.grid = program, grid
        ops = program.operations
        top = program.top_level()
        self._top = [(i, ops[i].call) for i in top]
        self._position = {i: p for p, i in enumerate(top)}
        self._position[len(ops)] = len(top)
        self._exchange = [(i, ops[i].call) for i in program.top_level(program.step_ops)]
        self.k = 0
        self._recorder: Recorder | None = None
        self._stop: StopRequest | None = None

    def start(self, recorder: Recorder, stop: StopRequest) -> None:
        self._recorder, self._stop = recorder, stop

    def advance(self, k: int, k_end: int, first: int) -> Event:
        time, record, stop = self.grid.time, self._recorder.record, self._stop.flag
        top = self._top
        while k < k_end:
            self.k = k
            t = time(k)
            t_next = time(k + 1)
            h = t_next - t
            for i, call in (top if first == 0 else top[self._position[first]:]):
                s = call(t, h, t_next)
                if s > 1:
                    return Event(STATUS, k, i, s)
            first = 0
            record(t_next)
            k += 1
            if stop:
                self.k = k
                return Event(STOP, k)
        self.k = k
        return Event(END, k)

    def run_python(self, k: int, first: int) -> tuple[int, Event | None]:
        """For the compiled loop: step k's operations from ``first`` while they have no C form;
        the operation to resume at, or the Event of a status above Warning."""
        ops = self.program.operations
        t, t_next = self.grid.time(k), self.grid.time(k + 1)
        h = t_next - t
        i = first
        while i < len(ops) and ops[i].native is None:
            s = ops[i].call(t, h, t_next)
            if s > 1:
                return i, Event(STATUS, k, i, s)
            i = ops[i].next
        return i, None

    def exchange(self, t: float) -> None:
        """The exchange at the end of a step, made at ``t`` (initialisation): a status above
        Warning fails the run."""
        ops = self.program.operations
        for i, call in self._exchange:
            s = call(t, 0.0, t)
            if s > 1:
                raise ops[i].failure(s, t)

    def finish(self) -> None:
        pass

    def close(self) -> None:
        pass


class NativeInterpreter:
    """The program in the compiled loop (`cosim.kernel.Kernel`), Python making the operations
    without a C form (``python``) when the loop hands them back."""

    name = "native"

    def __init__(self, program: LinkedProgram, grid: Grid, python: PythonInterpreter, threads: int = 1):
        self.program, self.grid, self.python = program, grid, python
        self.kernel = native.Kernel([op.native for op in program.operations], grid, threads, program.parallel)
        self.k = 0
        self._recorder: Recorder | None = None
        self._stop: StopRequest | None = None
        self._watching = False

    def start(self, recorder: Recorder, stop: StopRequest) -> None:
        self._recorder, self._stop = recorder, stop
        self.kernel.record(recorder.sources, recorder.width)
        self._watching = bool(stop.signals)
        if self._watching:
            self.kernel.watch_signals()

    def advance(self, k: int, k_end: int, first: int) -> Event:
        kernel, recorder, stop, time = self.kernel, self._recorder, self._stop, self.grid.time
        ops = self.program.operations
        while True:
            if stop.flag:
                kernel.stop_flag.value = stop.flag[0]
            rows, free_rows, count, flush_at = recorder.window()
            reason = kernel.run(k, k_end, first, rows, free_rows, count, recorder.samples, flush_at)
            state = kernel.state
            k = self.k = state.k
            first = 0
            recorder.filled(state.rows_done, state.samples, bool(reason & (native.KERNEL_FULL |
                                                                          native.KERNEL_FLUSH)))
            if reason & (native.KERNEL_UNMADE | native.KERNEL_STATUS | native.KERNEL_YIELD):
                op = ops[state.op]
                t, t_next = time(k), time(k + 1)
                if reason & native.KERNEL_UNMADE:  # a route of step k: its Python form raises what C found
                    op.call(t, t_next - t, t_next)
                    first = op.next
                    continue
                if reason & native.KERNEL_STATUS:
                    status = state.status if op.post_step is None else op.post_step(t, t_next - t, state.status)
                    return Event(STATUS, k, state.op, status)
                first, event = self.python.run_python(k, state.op)
                if event is not None:
                    return event
                continue
            if reason & native.KERNEL_STOP or stop.flag:
                if not stop.flag:
                    stop.flag.append(kernel.stop_flag.value)
                return Event(STOP, k)
            if k >= k_end:
                return Event(END, k)

    def finish(self) -> None:
        if self._watching:
            self.kernel.unwatch_signals()
            self._watching = False

    def close(self) -> None:
        self.kernel.close()


def check_kernel(algorithm: str, kernel: str, threads: int) -> None:
    """Refuse an unknown algorithm or kernel, a number of threads that is not a whole number of at
    least 1, threads on anything but a Jacobi step of the compiled loop, and the compiled loop
    asked for (``native``, or threads) where the library is missing."""
    if algorithm not in ALGORITHMS:
        raise SetupError(f"unknown algorithm '{algorithm}'; choose one of {', '.join(ALGORITHMS)}.",
                         element="algorithm")
    if kernel not in KERNELS:
        raise SetupError(f"unknown kernel '{kernel}'; choose one of {', '.join(KERNELS)}.", element="--kernel")
    if not (isinstance(threads, int) and threads >= 1):
        raise SetupError(f"the number of threads must be a whole number of at least 1; got {threads!r}.",
                         element="--threads")
    if threads > 1 and (algorithm != "jacobi" or kernel == "python"):
        raise SetupError(f"--threads {threads} steps components in parallel within a Jacobi step of the "
                         f"compiled kernel; this run is {algorithm} with the {kernel} kernel.",
                         element="--threads", hint="Run with --threads 1, or Jacobi and --kernel auto.")
    if (kernel == "native" or threads > 1) and native.library()[0] is None:
        raise SetupError(f"the compiled kernel cannot run this system: {native.library()[1]}.",
                         element="--kernel",
                         hint="Run with --kernel auto (which then runs the Python loop) or --kernel python.")


@dataclass(frozen=True)
class Choice:
    """The interpreter a run's step is made by (``name``: "native" or "python"; ``reason``: under
    "auto", why Python), and the Python interpreter, which makes initialisation's exchange and the
    operations the compiled loop hands back."""
    interpreter: Interpreter
    python: PythonInterpreter
    name: str
    reason: str = ""


def choose_interpreter(program: LinkedProgram, grid: Grid, kernel: str = "auto", threads: int = 1) -> Choice:
    """The compiled loop unless ``kernel`` is "python"; under "auto" Python when the library is
    missing (one notice per process) or no operation has a C form, saying why."""
    python = PythonInterpreter(program, grid)
    if kernel == "python":
        return Choice(python, python, "python")
    lib, reason = native.library()
    if lib is None:
        _notice_once(reason)
        return Choice(python, python, "python", reason)
    in_python = program.python_operations()
    if kernel == "auto" and sum(in_python.values()) == len(program.top_level()):
        return Choice(python, python, "python", "no operation of the step has a C form: " + "; ".join(in_python))
    return Choice(NativeInterpreter(program, grid, python, threads), python, "native")


def _notice_once(reason: str) -> None:
    """Warn once per process that the Python loop runs for ``reason`` (the library is missing)."""
    if reason not in _NOTICES:
        _NOTICES.add(reason)
        warnings.warn(f"{reason}; running the Python stepping loop (same results, slower).", RuntimeWarning,
                      stacklevel=4)
