"""The exchange buffers of a run: every component's outputs (Y) and inputs (U) of one exchange
type in ctypes memory, and the routes between them.

Values move through these preallocated arrays with one batched get and one batched set per
FMU and type; a group of routes (an operation of the step's program, `cosim.run.program`) is
precomputed NumPy index arrays (`TypedBuffers.affine`, `TypedBuffers.mapped`).  Both interpreters
of a step (`cosim.run.interpreters`) work on the same memory: the compiled one through the
addresses (`TypedBuffers.address`), the Python one through the arrays and `TypedBuffers.route`.
"""
from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..model.fmu import exchange_type
from ..errors import RunError
from .instances.fmi3 import BinaryValue
from ..model.structure import Plan, Route
from ..model.transforms import Unmapped

#: exchange types (`cosim.model.fmu.exchange_type`, in `cosim.model.fmu.EXCHANGE_TYPES` order) and their
#: buffers' C types, as fmi2 declares them (Binary, FMI 3.0 only: a pointer and a size,
#: `cosim.run.instances.fmi3.BinaryValue`)
TYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int, "String": ctypes.c_char_p,
         "Binary": BinaryValue}
FMI_WARNING = 1


class Routing(NamedTuple):
    """A group of routes whose transformations are affine: source and destination positions,
    factors, offsets, whether all of them are the identity (and the routes, to name an overflow)."""
    src: np.ndarray
    dst: np.ndarray
    factor: np.ndarray
    offset: np.ndarray
    identity: bool
    routes: tuple[Route, ...]

    def native(self) -> tuple:
        """The compiled loop's form (`cosim.kernel.NativeOp.route`)."""
        return self.src, self.dst, self.factor, self.offset, self.identity


#: the other routes (a mapping table, ...): (source position, destination position, route)
Mapped = list[tuple[int, int, Route]]


def exchange_buffers(plan: Plan, order: Sequence[str]) -> list[TypedBuffers]:
    """The buffers of the exchange types the plan's components connect or record, in `TYPES` order."""
    return [TypedBuffers(plan, t, order) for t in TYPES
            if any(exchange_type(v) == t for c in order for v in plan.outputs[c] + plan.inputs[c])]


class TypedBuffers:
    """Outputs (Y) and inputs (U) of one exchange type for all components, in ctypes memory.

    Strings (char*) and Binary values (pointer and size) are not numbers: they are routed by
    a Python loop over the pairs of buffer positions, never transformed, and not recorded (the
    recorder and the CSV hold numeric signals only).  An FMU's string or binary is valid only
    until its next FMI call (FMI 2.0 §2.1.7, FMI 3.0 §2.2.6.2), so every get is followed by a
    copy into memory the buffer owns (`get_call`); a routed Binary keeps that memory alive
    (``owners``) as long as the input holds it.
    """

    def __init__(self, plan: Plan, type_name: str, order: Sequence[str]):
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
        #: each output's and input's position in Y and U
        self.out_index = {(c, v.name): i for i, (c, v) in enumerate(outs)}
        self.in_index = {(c, v.name): i for i, (c, v) in enumerate(ins)}
        self.ctype = ctype
        self.integer = ctype is ctypes.c_int

    @staticmethod
    def _slices(pairs, order):
        """Each component's (first position, count, value references) in ``pairs`` (in ``order``)."""
        by_component: dict[str, list[int]] = {comp: [] for comp in order}
        for c, v in pairs:
            by_component[c].append(v.vr)
        slices = {}
        i = 0
        for comp, vrs in by_component.items():
            slices[comp] = (i, len(vrs), (ctypes.c_uint * max(1, len(vrs)))(*vrs))
            i += len(vrs)
        return slices

    def affine(self, routes: Sequence[Route]) -> Routing:
        """``routes`` (of this type, their transformations `cosim.model.transforms.Affine`) as a group."""
        src = np.array([self.out_index[(r.src, r.src_var.name)] for r in routes], dtype=np.intp)
        dst = np.array([self.in_index[(r.dst, r.dst_var.name)] for r in routes], dtype=np.intp)
        factors, offsets = [r.transform.factor for r in routes], [r.transform.offset for r in routes]
        factor, offset = np.array(factors, dtype=np.float64), np.array(offsets, dtype=np.float64)
        identity = all(f == 1.0 for f in factors) and all(o == 0.0 for o in offsets)
        return Routing(src, dst, factor, offset, identity, tuple(routes))

    def mapped(self, routes: Sequence[Route]) -> Mapped:
        """``routes`` (of this type, with other transformations) with their positions."""
        return [(self.out_index[(r.src, r.src_var.name)], self.in_index[(r.dst, r.dst_var.name)], r) for r in routes]

    def route(self, group: Routing, t: float) -> None:
        """Route the outputs into the inputs through the affine routes ``group`` at time ``t``; a
        factor and offset that make a finite value infinite is a `RunError` (`overflow`).  The
        other routes get their value from `map_values`, after this."""
        src, dst, factor, offset, identity, _ = group
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
                    raise self.overflow(group, int(overflowed[0]), t)
            self.U[dst] = values

    def map_values(self, mapped: Mapped, t: float) -> None:
        """The routes ``mapped``, whose transformation is not affine (a mapping table,
        `cosim.model.transforms.Table`): each input gets its source value through it; a value a
        table names no target for is a `RunError`."""
        for i, j, r in mapped:
            try:
                self.U[j] = r.transform.apply(self.Y[i].item())
            except Unmapped as e:
                table = e.table
                raise RunError(f"{r.src}.{r.src_var.name} = {table.shown(e.value)} at t = {t:g} is not a source value "
                               f"of {table.element} (its sources: {', '.join(table.shown(v) for v in sorted(table.mapping))}); "
                               f"{r.dst}.{r.dst_var.name} was not given it.", time=t, component=r.dst,
                               element=f"connection {r.label}") from None

    def overflow(self, group: Routing, j: int, t: float) -> RunError:
        """The error of route ``j`` of ``group`` at ``t``: its factor and offset (the
        LinearTransformations and unit conversions on the way) took its finite source value past
        the largest float."""
        r = group.routes[j]
        src, _, factor, offset, _, _ = group
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
