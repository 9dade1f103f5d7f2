"""One communication step as a program of operations, compiled from the plan alone: the only
description of what the master does from t to t + h (`compile`: a `cosim.model.structure.Plan`
-> `StepProgram`; `cosim.run.link` gives it live instances and buffers).

The program is a list of `Op`: doSteps (OP_STEP), batched gets and sets of one component and
exchange type (OP_GET, OP_SET), routes of one exchange type into one component or all (OP_ROUTE:
the routes whose transformation is affine, y·factor + offset; OP_MAP: the others, mapping tables,
`cosim.model.transforms`), the input table (OP_FEED, `cosim.run.feed`) and the iteration of an
algebraic loop (OP_SOLVE, `cosim.run.loops.LoopSolver`) over the settling sweep that follows it in
the list (its block, up to ``Op.next``).  Operations ``[0, step_ops)`` make the step, the rest is
the exchange at its end, which initialisation also runs at t0:

* Jacobi (default): every doStep; Gauss–Seidel: per component in dependency order, its inputs
  routed and set, its doStep, its outputs read;
* the exchange: every output read; the direct-feedthrough settling in dependency order (each
  component's inputs routed and set, its outputs read again), or that sweep iterated by the loop
  solver; every route; the input table's values; every input set.  Components whose outputs
  only the settling reads, or whose inputs only it sets, are left out of the batched reads and
  sets (`cosim.model.structure.Plan.read_in_settling_only`).

A program is a value: it depends on the plan and the algorithm only, prints (`listing`, shown by
``cosim info --program``) and compares without any FMU loaded.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..kernel import OP_GET, OP_MAP, OP_ROUTE, OP_SET, OP_STEP
from ..model.fmu import EXCHANGE_TYPES, exchange_type
from ..model.structure import Plan
from ..model.transforms import Affine

#: operations only Python makes
OP_FEED, OP_SOLVE = 6, 7
#: how the listing names each kind
NAMES = {OP_STEP: "doStep", OP_GET: "get", OP_SET: "set", OP_ROUTE: "route", OP_MAP: "map", OP_FEED: "feed",
         OP_SOLVE: "solve"}


@dataclass(frozen=True)
class Op:
    """One operation of a step (see the module docstring): ``component``, whose FMI call it is or
    the component a route feeds (None: all); ``type_name``, the exchange type of a get, set or
    route; ``at_step_end``: a failure is reported at t + h (else at t, as Gauss–Seidel routes and
    sets before a doStep); ``routes``: a route's routes, as indices of ``Plan.routes``;
    ``next``: the operation after it (after its block, for OP_SOLVE)."""
    kind: int
    component: str | None = None
    type_name: str = ""
    at_step_end: bool = True
    routes: tuple[int, ...] = ()
    next: int = -1


@dataclass(frozen=True)
class StepProgram:
    """The compiled step of ``plan`` with ``algorithm``: ``ops`` (``[0, step_ops)`` the step, the
    rest the exchange at its end)."""
    plan: Plan
    algorithm: str
    ops: tuple[Op, ...]
    step_ops: int

    def top_level(self, first: int = 0, last: int | None = None) -> list[int]:
        """The operations an interpreter runs from ``first`` to ``last`` (exclusive): those
        inside an OP_SOLVE's block run only within its iteration."""
        last = len(self.ops) if last is None else last
        indices, i = [], first
        while i < last:
            indices.append(i)
            i = self.ops[i].next
        return indices

    def listing(self) -> list[str]:
        """The program as text, an operation a line (a route's routes and their transformations
        on the lines after it)."""
        lines = [f"step program ({self.algorithm}): {len(self.ops)} operations, the step {0}..{self.step_ops - 1}, "
                 f"the exchange {self.step_ops}..{len(self.ops) - 1}"]
        for i, op in enumerate(self.ops):
            block = f" (its block: {i + 1}..{op.next - 1})" if op.kind == OP_SOLVE else ""
            where = op.component if op.component is not None else ("all" if op.kind in (OP_ROUTE, OP_MAP) else "")
            lines.append(f"{i:4} {NAMES[op.kind]:7} {where or '':14} {op.type_name}{block}".rstrip())
            for r in (self.plan.routes[j] for j in op.routes):
                lines.append(f"{'':13}{r.label}" + ("" if r.transform.identity else f" = {r.transform.text(r.source)}"))
        return lines


