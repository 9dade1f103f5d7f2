"""A compiled step (`cosim.run.program.StepProgram`) linked to a run's live instances: the only place
instances and memory enter the step (`link` -> `LinkedProgram`).

`link` makes the exchange buffers (`cosim.run.exchange`), the input feed (`cosim.run.feed`) and the
algebraic-loop solver (`cosim.run.loops`) of the plan, and gives every operation its Python form
(``call(t, h, t_next) -> FMI status``; a route, map, feed and solve return 0 or raise a
`RunError`) and, where the compiled loop can make it, its C form (``native``, `cosim.kernel.NativeOp`:
the instances' FMI function addresses, `cosim.run.instances.base.NativeInstance`, the buffers'
addresses, a transformation's C form); ``why_python`` says why not otherwise.  The interpreters
(`cosim.run.interpreters`) run the same list, the compiled one handing back to Python each
operation without a C form, so both make the same calls in the same order with the same
arithmetic.  With threads (Jacobi only), the doSteps that may run concurrently are spread round
robin over them (a pythonfmu FMU, or one instantiated once per process, stays on the caller's).
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import cache

import numpy as np

from .. import kernel as native
from ..errors import SetupError
from ..model.grid import Grid
from .exchange import TypedBuffers, exchange_buffers
from .feed import InputFeed, warn_off_grid
from .instances import Instance
from .instances.base import NativeInstance, fmi_failure
from .loops import LoopSettings, LoopSolver, Watched
from .program import OP_FEED, OP_GET, OP_MAP, OP_ROUTE, OP_SET, OP_SOLVE, OP_STEP, Op, StepProgram

_WHAT = {OP_STEP: "DoStep", OP_GET: "Get", OP_SET: "Set", OP_ROUTE: "route", OP_MAP: "mapped route",
         OP_FEED: "input table", OP_SOLVE: "algebraic loop"}
#: (t, h, t_next) -> FMI status
Call = Callable[[float, float, float], int]


@dataclass(frozen=True)
class Operation:
    """One operation of a linked step: its `cosim.run.program.Op` (``kind``, ``component``,
    ``type_name``, ``at_step_end``, ``next``) with its Python form ``call`` and C form ``native``;
    ``instance``: the component's instance (FMI calls); ``post_step``: after its C form returned,
    the instance's post-step (`cosim.run.instances.Instance.step_outcome`) that turns the raw status
    into the one ``call`` returns."""
    kind: int
    call: Call
    native: native.NativeOp | None
    why_python: str = ""
    component: str | None = None
    instance: Instance | None = field(default=None, repr=False, compare=False)
    type_name: str = ""
    at_step_end: bool = True
    post_step: Callable[[float, float, int], int] | None = field(default=None, repr=False, compare=False)
    next: int = -1

    @property
    def what(self) -> str:
        """The FMI function without its prefix ("DoStep", "Get", "Set"), or what else it is."""
        return _WHAT[self.kind]

    def time(self, t: float, t_next: float) -> float:
        """When a failure of this operation in the step from t to t_next happened."""
        return t_next if self.at_step_end else t

    def failure(self, status: int, t: float) -> Exception:
        """The error of an FMI call of this operation that returned ``status`` above Warning."""
        return fmi_failure(self.instance, self.what, status, t)


@dataclass(frozen=True)
class LinkedProgram:
    """A step program on live instances: ``operations`` (``[0, step_ops)`` the step, the rest the
    exchange at its end) on ``buffers``; with threads, the first ``parallel`` are doSteps made
    concurrently (``parallel_components``; ``serial``: the components kept on the calling thread,
    and why); the ``loop_solver`` of an iterated algebraic loop and the input table's ``feed``."""
    program: StepProgram
    operations: tuple[Operation, ...]
    buffers: tuple[TypedBuffers, ...]
    parallel: int = 0
    parallel_components: tuple[str, ...] = ()
    serial: Mapping[str, str] = field(default_factory=dict)
    loop_solver: LoopSolver | None = None
    feed: InputFeed | None = None

    @property
    def step_ops(self) -> int:
        return self.program.step_ops

    def top_level(self, first: int = 0, last: int | None = None) -> list[int]:
        """`cosim.run.program.StepProgram.top_level`."""
        return self.program.top_level(first, last)

    def python_operations(self) -> dict[str, int]:
        """Why operations run in Python (with the compiled loop: how often it hands back), and
        how many of them for each reason."""
        counts: dict[str, int] = {}
        for i in self.top_level():
            op = self.operations[i]
            if op.native is None:
                counts[op.why_python] = counts.get(op.why_python, 0) + 1
        return counts

    def recorder_sources(self) -> tuple[list[str], list[np.ndarray]]:
        """The recorded signals' names and the arrays that hold them, in the order rows are
        written (each type's outputs, then its inputs)."""
        names, arrays = [], []
        for ty in self.buffers:
            if ty.strings:
                continue
            names += ty.out_names + ty.in_names
            arrays += [ty.Y, ty.U]
        return names, arrays


