"""Run a validated plan: instantiate, initialise, step on a fixed grid, record.

The time grid is t_k = t0 + k·h (computed, never accumulated); when
(stop − t0)/h is not a whole number the last step is shortened to end at stop.

Algorithms (recorded in the result metadata):

* ``jacobi`` (default): every FMU steps from the inputs of the last
  communication point; then outputs are read and routed.
* ``gauss-seidel``: FMUs step one after the other in dependency order, each
  seeing the outputs its upstream FMUs have just computed.

At every communication point (and during initialisation) the exchange reads
all outputs, then re-reads the outputs of direct-feedthrough FMUs after
setting their inputs, in dependency order, so a chain of feedthrough blocks
(sums, gains) settles within the instant instead of lagging one step per
block.  Without feedthrough this is plain Jacobi, as libcosim does it.  An
algebraic loop of direct feedthrough is solved by repeating that settling sweep
(`cosim.loops.LoopSolver`), or broken by one step of delay (``loops="delay"``).

Values move through preallocated ctypes arrays with one batched get and one
batched set per FMU and type; routing is precomputed NumPy index arrays.

Kernels (``kernel``, recorded in the metadata): "native" runs the steps in the compiled loop
of `cosim.kernel`, which makes the same FMI calls in the same order with the same
arithmetic (bit-identical results) and returns here for every status above Warning, which
this module then handles and finishes the step with; "python" runs the loop below; "auto"
(default) the compiled one when the library is built and every component is FMI 2.0 or 3.0
Co-Simulation exchanging numbers with no algebraic loop to iterate and no connection with a
mapping table (`cosim.maptables`), else the Python one, saying why (``kernel_reason``).
"""
from __future__ import annotations

import ctypes
import math
import sys
import time as _time
import warnings
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from . import kernel as native
from .errors import ComponentLost, RunError, SetupError
from .description import FMUDescription, exchange_type
from .instances import STATUS, Instance, Unzipped, open_instance
from .instances.base import NativeFunctions, NativeInstance
from .instances.fmi3 import BinaryValue
from .instances.isolated import Isolation
from .instances.reuse import InstancePool
from .interrupts import StopRequest
from .loops import LoopSettings, LoopSolver, Watched
from .structure import Plan
from .observers import Recorder

#: exchange types (`cosim.description.exchange_type`) and their buffers' C types, as fmi2 declares them
#: (Binary, FMI 3.0 only: a pointer and a size, `cosim.instances.fmi3.BinaryValue`)
TYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int, "String": ctypes.c_char_p,
         "Binary": BinaryValue}
ALGORITHMS = ("jacobi", "gauss-seidel")
KERNELS = ("auto", "native", "python")
#: most communication steps of a run (10^9 steps at the fastest ~5 µs/step is over an hour)
MAX_STEPS = 10**9
#: the smallest step, in multiples of the spacing of doubles at the run's largest time
RESOLUTION_STEPS = 1024
FMI_WARNING, FMI_DISCARD = 1, 2


_NOTICES: set[str] = set()


def _notice_once(reason: str) -> None:
    """Warn once per process that the Python loop runs for ``reason`` (the library is missing)."""
    if reason not in _NOTICES:
        _NOTICES.add(reason)
        warnings.warn(f"{reason}; running the Python stepping loop (same results, slower).", RuntimeWarning,
                      stacklevel=3)


@dataclass
class Grid:
    start: float
    stop: float
    step: float

    def __post_init__(self):
        if not (math.isfinite(self.step) and self.step > 0):
            raise SetupError(f"the step size must be a positive number; got {self.step}.", element="step size")
        for what, value in (("start time", self.start), ("stop time", self.stop)):
            if not math.isfinite(value):
                raise SetupError(f"the {what} must be a finite number; got {value}.", element=what)
        if self.stop <= self.start:
            raise SetupError(f"the stop time {self.stop} is not after the start time {self.start}.",
                             element="stop time")
        resolution = math.ulp(max(abs(self.start), abs(self.stop)))
        if self.step < RESOLUTION_STEPS * resolution:
            raise SetupError(f"the step size {self.step:g} s is below the time resolution at t = "
                             f"{max(abs(self.start), abs(self.stop)):g} s ({RESOLUTION_STEPS} x {resolution:g} s, "
                             "the spacing of doubles there): communication times would repeat or drift.",
                             element="step size")
        if not math.isfinite(self.stop - self.start):
            raise SetupError(f"the stop time {self.stop:g} is {self.stop - self.start} s after the start time "
                             f"{self.start:g}: the span overflows a double (at most {sys.float_info.max:g} s).",
                             element="stop time", hint="Choose a stop time nearer the start.")
        steps = (self.stop - self.start) / self.step
        if not steps <= MAX_STEPS:
            raise SetupError(f"{self.stop:g} - {self.start:g} s in steps of {self.step:g} s is {steps:.3g} "
                             f"communication steps; at most {MAX_STEPS:.0e} are run.", element="step size")

    @cached_property
    def steps(self) -> int:
        return max(1, math.ceil((self.stop - self.start) / self.step - 1e-9))

    def time(self, k: int) -> float:
        return self.stop if k >= self.steps else self.start + k * self.step


