"""The compiled stepping loop (``kernel.c``) and its ctypes binding; the same library formats
result CSV rows (``csvrows.c``, used by `cosim.record.csvformat`) and FMI 2.0 log messages
(``fmulog.c``, `fmi2_logger`, used by `cosim.run.instances.fmi2`).

`cosim.run.program` compiles a communication step into one list of operations; an operation C can
run carries its `NativeOp` (doSteps, gets, sets, affine routes and routes through mapping tables),
the others none.
`Kernel` runs that list step after step in C, writing each recorded row into the recorder's
chunk buffer, and returns to Python for everything else (an operation without a `NativeOp`,
flushing, progress, signals, any FMI status above Warning, see ``kernel.c``), which resumes it
at an operation index (`cosim.run.interpreters.NativeInterpreter`).

The library is built from ``kernel.c`` when greyfmu is installed (an optional setuptools
extension, ``setup.py``: no Python C API, loaded here with ctypes); `library` finds it, or
says why not, and refuses a library whose ``cosim_kernel_abi`` (version and structure sizes)
differs from the ctypes mirrors below (one built before an edit of ``kernel.c``).
``COSIM_KERNEL_LIBRARY`` names another file to load (tests use a missing or a stale one to
check the fallback).
"""
from __future__ import annotations

import ctypes
import importlib.machinery
import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

OP_STEP, OP_GET, OP_SET, OP_ROUTE, OP_PYTHON, OP_MAP = 0, 1, 2, 3, 4, 5
#: why `Kernel.run` returned (bits): step k_end reached, buffer full, flush due, stop flag set,
#: an FMI status for Python to handle, a route whose value C could not make (a factor and offset
#: that overflowed, a value a table names no target for: its index in the status), an operation
#: for Python to run
KERNEL_END, KERNEL_FULL, KERNEL_FLUSH, KERNEL_STOP, KERNEL_STATUS, KERNEL_UNMADE, KERNEL_YIELD = \
    1, 2, 4, 8, 16, 32, 64
LIBRARY_ENV = "COSIM_KERNEL_LIBRARY"
#: KERNEL_ABI_VERSION of kernel.c: the layout of the structures mirrored below
ABI_VERSION = 5


class _Op(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_int), ("api", ctypes.c_int), ("integer", ctypes.c_int), ("identity", ctypes.c_int),
                ("thread", ctypes.c_int), ("fn", ctypes.c_void_p), ("instance", ctypes.c_void_p), ("vr", ctypes.c_void_p),
                ("n", ctypes.c_size_t), ("values", ctypes.c_void_p),
                ("event", ctypes.c_void_p), ("terminate", ctypes.c_void_p), ("early", ctypes.c_void_p),
                ("last", ctypes.c_void_p),
                ("src", ctypes.c_void_p), ("dst", ctypes.c_void_p), ("factor", ctypes.c_void_p),
                ("offset", ctypes.c_void_p), ("Y", ctypes.c_void_p), ("U", ctypes.c_void_p)]


class _Table(ctypes.Structure):
    _fields_ = [("keys", ctypes.c_void_p), ("values", ctypes.c_void_p), ("n", ctypes.c_size_t),
                ("boolean", ctypes.c_int)]


class _Source(ctypes.Structure):
    _fields_ = [("values", ctypes.c_void_p), ("n", ctypes.c_size_t), ("integer", ctypes.c_int),
                ("consecutive", ctypes.c_int), ("columns", ctypes.c_void_p)]


class _Program(ctypes.Structure):
    _fields_ = [("ops", ctypes.POINTER(_Op)), ("n_ops", ctypes.c_int), ("pool", ctypes.c_void_p),
                ("n_parallel", ctypes.c_int), ("statuses", ctypes.POINTER(ctypes.c_int)), ("sources", ctypes.POINTER(_Source)),
                ("n_sources", ctypes.c_int), ("columns", ctypes.c_int), ("start", ctypes.c_double),
                ("step", ctypes.c_double), ("stop", ctypes.c_double), ("steps", ctypes.c_longlong)]


class _Run(ctypes.Structure):
    _fields_ = [("k", ctypes.c_longlong), ("k_end", ctypes.c_longlong), ("rows", ctypes.c_void_p),
                ("free_rows", ctypes.c_longlong), ("rows_done", ctypes.c_longlong), ("count", ctypes.c_void_p),
                ("samples", ctypes.c_longlong), ("flush_at", ctypes.c_double), ("stop", ctypes.c_void_p),
                ("first", ctypes.c_int), ("op", ctypes.c_int), ("status", ctypes.c_int)]


def _library_path() -> Path | None:
    override = os.environ.get(LIBRARY_ENV)
    if override:
        return Path(override)
    here = Path(__file__).parent
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        if (here / f"_kernel{suffix}").is_file():
            return here / f"_kernel{suffix}"
    return None