def link(program: StepProgram, instances: Mapping[str, Instance], grid: Grid,
         loop_settings: LoopSettings | None = None, threads: int = 1) -> LinkedProgram:
    """``program`` on the live ``instances`` (see the module docstring); ``grid``: the run's, which
    an input table's events are checked against; ``threads`` > 1 (Jacobi only) spreads the doSteps
    that may run concurrently round robin over that many threads, and refuses a doStep only Python
    can make."""
    plan = program.plan
    buffers = tuple(exchange_buffers(plan, list(plan.components)))
    feed = None
    if plan.input_table is not None:
        warn_off_grid(plan.input_table, grid)
        feed = InputFeed(plan.input_table, list(buffers))
    solver = _loop_solver(program, buffers, loop_settings or LoopSettings()) \
        if any(op.kind == OP_SOLVE for op in program.ops) else None
    linker = _Linker(program, buffers, instances, feed, solver)
    operations = [linker.operation(op) for op in program.ops]
    for i, op in enumerate(program.ops):  # an iteration's block is known once every operation is
        if op.kind == OP_SOLVE:
            operations[i] = _solve(solver, operations[i + 1:op.next], op.next)
    parallel, serial, parallel_components = 0, {}, ()
    if threads > 1:
        serial = linker.serial
        operations[:program.step_ops], parallel_components = _threaded(operations[:program.step_ops],
                                                                       list(plan.components), threads, serial)
        parallel = program.step_ops
    return LinkedProgram(program, tuple(operations), buffers, parallel, parallel_components, serial, solver, feed)


def _loop_solver(program: StepProgram, buffers: tuple[TypedBuffers, ...], settings: LoopSettings) -> LoopSolver:
    """`cosim.run.loops.LoopSolver` over the exchange's output buffers: the loop outputs of each type."""
    plan = program.plan
    loop_outputs = {f"{c}.{v}": (c, v) for loop in plan.algebraic_loops for c, v in loop.outputs}
    watched = []
    for ty in buffers:
        if not ty.strings:
            positions = [i for i, n in enumerate(ty.out_names) if n in loop_outputs]
            watched.append(Watched(ty.Y, np.array(positions, dtype=np.intp), ty.type_name == "Real",
                                   [loop_outputs[ty.out_names[i]] for i in positions]))
    return LoopSolver(plan.algebraic_loops, watched, settings, plan.feedthrough_sequence)


class _Linker:
    """Each `Op`'s live `Operation` (`link`)."""

    def __init__(self, program: StepProgram, buffers: tuple[TypedBuffers, ...], instances: Mapping[str, Instance],
                 feed: InputFeed | None, solver: LoopSolver | None):
        self.plan, self.instances, self.feed = program.plan, instances, feed
        self.buffers = {ty.type_name: ty for ty in buffers}
        #: the components whose doStep must not run concurrently with others', and why
        self.serial: dict[str, str] = {}

    def operation(self, op: Op) -> Operation:
        if op.kind == OP_STEP:
            return self.step(op)
        if op.kind in (OP_GET, OP_SET):
            return self.call(op)
        if op.kind == OP_ROUTE:
            return self.route(op)
        if op.kind == OP_MAP:
            return self.map(op)
        if op.kind == OP_FEED:
            return self.make(op, _feed(self.feed), None, "an input table (--input-file) sets inputs (cosim.run.feed)")
        return self.make(op, _unlinked, None)   # OP_SOLVE: made by `link` once its block is linked

    @staticmethod
    def make(op: Op, call: Call, c_form: native.NativeOp | None, why: str = "", **kw) -> Operation:
        return Operation(op.kind, call, c_form, "" if c_form is not None else why, component=op.component,
                         type_name=op.type_name, at_step_end=op.at_step_end, next=op.next, **kw)

    def step(self, op: Op) -> Operation:
        inst = self.instances[op.component]
        found = inst.native_step() if _native(type(inst)) else _no_functions(inst)
        c_form, post_step, why = None, None, found
        if not isinstance(found, str):
            c_form = native.NativeOp(native.OP_STEP, found.api, found.do_step, found.component,
                                     post_step=found.post_step)
            post_step = inst.step_outcome if any(found.post_step) else None
            if found.serial:
                self.serial[op.component] = found.serial
        return self.make(op, _do_step(inst.do_step, inst.component), c_form, why, instance=inst, post_step=post_step)

    def call(self, op: Op) -> Operation:
        """The batched get (or set) of a component and exchange type."""
        get = op.kind == OP_GET
        inst, ty = self.instances[op.component], self.buffers[op.type_name]
        start, n, vr = (ty.out_slices if get else ty.in_slices)[op.component]
        buf = ty.Ybuf if get else ty.Ubuf
        fn = ty.get_call(inst.get[ty.type_name], buf, start, n) if get else inst.set[ty.type_name]
        found = inst.native_exchange(ty.type_name) if _native(type(inst)) else _no_functions(inst)
        c_form, why = None, found
        if not isinstance(found, str):
            c_form = native.NativeOp(op.kind, _api(inst), found[0 if get else 1], inst.component,
                                     ctypes.addressof(vr), n, ty.address(buf, start))
        return self.make(op, _exchange(fn, inst.component, vr, n, ty.pointer(buf, start)), c_form, why, instance=inst)

    def route(self, op: Op) -> Operation:
        """Routes whose transformations are affine, y·factor + offset."""
        ty = self.buffers[op.type_name]
        group = ty.affine([self.plan.routes[i] for i in op.routes])
        c_form = None if ty.strings else native.NativeOp(native.OP_ROUTE, route=group.native(), integer=ty.integer,
                                                         Y=ty.address(ty.Ybuf, 0), U=ty.address(ty.Ubuf, 0))
        return self.make(op, _timed(ty.route, group, op.at_step_end), c_form,
                         f"{ty.type_name} connections (routed by Python)")

    def map(self, op: Op) -> Operation:
        """Routes through other transformations: in C where each has a table's C form
        (`cosim.model.transforms.Transform.native`)."""
        ty = self.buffers[op.type_name]
        mapped = ty.mapped([self.plan.routes[i] for i in op.routes])
        forms = [r.transform.native() for _, _, r in mapped]
        tables = ty.integer and not ty.strings and all(f is not None and f[0] == "table" for f in forms)
        c_form = native.NativeOp(native.OP_MAP, route=(np.array([i for i, _, _ in mapped], dtype=np.intp),
                                                       np.array([j for _, j, _ in mapped], dtype=np.intp)),
                                 tables=tuple(f[1:] for f in forms), integer=True, Y=ty.address(ty.Ybuf, 0),
                                 U=ty.address(ty.Ubuf, 0)) if tables else None
        r = next((r for (_, _, r), f in zip(mapped, forms) if f is None or f[0] != "table"), mapped[0][2])
        why = (f"connection {r.label} maps its values through {r.transform.text(r.source)}, which has no C form "
               "(cosim.model.transforms)")
        return self.make(op, _timed(ty.map_values, mapped, op.at_step_end), c_form, why)


