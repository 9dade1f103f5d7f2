"""The wire between an `cosim.run.instances.isolated.IsolatedInstance` and its component's process
(`cosim.run.instances.host`): fixed-size request and response headers on a Unix socket pair, the
numbers themselves in a shared memory region both processes map.

A request is `REQUEST` (operation, exchange slot, count, t, h, flag, payload length) and an
optional pickled payload; the answer is `RESPONSE` (status, flags, payload length) and an
optional pickled payload ``(log messages, data)``.  The hot calls (do_step, get and set of
numbers) carry no payload: their values are in the slot's region of the shared memory, so a
call is one round trip of two small headers, and the reads the master makes right after a
step (its outputs) are done by the component's process before it answers the step.  Strings and Binary values (pointers, not
numbers) travel pickled in the payload, as do the set-up calls (`OP_CALL`).
"""
from __future__ import annotations

import ctypes
import pickle
import socket
import struct

from ...errors import CosimError, RunError

#: operation, slot, count, t, h, flag, payload length
REQUEST = struct.Struct("<BxHIddiI")
#: status, flags (`HAS_PAYLOAD`), payload length
RESPONSE = struct.Struct("<iII")

OP_STEP, OP_GET, OP_SET, OP_CALL, OP_SLOT, OP_FREE = range(1, 7)
HAS_PAYLOAD = 1
#: the status of an answer whose payload is an exception raised in the component's process
RAISED = -1

#: exchange types in slot declarations, and the C type of their values (as `cosim.run.exchange.TYPES`)
KINDS = ("Real", "Integer", "Boolean", "String", "Binary")
NUMBERS = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int}
#: bytes a slot reserves per value in the shared memory (the widest number, a double)
VALUE_BYTES = 8
#: The shared memory begins with the status of each number slot read right after a step
#: (int32 per slot, the first `READ_AHEAD_SLOTS` slots): the component's process does those
#: reads before it answers the step, so they cost no round trip of their own.
READ_AHEAD_SLOTS = 64
STATUS_BYTES = 4 * READ_AHEAD_SLOTS
#: a read-ahead status: not read (an earlier read of that step failed)
NOT_READ = -99


class RemoteError(Exception):
    """An exception a set-up call raised in the component's process, carried back with its
    message and FMI status (what `cosim.run.execution.Execution._guard` reads)."""

    def __init__(self, message: str, status: int | None = None):
        super().__init__(message)
        self.status = status


def exception_payload(e: BaseException) -> BaseException:
    """What crosses the wire for an exception: a setup error as it is (it pickles with its
    file, element and variable), anything else as a `RemoteError` with its text and status."""
    if isinstance(e, CosimError) and not isinstance(e, RunError):
        return e
    return RemoteError(str(e), getattr(e, "status", None))


def receive_exactly(sock: socket.socket, view: memoryview) -> bool:
    """Fill ``view`` from ``sock``; False when the peer has gone (end of file or reset)."""
    got = 0
    while got < len(view):
        try:
            n = sock.recv_into(view[got:])
        except ConnectionResetError:
            return False
        if n == 0:
            return False
        got += n
    return True


def dumps(value) -> bytes:
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


loads = pickle.loads