class _Typed:
    """Outputs (Y) and inputs (U) of one exchange type for all components, in ctypes memory.

    Strings (char*) and Binary values (pointer and size) are not numbers: they are routed by
    a Python loop over the pairs of buffer positions, never transformed, and not recorded (the
    recorder and the CSV hold numeric signals only).  An FMU's string or binary is valid only
    until its next FMI call (FMI 2.0 §2.1.7, FMI 3.0 §2.2.6.2), so every get is followed by a
    copy into memory the buffer owns (`get_call`); a routed Binary keeps that memory alive
    (``owners``) as long as the input holds it.
    """

    def __init__(self, plan: Plan, type_name: str, order: list[str]):
        ctype = TYPES[type_name]
        self.type_name = type_name
        self.strings = type_name in ("String", "Binary")
        self.binary = type_name == "Binary"
        outs = [(c, v) for c in order for v in plan.outputs[c] if exchange_type(v) == type_name]
        ins = [(c, v) for c in order for v in plan.inputs[c] if exchange_type(v) == type_name]
        self.out_names = [f"{c}.{v.name}" for c, v in outs]
        self.in_names = [f"{c}.{v.name}" for c, v in ins]
        self.Ybuf = (ctype * max(1, len(outs)))()
        self.Ubuf = (ctype * max(1, len(ins)))()
        #: Binary only: the memory each buffer position points to, kept alive here
        self.owners = {id(self.Ybuf): [None] * len(outs), id(self.Ubuf): [None] * len(ins)}
        if not self.strings:
            self.Y = np.ctypeslib.as_array(self.Ybuf)[:len(outs)]
            self.U = np.ctypeslib.as_array(self.Ubuf)[:len(ins)]
        self.out_slices = self._slices(outs, order)
        self.in_slices = self._slices(ins, order)
        out_index = {(c, v.name): i for i, (c, v) in enumerate(outs)}
        in_index = {(c, v.name): i for i, (c, v) in enumerate(ins)}
        routes = [r for r in plan.routes if exchange_type(r.src_var) == type_name]
        #: the routes (`cosim.structure.Route`) of each `routes_into` entry, in its order
        self.routes_of: dict[str | None, list] = {None: routes}
        for comp in order:  # feedthrough and Gauss–Seidel route into one component at a time
            self.routes_of[comp] = [r for r in routes if r.dst == comp]
        self.routes_into = {comp: self._routing(rs, out_index, in_index) for comp, rs in self.routes_of.items()}
        #: the routes with a mapping transformation (`cosim.maptables`) of each `routes_into` entry:
        #: (output position, input position, route)
        self.tables_into = {comp: [(out_index[(r.src, r.src_var.name)], in_index[(r.dst, r.dst_var.name)], r)
                                   for r in rs if r.table is not None] for comp, rs in self.routes_of.items()}
        self.ctype = ctype
        self.integer = ctype is ctypes.c_int

    @staticmethod
    def _slices(pairs, order):
        slices = {}
        i = 0
        for comp in order:
            vrs = [v.vr for c, v in pairs if c == comp]
            slices[comp] = (i, len(vrs), (ctypes.c_uint * max(1, len(vrs)))(*vrs))
            i += len(vrs)
        return slices

    @staticmethod
    def _routing(routes, out_index, in_index):
        src = np.array([out_index[(r.src, r.src_var.name)] for r in routes], dtype=np.intp)
        dst = np.array([in_index[(r.dst, r.dst_var.name)] for r in routes], dtype=np.intp)
        factor = np.array([r.factor for r in routes])
        offset = np.array([r.offset for r in routes])
        identity = bool(np.all(factor == 1.0) and np.all(offset == 0.0))
        return src, dst, factor, offset, identity

    def route(self, t: float, comp: str | None = None) -> None:
        """Route the outputs into the inputs (into ``comp``'s only, if given) at time ``t``; a
        factor and offset that make a finite value infinite is a `RunError` (`overflow`)."""
        src, dst, factor, offset, identity = self.routes_into[comp]
        if len(src) == 0:
            return
        if self.strings:
            Y, U = self.Ybuf, self.Ubuf
            for i, j in zip(src.tolist(), dst.tolist()):
                U[j] = Y[i]
            if self.binary:
                Yown, Uown = self.owners[id(Y)], self.owners[id(U)]
                for i, j in zip(src.tolist(), dst.tolist()):
                    Uown[j] = Yown[i]
        elif identity:
            self.U[dst] = self.Y[src]
        else:
            with np.errstate(over="ignore"):  # an overflow is an error of its own below, not a warning
                values = self.Y[src] * factor + offset
            if not np.isfinite(values).all():
                overflowed = np.flatnonzero(~np.isfinite(values) & np.isfinite(self.Y[src]))
                if len(overflowed):
                    raise self.overflow(comp, int(overflowed[0]), t)
            self.U[dst] = values
        for i, j, r in self.tables_into[comp]:
            self.U[j] = self._mapped(r, int(self.Y[i]), t)

    @staticmethod
    def _mapped(r, value: int, t: float) -> int:
        """``value`` through the route's mapping transformations (`cosim.structure.RouteTable`); a
        value that no ssc:MapEntry names is a `RunError`."""
        table = r.table
        key = int(value != 0) if table.boolean else value
        if key not in table.mapping:
            def shown(v: int) -> str:
                return ("true" if v else "false") if table.boolean else str(v)
            raise RunError(f"{r.src}.{r.src_var.name} = {shown(key)} at t = {t:g} is not a source value of "
                           f"{table.elements} (its sources: {', '.join(shown(v) for v in sorted(table.mapping))}); "
                           f"{r.dst}.{r.dst_var.name} was not given it.", time=t, component=r.dst,
                           element=f"connection {r.src}.{r.src_var.name} -> {r.dst}.{r.dst_var.name}")
        return table.mapping[key]

    def overflow(self, comp: str | None, j: int, t: float) -> RunError:
        """The error of route ``j`` of ``routes_into[comp]`` at ``t``: its factor and offset (the
        LinearTransformations and unit conversions on the way) took its finite source value past
        the largest float."""
        r = self.routes_of[comp][j]
        src, _, factor, offset, _ = self.routes_into[comp]
        y = float(self.Y[src[j]])
        value = y * float(factor[j]) + float(offset[j])
        label = f"{r.src}.{r.src_var.name} -> {r.dst}.{r.dst_var.name}"
        return RunError(f"the value {y:.17g} of {r.src}.{r.src_var.name}, times {factor[j]:.17g} plus {offset[j]:.17g} "
                        f"(the connection's LinearTransformation and unit conversions), overflows to {value} at "
                        f"t = {t:g}; {r.dst}.{r.dst_var.name} was not given it.", time=t, component=r.dst,
                        element=f"connection {label}")

    def address(self, buf, start: int) -> int:
        return ctypes.addressof(buf) + start * ctypes.sizeof(self.ctype)

    def pointer(self, buf, start: int):
        return ctypes.cast(self.address(buf, start), ctypes.POINTER(self.ctype))

    def get_call(self, get, buf, start: int, n: int):
        """The get function for the hot loop: ``get`` itself for numbers; for strings, ``get``
        followed by copying the n strings into ``buf`` (reading a c_char_p item copies the
        bytes, writing it back makes the array keep them)."""
        if not self.strings:
            return get
        if self.binary:
            owners = self.owners[id(buf)]

            def get_owned_binary(component, vrs, count, values) -> int:
                status = get(component, vrs, count, values)
                if status <= FMI_WARNING:
                    for i in range(start, start + n):
                        data = ctypes.string_at(buf[i].data, buf[i].size) if buf[i].size else b""
                        owners[i] = ctypes.create_string_buffer(data, max(1, len(data)))
                        buf[i].data = ctypes.cast(owners[i], type(buf[i].data))
                return status
            return get_owned_binary

        def get_owned(component, vrs, count, values) -> int:
            status = get(component, vrs, count, values)
            for i in range(start, start + n):
                buf[i] = buf[i]
            return status
        return get_owned


