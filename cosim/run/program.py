"""One communication step as a program of operations: the only description of what the master
does from t to t + h (compile: plan and instances -> `Program`).

The program is a list of `Operation`: doSteps (OP_STEP), batched gets and sets of one
component and exchange type (OP_GET, OP_SET), routes of one exchange type into one component
or all (OP_ROUTE: the affine ones, y·factor + offset, `cosim.run.exchange.TypedBuffers.route`; OP_MAP:
the others, mapping tables, `cosim.model.transforms`), the input table (OP_FEED, `cosim.plan.inputs`) and the
iteration of an algebraic loop (OP_SOLVE, `cosim.run.loops.LoopSolver`) over the settling sweep that
follows it in the list (its block, up to ``Operation.next``).  Operations ``[0, step_ops)`` make
the step, the rest is the exchange at its end, which initialisation also runs at t0:

* Jacobi (default): every doStep (with threads, the first ``parallel`` ones run concurrently);
  Gauss–Seidel: per component in dependency order, its inputs routed and set, its doStep, its
  outputs read;
* the exchange: every output read; the direct-feedthrough settling in dependency order (each
  component's inputs routed and set, its outputs read again), or that sweep iterated by the loop
  solver; every route; the input table's values; every input set.  Components whose outputs
  only the settling reads, or whose inputs only it sets, are left out of the batched reads and
  sets (`cosim.model.structure.Plan.read_in_settling_only`).

Each operation has a Python form (``call(t, h, t_next) -> FMI status``; a route, table, feed
and solve return 0 or raise a `RunError`) and, where the compiled loop can make it, a C form
(``native``, `cosim.kernel.NativeOp`); ``why_python`` says why not otherwise.  The interpreters
(`cosim.run.interpreters`) run the same list, the compiled one handing back to Python each
operation without a C form, so both make the same calls in the same order with the same
arithmetic.
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .. import kernel as native
from ..errors import SetupError
from .exchange import TypedBuffers
from ..plan.inputs import InputFeed
from .instances import Instance
from .instances.base import NativeInstance, fmi_failure
from .loops import LoopSolver
from ..model.structure import Plan

OP_STEP, OP_GET, OP_SET, OP_ROUTE, OP_MAP = native.OP_STEP, native.OP_GET, native.OP_SET, native.OP_ROUTE, native.OP_MAP
#: operations only Python makes
OP_FEED, OP_SOLVE = 6, 7
_WHAT = {OP_STEP: "DoStep", OP_GET: "Get", OP_SET: "Set", OP_ROUTE: "route", OP_MAP: "mapped route",
         OP_FEED: "input table", OP_SOLVE: "algebraic loop"}
#: (t, h, t_next) -> FMI status
Call = Callable[[float, float, float], int]


@dataclass(frozen=True)
class Operation:
    """One operation of a step (see the module docstring).

    ``component``: whose FMI call it is, or the component a route or table feeds (None: all);
    ``instance``: that component's instance (FMI calls); ``at_step_end``: an error is reported
    at t + h (else at t, as Gauss–Seidel routes and sets before a doStep); ``post_step``: after its C form returned, the
    instance's post-step (`cosim.run.instances.Instance.step_outcome`) that turns the raw status
    into the one ``call`` returns; ``next``: the operation after it (after its block, for OP_SOLVE).
    """
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
class Program:
    """A compiled communication step: ``operations`` (``[0, step_ops)`` the step, the rest the
    exchange at its end); with threads, the first ``parallel`` are doSteps made concurrently
    (``parallel_components``; ``serial``: the components kept on the calling thread, and why)."""
    operations: tuple[Operation, ...]
    step_ops: int
    parallel: int = 0
    parallel_components: tuple[str, ...] = ()
    serial: Mapping[str, str] = field(default_factory=dict)

    def top_level(self, first: int = 0, last: int | None = None) -> list[int]:
        """The operations an interpreter runs from ``first`` to ``last`` (exclusive): those
        inside an OP_SOLVE's block run only within its iteration."""
        last = len(self.operations) if last is None else last
        indices, i = [], first
        while i < last:
            indices.append(i)
            i = self.operations[i].next
        return indices

    def python_operations(self) -> dict[str, int]:
        """Why operations run in Python (with the compiled loop: how often it hands back), and
        how many of them for each reason."""
        counts: dict[str, int] = {}
        for i in self.top_level():
            op = self.operations[i]
            if op.native is None:
                counts[op.why_python] = counts.get(op.why_python, 0) + 1
        return counts


def compile_step(plan: Plan, buffers: Sequence[TypedBuffers], instances: Mapping[str, Instance],
                 algorithm: str = "jacobi", loop_solver: LoopSolver | None = None,
                 feed: InputFeed | None = None, threads: int = 1) -> Program:
    """The step of ``plan`` on live ``instances`` exchanging through ``buffers`` (see the module
    docstring); ``threads`` > 1 (Jacobi only) spreads the doSteps that may run concurrently
    round robin over that many threads, and refuses a doStep only Python can make."""
    ops = _Compiler(buffers, instances)
    order = list(plan.components)
    if algorithm == "gauss-seidel":
        for comp in plan.gauss_seidel_order:
            ops.route_into(comp, at_step_end=False)
            ops.step(comp)
            ops.calls(OP_GET, comp)
    else:
        for comp in order:
            ops.step(comp)
    step_ops = len(ops.ops)
    parallel, serial, parallel_components = 0, {}, ()
    if threads > 1:
        serial = ops.serial
        ops.ops, parallel_components = _threaded(ops.ops, order, threads, serial)
        parallel = step_ops
    for comp in order:
        if comp not in plan.read_in_settling_only:
            ops.calls(OP_GET, comp)
    solve = len(ops.ops)
    if loop_solver is not None:
        ops.ops.append(None)  # the OP_SOLVE, made when its block is known
    for comp in plan.feedthrough_sequence:
        ops.route_into(comp)
        ops.calls(OP_GET, comp)
    if loop_solver is not None:
        ops.ops[solve] = _solve(loop_solver, ops.ops[solve + 1:], len(ops.ops))
    ops.routes(None)
    if feed is not None:
        ops.append(OP_FEED, _feed(feed), None, "an input table (--input-file) sets inputs (cosim.plan.inputs)")
    for comp in order:
        if comp not in plan.set_in_settling_only:
            ops.calls(OP_SET, comp)
    return Program(tuple(ops.ops), step_ops, parallel, parallel_components, serial)


