"""The component's own process under ``--isolate``: one live instance served over the channel
(`cosim.run.instances.channel`) until the master frees it or goes away.

`serve` runs in the child forked by `cosim.run.instances.isolated.IsolatedInstance`: it opens the
real instance with `cosim.run.instances.open_instance` (FMI 2.0/3.0 Co-Simulation, Model Exchange),
answers each request, and passes on the log messages the FMU sent during the call.  The child
ignores SIGINT and SIGTERM (a Ctrl-C, or a SIGTERM to the process group, reaches every process
of the group; the master stops the run at its next communication point and frees the
components), leaves reporting a crash to the master (no
faulthandler dump), asks the kernel to kill it when the master
dies (``PR_SET_PDEATHSIG``), and never returns: it ends with ``os._exit``, running none of the
master's exit handlers (its FMU extraction folder belongs to the master).
"""
from __future__ import annotations

import ctypes
import faulthandler
import mmap
import os
import signal
import socket
from typing import NoReturn

from ...model.fmu import FMUDescription
from ...model.structure import SolverSettings
from . import open_instance
from .channel import (HAS_PAYLOAD, NOT_READ, NUMBERS, OP_CALL, OP_FREE, OP_GET, OP_SET, OP_SLOT, OP_STEP, RAISED,
                      READ_AHEAD_SLOTS, REQUEST, RESPONSE, dumps, exception_payload, loads, receive_exactly)
from .fmi3 import BinaryValue

#: prctl option: the signal this process gets when its parent thread ends (linux/prctl.h)
PR_SET_PDEATHSIG = 1
#: the set-up calls a request may name (`cosim.run.instances.Instance`)
CALLS = frozenset({"instantiate", "setup_experiment", "set_start", "step_end", "enter_initialization_mode",
                   "exit_initialization_mode"})


def serve(sock: socket.socket, shared: mmap.mmap, name: str, desc: FMUDescription, unzip_dir: str,
          solver: SolverSettings | None, master: int, inherited: list[socket.socket]) -> NoReturn:
    """The child's whole life: detach from the master's signals and sockets, open the instance,
    answer requests; exit 0 when freed or when the master has gone."""
    code = 0
    try:
        for s in (signal.SIGINT, signal.SIGTERM):  # sent to the group: the master stops the run and frees us
            signal.signal(s, signal.SIG_IGN)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)  # the master's stop handler (cosim.run.interrupts) is not ours
        faulthandler.disable()  # a crash is reported by the master (pytest turns the dump on)
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != master:  # the master died before the line above
            os._exit(1)
        for other in inherited:  # the master's ends of the other components' sockets
            other.close()
        _Host(sock, shared, name, desc, unzip_dir, solver).loop()
    except BaseException:
        code = 1
    finally:
        os._exit(code)


class _Slot:
    """One call site's arrays in this process: its value references, and its values in the
    slot's region of the shared memory (numbers) or in arrays of its own (String, Binary)."""

    def __init__(self, shared: mmap.mmap, kind: str, offset: int, vrs: list[int]):
        self.n = len(vrs)
        n = max(1, self.n)
        self.kind = kind
        self.vrs = (ctypes.c_uint * n)(*vrs)
        if kind in NUMBERS:
            self.values = (NUMBERS[kind] * n).from_buffer(shared, offset)
        elif kind == "String":
            self.values = (ctypes.c_char_p * n)()
        else:
            self.values = (BinaryValue * n)()
        self.keep: list = []  # Binary: the memory the values point to, until the next set

    def export(self, n: int) -> list[bytes | None] | None:
        """After a get: String and Binary values as bytes (numbers are already shared)."""
        if self.kind == "String":
            return [self.values[i] for i in range(n)]
        if self.kind == "Binary":
            return [ctypes.string_at(v.data, v.size) if v.size else b"" for v in self.values[:n]]
        return None

    def load(self, values: list[bytes | None]) -> None:
        """Before a set: String and Binary values from the master."""
        if self.kind == "String":
            for i, value in enumerate(values):
                self.values[i] = value
        elif self.kind == "Binary":
            self.keep = [ctypes.create_string_buffer(v, max(1, len(v))) for v in values]
            for i, (value, buffer) in enumerate(zip(values, self.keep)):
                self.values[i].data = ctypes.cast(buffer, type(self.values[i].data))
                self.values[i].size = len(value)