class Execution:
    """One run of a plan on a grid with an algorithm, feeding a recorder."""

    def __init__(self, plan: Plan, grid: Grid, algorithm: str = "jacobi", fmu_log: str = "errors",
                 loop_settings: LoopSettings | None = None, isolation: Isolation | None = None,
                 kernel: str = "auto", threads: int = 1, pool: InstancePool | None = None):
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
        self.plan = plan
        self.grid = grid
        self.algorithm = algorithm
        self.fmu_log = fmu_log
        #: each component in a process of its own (``--isolate``), or all in this one (None)
        self.isolation = isolation
        self.order = list(plan.components)
        self.typed = [_Typed(plan, t, self.order) for t in TYPES
                      if any(exchange_type(v) == t for c in self.order for v in plan.outputs[c] + plan.inputs[c])]
        #: the input table's values into the input buffers at a time (`cosim.inputs.InputFeed`)
        self._feed = plan.input_table.feed(self.typed, grid) if plan.input_table is not None else None
        self.loop_solver = self._loop_solver(loop_settings or LoopSettings()) \
            if plan.algebraic_loops and plan.loop_mode == "iterate" else None
        if plan.algebraic_loops and plan.loop_mode == "delay":
            warnings.warn("algebraic loop broken by one step of delay (--loops delay): "
                          + "; ".join(loop.describe() for loop in plan.algebraic_loops), RuntimeWarning, stacklevel=2)
        self.instances: dict[str, Instance] = {}
        #: instances kept across runs (`cosim.instances.reuse`): taken from it, given back at `close`
        self.pool = pool if isolation is None else None
        #: the components whose instance came from ``pool`` (reset after an earlier run)
        self.reused: list[str] = []
        self._unzipped = Unzipped()
        self.last_time = grid.start
        self.loop_seconds = 0.0
        self.status = "not started"
        self.message = ""
        self.error: str | None = None
        """The `cosim.errors.Errc` value of the error that ended the run, None otherwise."""
        self.kernel_requested = kernel
        self.threads = threads
        #: with threads: the components whose doSteps run in parallel, and why the others do not
        self.parallel: list[str] = []
        self.serial: dict[str, str] = {}
        #: the loop that runs ("native" or "python"), decided when the FMUs are instantiated, and
        #: under "auto" why the Python loop runs
        self.kernel, self.kernel_reason = "python", ""
        self._native: native.Kernel | None = None
        self._plan_refusal = self._native_refusal() if kernel != "python" else ""
        if (kernel == "native" or threads > 1) and self._plan_refusal:
            self._refuse_native(self._plan_refusal)

    def _native_refusal(self) -> str:
        """Why the compiled loop cannot run this plan (before instantiation), or ""."""
        for name in self.order:
            if self.plan.fmus[name].kind not in ("fmi2-cs", "fmi3-cs"):
                return f"component '{name}' is Model Exchange (integrated by the master)"
        if self._feed is not None:
            return "an input table (--input-file) sets inputs (cosim.inputs, in Python)"
        strings = [ty.type_name for ty in self.typed if ty.strings]
        if strings:
            return f"{' and '.join(strings)} connectors (routed by Python)"
        if self.loop_solver is not None:
            return "an algebraic loop solved by iteration (--loops iterate; cosim.loops stays in Python)"
        tabled = [r for r in self.plan.routes if r.table is not None]
        if tabled:
            r = tabled[0]
            return (f"connection {r.src}.{r.src_var.name} -> {r.dst}.{r.dst_var.name} maps its values through "
                    f"{r.table.elements} (mapping tables are applied by Python, cosim.maptables)")
        return native.library()[1]

    @staticmethod
    def _refuse_native(reason: str) -> None:
        raise SetupError(f"the compiled kernel cannot run this system: {reason}.", element="--kernel",
                         hint="Run with --kernel auto (which then runs the Python loop) or --kernel python.")

    def _loop_solver(self, settings: LoopSettings) -> LoopSolver:
        """`cosim.loops.LoopSolver` over the exchange's output buffers: the loop outputs of each type."""
        loop_outputs = {f"{c}.{v}": (c, v) for loop in self.plan.algebraic_loops for c, v in loop.outputs}
        watched = []
        for ty in self.typed:
            if not ty.strings:
                positions = [i for i, n in enumerate(ty.out_names) if n in loop_outputs]
                watched.append(Watched(ty.Y, np.array(positions, dtype=np.intp), ty.type_name == "Real",
                                       [loop_outputs[ty.out_names[i]] for i in positions]))
        return LoopSolver(self.plan.algebraic_loops, watched, settings, self.plan.feedthrough_sequence)

    # ----------------------------------------------------------------- set-up

    def instantiate(self) -> None:
        for name in self.order:
            desc = self.plan.fmus[name]
            kept = self.pool.take(name, desc, self.fmu_log) if self.pool is not None else None
            if kept is not None:
                self.instances[name] = kept
                self.reused.append(name)
                continue
            opened = open_instance if self.isolation is None else self.isolation.open
            inst = opened(name, desc, self._unzipped(desc.path), self.plan.solvers.get(name))
            self.instances[name] = inst
            inst.instantiate(self.fmu_log)
        self._compile_calls()

    def _compile_calls(self) -> None:
        """Precompute the (function, arguments) tuples of the hot loop."""
        self._get: dict[str, list] = {c: [] for c in self.order}
        self._set: dict[str, list] = {c: [] for c in self.order}
        self._get_inputs: dict[str, list] = {c: [] for c in self.order}
        for ty in self.typed:
            for comp in self.order:
                inst = self.instances[comp]
                start, n, vr = ty.out_slices[comp]
                if n:
                    self._get[comp].append((ty.get_call(inst.get[ty.type_name], ty.Ybuf, start, n),
                                            inst.component, vr, n, ty.pointer(ty.Ybuf, start)))
                start, n, vr = ty.in_slices[comp]
                if n:
                    self._set[comp].append((inst.set[ty.type_name], inst.component, vr, n,
                                            ty.pointer(ty.Ubuf, start)))
                    self._get_inputs[comp].append((ty.get_call(inst.get[ty.type_name], ty.Ubuf, start, n),
                                                   inst.component, vr, n, ty.pointer(ty.Ubuf, start)))
        read_once, set_once = self.plan.read_in_settling_only, self.plan.set_in_settling_only
        self._all_get = [call + (c,) for c in self.order if c not in read_once for call in self._get[c]]
        self._all_set = [call + (c,) for c in self.order if c not in set_once for call in self._set[c]]
        if self.kernel_requested != "python":
            self._choose_kernel()

    # ----------------------------------------------------------------- the compiled loop

    def _choose_kernel(self) -> None:
        """The compiled loop when the plan and every instance allow it (`_native_refusal`,
        `cosim.instances.base.NativeInstance`); else, under "auto", the Python loop and why
        (one notice per process when the library is missing), under "native" a SetupError."""
        functions, reason = {}, self._plan_refusal
        for name in self.order if not reason else ():
            inst = self.instances[name]
            types = [ty.type_name for ty in self.typed if ty.out_slices[name][1] or ty.in_slices[name][1]]
            found = inst.native_functions(types) if isinstance(inst, NativeInstance) else \
                f"component '{name}' offers no FMI function addresses ({type(inst).__name__})"
            if isinstance(found, str):
                reason = found
                break
            functions[name] = found
        if reason:
            if self.kernel_requested == "native" or self.threads > 1:
                self._refuse_native(reason)
            if reason == native.library()[1]:
                _notice_once(reason)
            self.kernel_reason = reason
            return
        operations = self._step_operations(functions) + self._exchange_operations(functions)
        sources = [(ty.address(buf, 0), n, ty.integer) for ty in self.typed
                   for buf, n in ((ty.Ybuf, len(ty.Y)), (ty.Ubuf, len(ty.U)))]
        self._native = native.Kernel(operations, sources, self.grid, 1 + sum(n for _, n, _ in sources),
                                     self.threads, len(self.order) if self.threads > 1 else 0)
        self.kernel = "native"

    def _call_operations(self, kind: int, comp: str, fn: NativeFunctions, at_step_end: bool = True) -> list:
        """The gets (or sets) of ``comp`` as kernel operations: one per exchange type, as ``calls``."""
        get = kind == native.OP_GET
        table = fn.get if get else fn.set
        ops = []
        for ty in self.typed:
            start, n, vr = (ty.out_slices if get else ty.in_slices)[comp]
            if n:
                buf = ty.Ybuf if get else ty.Ubuf
                ops.append(native.Operation(kind, comp, fn.api, table[ty.type_name], fn.component,
                                            ctypes.addressof(vr), n, ty.address(buf, start), at_step_end=at_step_end))
        return ops

    def _route_operations(self, comp: str | None, at_step_end: bool = True) -> list:
        return [native.Operation(native.OP_ROUTE, route=ty.routes_into[comp], integer=ty.integer,
                                 Y=ty.address(ty.Ybuf, 0), U=ty.address(ty.Ubuf, 0), routes_of=(ty, comp),
                                 at_step_end=at_step_end)
                for ty in self.typed if len(ty.routes_into[comp][0])]

    def _route_into_operations(self, comp: str, functions: dict, at_step_end: bool) -> list:
        return (self._route_operations(comp, at_step_end)
                + self._call_operations(native.OP_SET, comp, functions[comp], at_step_end))

    def _step_operations(self, functions: dict) -> list:
        """The doSteps of one step (`_loop`, `_gauss_seidel_step`) as kernel operations."""
        def step(name: str, position: int):
            fn = functions[name]
            return native.Operation(native.OP_STEP, name, fn.api, fn.do_step, fn.component, step_out=fn.step_out,
                                    position=position)
        if self.algorithm != "gauss-seidel":
            ops = [step(name, p) for p, name in enumerate(self.order)]
            if self.threads > 1:  # round robin over the threads; a serial component on the caller's
                self.serial = {name: functions[name].serial for name in self.order if functions[name].serial}
                self.parallel = [name for name in self.order if name not in self.serial]
                for i, name in enumerate(self.parallel):
                    ops[self.order.index(name)] = replace(ops[self.order.index(name)], thread=i % self.threads)
            return ops
        ops = []
        for p, name in enumerate(self.plan.gauss_seidel_order):
            ops += self._route_into_operations(name, functions, at_step_end=False)
            ops.append(step(name, p))
            ops += self._call_operations(native.OP_GET, name, functions[name])
        return ops

    def _exchange_operations(self, functions: dict) -> list:
        """`_exchange` at the end of a step (without an algebraic loop solver) as kernel operations."""
        ops = []
        for comp in self.order:
            if comp not in self.plan.read_in_settling_only:
                ops += self._call_operations(native.OP_GET, comp, functions[comp])
        for comp in self.plan.feedthrough_sequence:
            ops += self._route_into_operations(comp, functions, at_step_end=True)
            ops += self._call_operations(native.OP_GET, comp, functions[comp])
        ops += self._route_operations(None)
        for comp in self.order:
            if comp not in self.plan.set_in_settling_only:
                ops += self._call_operations(native.OP_SET, comp, functions[comp])
        return ops

    def initialize(self) -> None:
        t0, stop = self.grid.start, self.grid.stop
        for name, inst in self.instances.items():
            self._guard(name, t0, "setting up the experiment", lambda: inst.setup_experiment(t0, stop))
        for sv in self.plan.start_values:
            inst = self.instances[sv.component]
            self._guard(sv.component, t0, f"setting {sv.variable.name} = {sv.value} (from {sv.origin})",
                        lambda: inst.set_start(sv.variable, sv.value))
        for name, inst in self.instances.items():
            self._guard(name, t0, "entering initialization mode", inst.enter_initialization_mode)
        for comp in self.order:  # unconnected inputs keep the FMU's (or the binding's) start value
            for call in self._get_inputs[comp]:
                self._check(call[0](*call[1:]), comp, t0, "Get (inputs)")
        self._exchange(t0)
        for name, inst in self.instances.items():
            self._guard(name, t0, "exiting initialization mode", inst.exit_initialization_mode)
        self._exchange(t0)

    def _guard(self, comp: str, t: float, what: str, call) -> None:
        try:
            call()
        except ComponentLost:  # names the component, the call and t already
            raise
        except Exception as e:
            inst = self.instances[comp]
            status = getattr(e, "status", None)
            if status is not None and status >= 3:
                inst.failed = STATUS.get(status, "Fatal")
            raise RunError(f"{what} failed at t = {t:g}: {e}.{inst.last_messages()}", time=t, component=comp,
                           element=f"component '{comp}' ({inst.desc.path.name})") from None

    def _check(self, status: int, comp: str, t: float, what: str) -> None:
        """Raise for a status above Warning; ``what`` is the FMI function without its API prefix
        ("DoStep", "Get"), which the instance gives (`cosim.instances.Instance.api`)."""
        if status > FMI_WARNING:
            inst = self.instances[comp]
            if status >= 3:
                inst.failed = STATUS.get(status, "Fatal")
            raise RunError(f"{inst.api}{what} returned {STATUS.get(status, status)} at t = {t:g}."
                           f"{inst.last_messages()}", time=t, component=comp, status=status,
                           element=f"component '{comp}' ({inst.desc.path.name})")

    # ----------------------------------------------------------------- exchange

    def _exchange(self, t: float) -> None:
        """Read outputs, settle direct feedthrough in dependency order, route, set inputs (an
        input table's values at ``t`` among them: set after the outputs at ``t`` are read, as fmpy
        sets them, `cosim.inputs`)."""
        for fn, c, vr, n, ptr, comp in self._all_get:
            s = fn(c, vr, n, ptr)
            if s > FMI_WARNING:
                self._check(s, comp, t, "Get")
        if self.loop_solver is None:
            self._settle(t)
        else:
            self.loop_solver.solve(t, self._settle)
        for ty in self.typed:
            ty.route(t)
        if self._feed is not None:
            self._feed(t)
        for fn, c, vr, n, ptr, comp in self._all_set:
            s = fn(c, vr, n, ptr)
            if s > FMI_WARNING:
                self._check(s, comp, t, "Set")

    def _settle(self, t: float) -> None:
        """One sweep of the feedthrough sequence: each component's inputs set, its outputs re-read."""
        for comp in self.plan.feedthrough_sequence:
            self._route_into(comp, t)
            self._read_outputs(comp, t)

    def _route_into(self, comp: str, t: float) -> None:
        for ty in self.typed:
            ty.route(t, comp)
        for fn, c, vr, n, ptr in self._set[comp]:
            s = fn(c, vr, n, ptr)
            if s > FMI_WARNING:
                self._check(s, comp, t, "Set")

    # ----------------------------------------------------------------- stepping

    def recorder_sources(self) -> tuple[list[str], list[np.ndarray]]:
        names, arrays = [], []
        for ty in self.typed:
            if ty.strings:
                continue
            names += ty.out_names + ty.in_names
            arrays += [ty.Y, ty.U]
        return names, arrays

    def run(self, recorder: Recorder, progress=None, stop: StopRequest | None = None) -> None:
        """Step from start to stop; ``status`` ends as completed, terminated (an FMU ended the run
        after a valid step, recorded), discarded (an FMU could not complete a step), failed, or
        (when ``stop`` is set by a signal, checked at every communication point) interrupted or
        timeout."""
        self.stop = stop or StopRequest()
        grid = self.grid
        steppers = [(name, self.instances[name].do_step, self.instances[name].component) for name in self.order]
        gs = [(name, self.instances[name].do_step, self.instances[name].component)
              for name in self.plan.gauss_seidel_order]
        gauss_seidel = self.algorithm == "gauss-seidel"
        n_steps = grid.steps
        stride = max(1, n_steps // 200)
        recorder.record(grid.start)
        self._recorder = recorder
        self.status = "running"
        started = _time.perf_counter()
        try:
            if self._native is not None:
                self._native_loop(recorder, progress, steppers, gs, n_steps, stride)
            else:
                self._loop(recorder, progress, steppers, gs, gauss_seidel, n_steps, stride)
        finally:
            self.loop_seconds = _time.perf_counter() - started

    def _loop(self, recorder, progress, steppers, gs, gauss_seidel, n_steps, stride) -> None:
        time = self.grid.time  # computed per step: a list of 10^6 times would cost 32 MB
        exchange, record = self._exchange, recorder.record
        stop = self.stop.flag
        for block in range(0, n_steps, stride):
            for k in range(block, min(block + stride, n_steps)):
                t = time(k)
                t_next = time(k + 1)
                h = t_next - t
                ended: list[tuple[str, str]] = []
                if gauss_seidel:
                    if self._gauss_seidel_step(gs, t, h, t_next, ended):
                        return
                else:
                    for name, do_step, c in steppers:
                        s = do_step(c, t, h, 1)
                        if s and self._step_status(s, name, t, h, ended):
                            return
                if ended:
                    self._terminate(ended, t_next)
                    return
                exchange(t_next)
                record(t_next)
                self.last_time = t_next
                if stop:
                    self._stopped(t_next)
                    return
            if progress is not None:
                progress.update(min(block + stride, n_steps) - block)
        self.status = "completed"

    def _native_loop(self, recorder, progress, steppers, gs, n_steps, stride) -> None:
        """`_loop` in the compiled kernel: it returns here to flush the recorder, for progress,
        when the stop flag is set (by a signal while it runs: `cosim.kernel.Kernel.watch_signals`)
        and for every FMI status above Warning, which `_finish_step` handles."""
        kernel, time, stop = self._native, self.grid.time, self.stop
        watching = bool(stop.signals)
        if watching:
            kernel.watch_signals()
        try:
            k = 0
            for block in range(0, n_steps, stride):
                end = min(block + stride, n_steps)
                while k < end:
                    if stop.flag:
                        kernel.stop_flag.value = stop.flag[0]
                    rows, free_rows, count, flush_at = recorder.window()
                    reason = kernel.run(k, end, rows, free_rows, count, recorder.samples, flush_at)
                    state = kernel.state
                    k = state.k
                    self.last_time = time(k)
                    recorder.filled(state.rows_done, state.samples, bool(reason & (native.KERNEL_FULL |
                                                                                  native.KERNEL_FLUSH)))
                    if reason & native.KERNEL_OVERFLOW:  # a route of step k: as `_Typed.route` raises
                        op = kernel.operations[state.op]
                        ty, comp = op.routes_of
                        raise ty.overflow(comp, state.status, time(k + 1) if op.at_step_end else time(k))
                    if reason & native.KERNEL_STATUS:
                        if self._finish_step(k, kernel.operations[state.op], state.status, steppers, gs):
                            return
                        k += 1
                    elif reason & native.KERNEL_STOP or stop.flag:
                        if not stop.flag:
                            stop.flag.append(kernel.stop_flag.value)
                        self._stopped(self.last_time)
                        return
                if progress is not None:
                    progress.update(end - block)
            self.status = "completed"
        finally:
            if watching:
                kernel.unwatch_signals()

    def _finish_step(self, k: int, op: native.Operation, status: int, steppers, gs) -> bool:
        """Step k after the kernel stopped at ``op`` with ``status``, in Python from there on, as
        `_loop` would have gone on; True when the run ends."""
        t, t_next = self.grid.time(k), self.grid.time(k + 1)
        h = t_next - t
        if op.kind != native.OP_STEP:  # a get or set above Warning: raises
            self._check(status, op.component, t_next if op.at_step_end else t, op.what())
        status = self.instances[op.component].step_outcome(t, h, status)
        ended: list[tuple[str, str]] = []
        if status and self._step_status(status, op.component, t, h, ended):
            return True
        if self.algorithm == "gauss-seidel":
            self._read_outputs(op.component, t_next)
            if self._gauss_seidel_step(gs[op.position + 1:], t, h, t_next, ended):
                return True
        else:
            for position in range(op.position + 1, len(steppers)):
                name, do_step, c = steppers[position]
                if self.threads > 1:  # stepped already, in the parallel phase: its status
                    s = self._native.statuses[position]
                    s = self.instances[name].step_outcome(t, h, s)
                else:
                    s = do_step(c, t, h, 1)
                if s and self._step_status(s, name, t, h, ended):
                    return True
        if ended:
            self._terminate(ended, t_next)
            return True
        self._exchange(t_next)
        self._recorder.record(t_next)
        self.last_time = t_next
        if self.stop.flag:
            self._stopped(t_next)
            return True
        return False

    def _stopped(self, t: float) -> None:
        """The run ends at communication point ``t`` on the signal in ``self.stop``."""
        self.status = self.stop.status()
        self.message = f"stopped by {self.stop.describe()} at t = {t:g}."

    def _gauss_seidel_step(self, gs, t: float, h: float, t_next: float, ended: list) -> bool:
        """Each FMU in dependency order: inputs from the freshest outputs, step, read outputs."""
        for name, do_step, c in gs:
            self._route_into(name, t)
            s = do_step(c, t, h, 1)
            if s and self._step_status(s, name, t, h, ended):
                return True
            self._read_outputs(name, t_next)
        return False

    def _read_outputs(self, comp: str, t: float) -> None:
        for fn, c, vr, n, ptr in self._get[comp]:
            s = fn(c, vr, n, ptr)
            if s > FMI_WARNING:
                self._check(s, comp, t, "Get")

    def _step_status(self, status: int, comp: str, t: float, h: float, ended: list[tuple[str, str]]) -> bool:
        """After a status other than OK: False on Warning; raises on Error and Fatal.  On Discard
        (or FMI 3.0 terminateSimulation), when the FMU's outputs are valid at the end of the step
        (fmi2LastSuccessfulTime = t + h, or an FMI 3.0 step that completed) the component goes
        into ``ended`` and the others still step, so that communication point is recorded
        (`_terminate`); otherwise the run ends now at the last good time (True)."""
        if status == FMI_WARNING:
            return False
        inst = self.instances[comp]
        if status == FMI_DISCARD:
            valid_until, reason = inst.step_end(t, h)
            t_next = t + h
            if valid_until is not None and math.isclose(valid_until, t_next, rel_tol=1e-12, abs_tol=1e-12):
                ended.append((comp, reason))
                return False
            self.status = "discarded"
            self.message = (f"component '{comp}' ({inst.desc.path.name}): {reason} at t = {t:g} (step {h:g}); "
                            f"the run ended at the last good time {self.last_time:g}.{inst.last_messages()}")
            return True
        self._check(status, comp, t, "DoStep")
        return False

    def _terminate(self, ended: list[tuple[str, str]], t_end: float) -> None:
        """FMUs ended the run after a step whose outputs are valid: record that point, then stop."""
        self._exchange(t_end)
        self._recorder.record(t_end)
        self.last_time = t_end
        self.status = "terminated"
        self.message = "; ".join(f"component '{comp}' ({self.instances[comp].desc.path.name}): {reason} at "
                                 f"t = {t_end:g}" for comp, reason in ended) \
            + f"; the run ended there, that point recorded (stop time {self.grid.stop:g})."

    def close(self) -> None:
        if self._native is not None:
            self._native.close()
        for inst in self.instances.values():
            if self.pool is not None:
                self.pool.give(inst, self.status == "completed", self.fmu_log)
            else:
                inst.free()
        self.instances.clear()

    def _component_metadata(self, name: str, d: FMUDescription) -> dict:
        meta = {"fmu": str(d.path), "guid": d.guid, "generation_tool": d.generation_tool, "interface": d.kind}
        if d.kind in ("fmi2-me", "fmi3-me"):  # integrated by the master (cosim.instances.me)
            meta["solver"] = self.plan.solvers[name].as_dict()
        return meta

    def _loop_metadata(self) -> dict | None:
        if self.loop_solver is not None:
            return self.loop_solver.metadata()
        if self.plan.algebraic_loops:
            return {"mode": "delay", "loops": [loop.describe() for loop in self.plan.algebraic_loops]}
        return None

    def metadata(self) -> dict:
        kernel = {"kernel": self.kernel} | ({"kernel_reason": self.kernel_reason} if self.kernel_reason else {}) \
            | ({"threads": self.threads, "parallel_components": self.parallel, "serial_components": self.serial}
               if self.threads > 1 else {})
        return {
            "algorithm": self.algorithm, **kernel,
            "gauss_seidel_order": self.plan.gauss_seidel_order if self.algorithm == "gauss-seidel" else None,
            "feedthrough_sequence": self.plan.feedthrough_sequence,
            "algebraic_loops": self._loop_metadata(),
            "start_time": self.grid.start, "stop_time": self.grid.stop, "step_size": self.grid.step,
            "status": self.status, "last_time": self.last_time, "message": self.message, "error": self.error,
            "steps": self.grid.steps, "loop_seconds": self.loop_seconds,
            "components": {name: self._component_metadata(name, d) for name, d in self.plan.fmus.items()},
            **({"reused_instances": self.reused,
                "reset_refused": {Path(fmu).name: why for fmu, why in self.pool.refused.items()}}
               if self.pool is not None else {}),
            "parameters": {f"{sv.component}.{sv.variable.name}": sv.value for sv in self.plan.start_values},
            "finished_at": _time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