class _Compiler:
    """Appends the operations of one component or route group to ``ops`` (`compile_step`)."""

    def __init__(self, buffers: Sequence[TypedBuffers], instances: Mapping[str, Instance]):
        self.buffers, self.instances = buffers, instances
        self.ops: list[Operation | None] = []
        #: the components whose doStep must not run concurrently with others', and why
        self.serial: dict[str, str] = {}

    def append(self, kind: int, call: Call, c_form: native.NativeOp | None, why: str = "", **kw) -> None:
        self.ops.append(Operation(kind, call, c_form, "" if c_form is not None else why,
                                  next=len(self.ops) + 1, **kw))

    def step(self, comp: str) -> None:
        inst = self.instances[comp]
        found = inst.native_step() if isinstance(inst, NativeInstance) else _no_functions(inst)
        c_form, post_step, why = None, None, found
        if not isinstance(found, str):
            c_form = native.NativeOp(native.OP_STEP, found.api, found.do_step, found.component,
                                     post_step=found.post_step)
            post_step = inst.step_outcome if any(found.post_step) else None
            if found.serial:
                self.serial[comp] = found.serial
        self.append(OP_STEP, _do_step(inst.do_step, inst.component), c_form, why, component=comp, instance=inst,
                    post_step=post_step)

    def calls(self, kind: int, comp: str, at_step_end: bool = True) -> None:
        """The batched gets (or sets) of ``comp``, one per exchange type."""
        get = kind == OP_GET
        inst = self.instances[comp]
        for ty in self.buffers:
            start, n, vr = (ty.out_slices if get else ty.in_slices)[comp]
            if not n:
                continue
            buf = ty.Ybuf if get else ty.Ubuf
            fn = ty.get_call(inst.get[ty.type_name], buf, start, n) if get else inst.set[ty.type_name]
            found = inst.native_exchange(ty.type_name) if isinstance(inst, NativeInstance) else _no_functions(inst)
            c_form, why = None, found
            if not isinstance(found, str):
                c_form = native.NativeOp(kind, _api(inst), found[0 if get else 1], inst.component,
                                         ctypes.addressof(vr), n, ty.address(buf, start))
            self.append(kind, _exchange(fn, inst.component, vr, n, ty.pointer(buf, start)), c_form, why,
                        component=comp, instance=inst, type_name=ty.type_name, at_step_end=at_step_end)

    def routes(self, comp: str | None, at_step_end: bool = True) -> None:
        """The routes into ``comp`` (None: all) of each exchange type: the affine ones, then the
        others (their transformations' C forms, `cosim.model.transforms.Transform.native`)."""
        for ty in self.buffers:
            routing = ty.routes_into[comp]
            if len(routing[0]):
                c_form = None if ty.strings else native.NativeOp(
                    native.OP_ROUTE, route=routing, integer=ty.integer, Y=ty.address(ty.Ybuf, 0),
                    U=ty.address(ty.Ubuf, 0))
                self.append(OP_ROUTE, _route(ty.route, comp, at_step_end), c_form,
                            f"{ty.type_name} connections (routed by Python)", component=comp,
                            type_name=ty.type_name, at_step_end=at_step_end)
            mapped = ty.maps_into[comp]
            if mapped:
                forms = [r.transform.native() for _, _, r in mapped]
                c_form = None if ty.strings or not ty.integer or any(f is None or f[0] != "table" for f in forms) \
                    else native.NativeOp(native.OP_MAP, route=(np.array([i for i, _, _ in mapped], dtype=np.intp),
                                                               np.array([j for _, j, _ in mapped], dtype=np.intp)),
                                         tables=tuple(f[1:] for f in forms), integer=True,
                                         Y=ty.address(ty.Ybuf, 0), U=ty.address(ty.Ubuf, 0))
                r = next((r for (_, _, r), f in zip(mapped, forms) if f is None or f[0] != "table"), mapped[0][2])
                why = (f"connection {r.label} maps its values through {r.transform.text(r.source)}, which has no C form "
                       "(cosim.model.transforms)")
                self.append(OP_MAP, _route(ty.map_values, comp, at_step_end), c_form, why, component=comp,
                            type_name=ty.type_name, at_step_end=at_step_end)

    def route_into(self, comp: str, at_step_end: bool = True) -> None:
        """``comp``'s inputs routed and set (the settling, and Gauss–Seidel before a doStep)."""
        self.routes(comp, at_step_end)
        self.calls(OP_SET, comp, at_step_end)


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


def _do_step(do_step, component) -> Call:
    def call(t: float, h: float, t_next: float) -> int:
        return do_step(component, t, h, 1)
    return call


def _exchange(fn, component, vr, n: int, values) -> Call:
    def call(t: float, h: float, t_next: float) -> int:
        return fn(component, vr, n, values)
    return call


def _route(route, comp: str | None, at_step_end: bool) -> Call:
    if at_step_end:
        def call(t: float, h: float, t_next: float) -> int:
            route(t_next, comp)
            return 0
    else:
        def call(t: float, h: float, t_next: float) -> int:
            route(t, comp)
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