def _abi_mismatch(lib: ctypes.CDLL) -> str:
    """How the library's structures differ from the ctypes mirrors (`cosim_kernel_abi`), or ""."""
    try:
        abi = lib.cosim_kernel_abi
    except AttributeError:
        return "it has no cosim_kernel_abi (older than the ABI check)"
    mirrors = (_Op, _Source, _Program, _Run, _Table)
    sizes = (ctypes.c_size_t * len(mirrors))()
    abi.argtypes, abi.restype = [ctypes.POINTER(ctypes.c_size_t)], ctypes.c_int
    version = abi(sizes)
    if version != ABI_VERSION:
        return f"ABI version {version}, expected {ABI_VERSION}"
    wrong = [f"sizeof({m.__name__[1:]}) is {size} bytes in C, {ctypes.sizeof(m)} in ctypes"
             for m, size in zip(mirrors, sizes) if size != ctypes.sizeof(m)]
    return "; ".join(wrong)


@lru_cache(maxsize=1)
def library() -> tuple[ctypes.CDLL | None, str]:
    """The loaded kernel library, or None and why it is not available."""
    path = _library_path()
    if path is None:
        return None, (f"the compiled kernel was not built when greyfmu was installed (no C compiler?): no "
                      f"_kernel library in {Path(__file__).parent}")
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as e:
        return None, f"the compiled kernel {path} cannot be loaded: {e}"
    mismatch = _abi_mismatch(lib)
    if mismatch:
        return None, f"the compiled kernel {path} does not match cosim/kernel/__init__.py: {mismatch} (a library " \
                     f"built before kernel.c changed: reinstall greyfmu, `python -m pip install -e .`)"
    lib.cosim_run.argtypes = [ctypes.POINTER(_Program), ctypes.POINTER(_Run)]
    lib.cosim_run.restype = ctypes.c_int
    lib.cosim_watch_signals.argtypes = [ctypes.POINTER(ctypes.c_int)]
    lib.cosim_watch_signals.restype = ctypes.c_int
    lib.cosim_unwatch_signals.argtypes = []
    lib.cosim_unwatch_signals.restype = None
    lib.cosim_pool_new.argtypes = [ctypes.c_int]
    lib.cosim_pool_new.restype = ctypes.c_void_p
    lib.cosim_pool_free.argtypes = [ctypes.c_void_p]
    lib.cosim_pool_free.restype = None
    lib.cosim_csv_value_max.argtypes = []
    lib.cosim_csv_value_max.restype = ctypes.c_int
    lib.cosim_format_rows.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_void_p]
    lib.cosim_format_rows.restype = ctypes.c_size_t
    return lib, ""


#: the Python side of `fmi2_logger`: (environment, instance name, status, category, message)
LogTarget = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)


def fmi2_logger(target: LogTarget) -> int | None:
    """The C address of ``fmulog.c``'s FMI 2.0 logger (an fmi2CallbackLogger that formats a message
    only where it safely can, else hands it over verbatim), made to hand each message to
    ``target`` (the caller keeps ``target`` alive); None without the library or in one built
    before ``fmulog.c`` (the caller then receives every message verbatim)."""
    lib, _ = library()
    if lib is None or not hasattr(lib, "cosim_fmi2_log"):
        return None
    lib.cosim_fmi2_log_target.argtypes = [LogTarget]
    lib.cosim_fmi2_log_target.restype = None
    lib.cosim_fmi2_log_target(target)
    return ctypes.cast(lib.cosim_fmi2_log, ctypes.c_void_p).value


@dataclass(frozen=True)
class NativeOp:
    """The C form of one operation of a step (`cosim.run.program.Operation.native`).

    ``kind``: OP_STEP, OP_GET, OP_SET (an FMI call on the instance handle ``instance``, ``api`` 2
    or 3 telling the C signature of the function at address ``fn``; a get or set exchanges ``n``
    values of references at ``vr`` with the buffer at ``values``), OP_ROUTE (``route``: source
    and destination positions, factor, offset, identity, on the buffers at ``Y`` and ``U`` of C
    ints when ``integer``, else doubles) or OP_MAP (``route``: source and destination positions;
    ``tables``: per route the C form of its `cosim.model.transforms.Table`, sorted keys, their
    values and whether they are Booleans, on C int buffers).  ``post_step``: for a doStep, the addresses of
    fmi3DoStep's out-arguments (eventHandlingNeeded, terminateSimulation, earlyReturn,
    lastSuccessfulTime), zeros for FMI 2.0; a set terminateSimulation returns to Python, which
    runs the instance's post-step (`cosim.run.instances.Instance.step_outcome`).  ``thread``: with
    threads, which one makes a doStep of the parallel phase (0: the caller).
    """
    kind: int
    api: int = 2
    fn: int = 0
    instance: int = 0
    vr: int = 0
    n: int = 0
    values: int = 0
    post_step: tuple[int, int, int, int] = (0, 0, 0, 0)
    route: tuple | None = None
    tables: tuple | None = None
    integer: bool = False
    Y: int = 0
    U: int = 0
    thread: int = 0