@cache
def _native(kind: type) -> bool:
    """Whether instances of ``kind`` are `NativeInstance`s (a Protocol's isinstance check walks its
    members each time: 0.1 ms, once per class here)."""
    return issubclass(kind, NativeInstance)


def _api(inst: Instance) -> int:
    return 3 if inst.api == "fmi3" else 2


def _no_functions(inst: Instance) -> str:
    return f"component '{inst.name}' offers no FMI function addresses ({type(inst).__name__})"


def _threaded(ops: list[Operation], order: list[str], threads: int, serial: Mapping[str, str]
              ) -> tuple[list[Operation], tuple[str, ...]]:
    """The doSteps of a Jacobi step round robin over ``threads``, a ``serial`` one on the
    caller's (thread 0); a doStep only Python can make is refused."""
    python = [op for op in ops if op.native is None]
    if python:
        raise SetupError(f"--threads {threads} steps components in parallel in the compiled kernel, and "
                         f"{python[0].why_python}: its doStep is made by Python.", element="--threads",
                         hint="Run with --threads 1.")
    parallel = [c for c in order if c not in serial]
    threaded = [replace(op, native=replace(op.native, thread=parallel.index(op.component) % threads))
                if op.component in parallel else op for op in ops]
    return threaded, tuple(parallel)


def _unlinked(t: float, h: float, t_next: float) -> int:
    raise AssertionError("an operation linked without its Python form")


def _do_step(do_step, component) -> Call:
    def call(t: float, h: float, t_next: float) -> int:
        return do_step(component, t, h, 1)
    return call


def _exchange(fn, component, vr, n: int, values) -> Call:
    def call(t: float, h: float, t_next: float) -> int:
        return fn(component, vr, n, values)
    return call


def _timed(make, group, at_step_end: bool) -> Call:
    """``make(group, t)``: at t + h (``at_step_end``) or at t."""
    if at_step_end:
        def call(t: float, h: float, t_next: float) -> int:
            make(group, t_next)
            return 0
    else:
        def call(t: float, h: float, t_next: float) -> int:
            make(group, t)
            return 0
    return call


def _feed(feed: InputFeed) -> Call:
    def call(t: float, h: float, t_next: float) -> int:
        feed(t_next)
        return 0
    return call


def _solve(solver: LoopSolver, block: list[Operation], end: int) -> Operation:
    """The algebraic loop's iteration at t + h over ``block`` (the settling sweep that follows
    it, up to ``end``), in Python: an FMI status above Warning in a sweep fails the run."""
    def sweep(t: float) -> None:
        for op in block:
            status = op.call(t, 0.0, t)
            if status > 1:
                raise op.failure(status, t)

    def call(t: float, h: float, t_next: float) -> int:
        solver.solve(t_next, sweep)
        return 0
    return Operation(OP_SOLVE, call, None, "an algebraic loop solved by iteration (--loops iterate, cosim.run.loops)",
                     next=end)