class _Host:
    """The request loop over one instance."""

    def __init__(self, sock: socket.socket, shared: mmap.mmap, name: str, desc: FMUDescription, unzip_dir: str,
                 solver: SolverSettings | None):
        self.sock, self.shared = sock, shared
        self.slots: list[_Slot] = []
        #: the number slots the master reads right after a step, read here before the step is answered
        self.read_ahead: list[int] = []
        self.statuses = (ctypes.c_int32 * READ_AHEAD_SLOTS).from_buffer(shared)
        self.head = bytearray(REQUEST.size)
        self.view = memoryview(self.head)
        try:
            self.inst = open_instance(name, desc, unzip_dir, solver)
        except Exception as e:  # the master raises it from the IsolatedInstance's constructor
            self.inst = None
            self.answer(RAISED, exception_payload(e))
            raise
        self.answer(0, None)

    def loop(self) -> None:
        while receive_exactly(self.sock, self.view):  # until the master has gone
            op, slot, n, t, h, flag, length = REQUEST.unpack(self.head)
            payload = None
            if length:
                buffer = bytearray(length)
                if not receive_exactly(self.sock, memoryview(buffer)):
                    return
                payload = loads(buffer)
            try:
                status, data = self.dispatch(op, slot, n, t, h, flag, payload)
            except Exception as e:
                status, data = RAISED, exception_payload(e)
            self.answer(status, data)
            if op == OP_FREE:
                return

    def dispatch(self, op: int, slot: int, n: int, t: float, h: float, flag: int, payload) -> tuple[int, object]:
        inst = self.inst
        if op == OP_STEP:
            if payload is not None:
                self.read_ahead = payload
            status = inst.do_step(inst.component, t, h, flag)
            if status <= 1:
                self.read_after_step()
            return status, None
        if op == OP_GET:
            s = self.slots[slot]
            status = inst.get[s.kind](inst.component, s.vrs, n, s.values)
            return status, (s.export(n) if status <= 1 else None)
        if op == OP_SET:
            s = self.slots[slot]
            if payload is not None:
                s.load(payload)
            return inst.set[s.kind](inst.component, s.vrs, n, s.values), None
        if op == OP_SLOT:
            kind, offset, vrs = payload
            self.slots.append(_Slot(self.shared, kind, offset, vrs))
            return 0, None
        if op == OP_CALL:
            method, args = payload
            if method not in CALLS:
                raise ValueError(f"no such instance call: {method}")
            return 0, getattr(inst, method)(*args)
        if op == OP_FREE:
            inst.failed = payload
            inst.free()
            return 0, None
        raise ValueError(f"unknown request {op}")

    def read_after_step(self) -> None:
        """The master's reads that follow a step (`cosim.run.instances.isolated`), in its order; their
        statuses in the shared memory, none after one above Warning."""
        inst, statuses = self.inst, self.statuses
        for i in self.read_ahead:
            statuses[i] = NOT_READ
        for i in self.read_ahead:
            s = self.slots[i]
            statuses[i] = status = inst.get[s.kind](inst.component, s.vrs, s.n, s.values)
            if status > 1:
                return

    def answer(self, status: int, data) -> None:
        """The status, and the FMU's log messages since the last answer with the call's data."""
        messages = list(self.inst.messages) if self.inst is not None and self.inst.messages else []
        if messages:
            self.inst.messages.clear()
        if messages or data is not None:
            payload = dumps((messages, data))
            self.sock.sendall(RESPONSE.pack(status, HAS_PAYLOAD, len(payload)) + payload)
        else:
            self.sock.sendall(RESPONSE.pack(status, 0, 0))