class Kernel:
    """The compiled loop over one step's operations (their `NativeOp`, None for one Python runs:
    the loop returns at it) on ``grid``, recording a row after each step (what goes where:
    `record`); with ``threads`` > 1, the first ``parallel`` operations (doSteps) run
    concurrently, each on its ``thread`` (`close` ends the threads)."""

    def __init__(self, operations: Sequence[NativeOp | None], grid, threads: int = 1, parallel: int = 0):
        self.lib, reason = library()
        if self.lib is None:
            raise RuntimeError(reason)
        self._keep: list = []
        ops = (_Op * max(1, len(operations)))()
        for o, op in zip(ops, operations):
            if op is None:
                o.kind = OP_PYTHON
                continue
            o.kind, o.api, o.integer, o.thread = op.kind, op.api, int(op.integer), op.thread
            o.fn, o.instance, o.vr, o.n, o.values = op.fn, op.instance, op.vr, op.n, op.values
            o.event, o.terminate, o.early, o.last = op.post_step
            if op.kind == OP_MAP:
                src, dst = (np.ascontiguousarray(a, dtype=np.intp) for a in op.route)
                tables = (_Table * len(op.tables))()
                held = [src, dst, tables]
                for t, (keys, values, boolean) in zip(tables, op.tables):
                    k, v = np.array(keys, dtype=np.intc), np.array(values, dtype=np.intc)
                    held += [k, v]
                    t.keys, t.values, t.n, t.boolean = k.ctypes.data, v.ctypes.data, len(k), int(boolean)
                self._keep.append(held)
                # kernel.c's Op holds the tables where a route's factors are (a union)
                o.src, o.dst, o.factor, o.n, o.Y, o.U = src.ctypes.data, dst.ctypes.data, ctypes.addressof(tables), \
                    len(src), op.Y, op.U
            elif op.route is not None:
                src, dst, factor, offset, identity = op.route
                arrays = (np.ascontiguousarray(src, dtype=np.intp), np.ascontiguousarray(dst, dtype=np.intp),
                          np.ascontiguousarray(factor, dtype=np.float64),
                          np.ascontiguousarray(offset, dtype=np.float64))
                self._keep.append(arrays)
                o.src, o.dst, o.factor, o.offset = (a.ctypes.data for a in arrays)
                o.identity, o.n, o.Y, o.U = int(identity), len(arrays[0]), op.Y, op.U
        self._ops = ops
        #: with threads: the statuses of the parallel doSteps of the last step
        self.statuses = (ctypes.c_int * max(1, len(operations)))()
        self.pool = None
        if threads > 1:
            self.pool = self.lib.cosim_pool_new(threads)
            if not self.pool:
                raise RuntimeError(f"the kernel could not start {threads - 1} threads")
        self.program = _Program(ops, len(operations), self.pool, parallel if self.pool else 0, self.statuses,
                                None, 0, 1, grid.start, grid.step, grid.stop, grid.steps)
        self.state = _Run()
        self.stop_flag = ctypes.c_int(0)
        self.state.stop = ctypes.addressof(self.stop_flag)

    def record(self, sources: Sequence[tuple[int, int, bool, np.ndarray]], columns: int) -> None:
        """What each row holds: rows of ``columns`` doubles, the time in column 0, then per source
        (an exchange buffer's address, its length, whether it holds C ints, and the column of each
        of its values: int32, kept alive by the caller) its values in their columns."""
        srcs = (_Source * max(1, len(sources)))()
        for s, (values, n, integer, where) in zip(srcs, sources):
            s.values, s.n, s.integer, s.columns = values, n, int(integer), where.ctypes.data
            s.consecutive = int(n > 0 and bool(np.all(np.diff(where) == 1)))
        self._sources = srcs
        self.program.sources, self.program.n_sources, self.program.columns = srcs, len(sources), columns

    def run(self, k: int, k_end: int, first: int, rows: int, free_rows: int, count: int, samples: int,
            flush_at: float) -> int:
        """Steps k .. k_end - 1, step k from its operation ``first``, into the buffer at address
        ``rows`` (``free_rows`` rows free); returns the KERNEL_* bits; `state` holds the step
        reached, the rows and samples done, and, on KERNEL_STATUS, KERNEL_UNMADE and
        KERNEL_YIELD, the operation (and its status)."""
        r = self.state
        r.k, r.k_end, r.first, r.rows, r.free_rows, r.rows_done = k, k_end, first, rows, free_rows, 0
        r.count, r.samples, r.flush_at = count, samples, flush_at
        return self.lib.cosim_run(ctypes.byref(self.program), ctypes.byref(r))

    def watch_signals(self) -> None:
        """SIGINT, SIGTERM and SIGALRM set the stop flag (and still reach their Python handler)."""
        if self.lib.cosim_watch_signals(ctypes.byref(self.stop_flag)) != 0:
            raise RuntimeError("the kernel could not install its signal handlers")

    def unwatch_signals(self) -> None:
        self.lib.cosim_unwatch_signals()

    def close(self) -> None:
        """End the threads, if any (before the instances they call are freed)."""
        if self.pool:
            self.lib.cosim_pool_free(self.pool)
            self.pool = self.program.pool = None