def compile(plan: Plan, algorithm: str = "jacobi") -> StepProgram:
    """The step of ``plan`` with ``algorithm`` ("jacobi" or "gauss-seidel") as a `StepProgram`."""
    c = _Compiler(plan)
    if algorithm == "gauss-seidel":
        for comp in plan.gauss_seidel_order:
            c.route_into(comp, at_step_end=False)
            c.append(OP_STEP, comp)
            c.calls(OP_GET, comp)
    else:
        for comp in plan.components:
            c.append(OP_STEP, comp)
    step_ops = len(c.ops)
    for comp in plan.components:
        if comp not in plan.read_in_settling_only:
            c.calls(OP_GET, comp)
    iterate = bool(plan.algebraic_loops) and plan.loop_mode == "iterate"
    solve = len(c.ops)
    if iterate:
        c.append(OP_SOLVE)   # its block, up to next, is known after the settling
    for comp in plan.feedthrough_sequence:
        c.route_into(comp)
        c.calls(OP_GET, comp)
    if iterate:
        c.ops[solve] = Op(OP_SOLVE, next=len(c.ops))
    c.routes(None)
    if plan.input_table is not None:
        c.append(OP_FEED)
    for comp in plan.components:
        if comp not in plan.set_in_settling_only:
            c.calls(OP_SET, comp)
    return StepProgram(plan, algorithm, tuple(c.ops), step_ops)


class _Compiler:
    """Appends the operations of one component or route group (`compile`).  What it looks up per
    component (its exchange types, the routes into it by type) is grouped once, so compiling a
    plan is linear in its components and routes."""

    def __init__(self, plan: Plan):
        self.plan = plan
        self.ops: list[Op] = []
        #: each component's exchange types of its outputs and of its inputs
        self._out_types = {c: {exchange_type(v) for v in plan.outputs[c]} for c in plan.components}
        self._in_types = {c: {exchange_type(v) for v in plan.inputs[c]} for c in plan.components}
        #: the exchange types the plan's components connect or record, in `EXCHANGE_TYPES` order
        present = set().union(*self._out_types.values(), *self._in_types.values())
        self.types = [t for t in EXCHANGE_TYPES if t in present]
        #: the routes (indices of plan.routes) by (destination, exchange type), and by type
        self._into: dict[tuple[str | None, str], list[int]] = {}
        for i, r in enumerate(plan.routes):
            ty = exchange_type(r.src_var)
            self._into.setdefault((r.dst, ty), []).append(i)
            self._into.setdefault((None, ty), []).append(i)

    def append(self, kind: int, component: str | None = None, **kw) -> None:
        self.ops.append(Op(kind, component, next=len(self.ops) + 1, **kw))

    def calls(self, kind: int, comp: str, at_step_end: bool = True) -> None:
        """The batched gets (or sets) of ``comp``, one per exchange type it has connectors of."""
        present = self._out_types[comp] if kind == OP_GET else self._in_types[comp]
        for ty in self.types:
            if ty in present:
                self.append(kind, comp, type_name=ty, at_step_end=at_step_end)

    def routes(self, comp: str | None, at_step_end: bool = True) -> None:
        """The routes into ``comp`` (None: all) of each exchange type: the affine ones, then the others."""
        for ty in self.types:
            into = self._into.get((comp, ty), ())
            affine = tuple(i for i in into if isinstance(self.plan.routes[i].transform, Affine))
            others = tuple(i for i in into if not isinstance(self.plan.routes[i].transform, Affine))
            for kind, routes in ((OP_ROUTE, affine), (OP_MAP, others)):
                if routes:
                    self.append(kind, comp, type_name=ty, at_step_end=at_step_end, routes=routes)

    def route_into(self, comp: str, at_step_end: bool = True) -> None:
        """``comp``'s inputs routed and set (the settling, and Gauss–Seidel before a doStep)."""
        self.routes(comp, at_step_end)
        self.calls(OP_SET, comp, at_step_end)
