"""``--isolate``: each component in a process of its own, so a crashing FMU is that component's
reported failure and the master writes every row, the result file and the JSON itself.

This is libcosim's proxy-FMU idea on a fork: `IsolatedInstance` is the master's side, an
`cosim.run.instances.Instance` whose ``do_step``/``get``/``set`` are Python callables with the
raw functions' signatures; each forwards the call to the component's process
(`cosim.run.instances.host`) over a Unix socket pair, the numbers in a shared memory region both
map (`cosim.run.instances.channel`), so a call is one round trip of two small headers; the reads
the master makes right after a step (learnt at the first step) are done by the component's
process before it answers the step and cost no round trip (the FMU sees the same calls in the
same order).  When the
component's process dies (``abort()``, a segfault, ``_exit()``, SIGKILL) the call raises
`cosim.errors.ComponentLost` (outcome ``crashed``) naming the component, its FMU file, the FMI
call, the signal or exit status and t; with ``call_timeout`` a call that does not return in
time kills the process and raises it with outcome ``timeout``.  Either way the process is
reaped before the error is raised, and `cosim.run.simulation.run` records the outcome as the
run's status.
"""
from __future__ import annotations

import collections
import ctypes
import math
import mmap
import os
import select
import signal
import socket
import time
import warnings
from dataclasses import dataclass

from ...model.fmu import FMUDescription
from ...errors import ComponentLost, SetupError
from ...model.structure import SolverSettings
from .channel import (KINDS, NOT_READ, NUMBERS, OP_CALL, OP_FREE, OP_GET, OP_SET, OP_SLOT, OP_STEP, RAISED,
                      READ_AHEAD_SLOTS, REQUEST, RESPONSE, STATUS_BYTES, VALUE_BYTES, dumps, loads, receive_exactly)
from .fmi3 import FMI3_FUNCTIONS
from .host import serve

#: the master's ends of every live component socket, closed in each new child
_OPEN: set[socket.socket] = set()
#: exchange slots a component's shared memory holds per value it could exchange (outputs read;
#: inputs set and read back at initialisation)
SLOTS_PER_VALUE = 4
#: seconds a freed component's process has to exit before it is killed
EXIT_GRACE = 5.0


@dataclass(frozen=True)
class Isolation:
    """How components are isolated: ``call_timeout`` seconds an FMU call may take (None: no limit)."""
    call_timeout: float | None = None

    def __post_init__(self):
        if self.call_timeout is not None and not (math.isfinite(self.call_timeout) and self.call_timeout > 0):
            raise SetupError(f"--call-timeout {self.call_timeout}: give a positive number of seconds.",
                             element="--call-timeout")

    def open(self, name: str, desc: FMUDescription, unzip_dir: str,
             solver: SolverSettings | None = None) -> IsolatedInstance:
        """`cosim.run.instances.open_instance`, in a process of the component's own."""
        return IsolatedInstance(name, desc, unzip_dir, solver, self.call_timeout)

    def metadata(self) -> dict:
        return {"call_timeout": self.call_timeout}


class IsolatedInstance:
    """The master's side of a component running in its own process (`cosim.run.instances.Instance`)."""

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str, solver: SolverSettings | None,
                 call_timeout: float | None):
        self.name, self.desc = name, desc
        self.api = "fmi3" if desc.kind.startswith("fmi3") else "fmi2"
        self.messages: collections.deque[str] = collections.deque(maxlen=20)
        self.component: object = None
        self.failed: str | None = None
        self.call_timeout = call_timeout
        self._time = 0.0  # the time of the last call, for messages
        capacity = SLOTS_PER_VALUE * (len(desc.variables) + len(desc.elements))
        self._size = -(-(STATUS_BYTES + capacity * VALUE_BYTES) // mmap.PAGESIZE) * mmap.PAGESIZE
        self._shared = mmap.mmap(-1, self._size)  # anonymous and shared: inherited by the fork
        self._anchor = ctypes.c_char.from_buffer(self._shared)
        self._base = ctypes.addressof(self._anchor)
        self._used = STATUS_BYTES
        #: read ahead (`cosim.run.instances.channel.READ_AHEAD_SLOTS`): the number slots read right
        #: after a step, how many of them the component's process knows, those read since the
        #: last step and not yet taken, and whether only reads followed the last step
        self._read_ahead: list[int] = []
        self._told = 0
        self._fresh: set[int] = set()
        self._after_step = False
        self._statuses = (ctypes.c_int32 * READ_AHEAD_SLOTS).from_address(self._base)
        self._slots: dict[tuple[int, int], tuple] = {}
        self._head = bytearray(RESPONSE.size)
        self._view = memoryview(self._head)
        self._data = None
        self._keep: list[bytes] = []  # the String/Binary values of the last read, until the caller copied them
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        master = os.getpid()
        pid = os.fork()
        if pid == 0:
            ours.close()
            serve(theirs, self._shared, name, desc, unzip_dir, solver, master, list(_OPEN))
        theirs.close()
        self._sock, self._pid = ours, pid
        _OPEN.add(ours)
        self._poll = select.poll()
        self._poll.register(ours, select.POLLIN)
        try:
            self._answer(f"opening {desc.path.name}")
        except ComponentLost:  # reaped already
            raise
        except Exception:  # open_instance raised there: the process has ended
            self._reap(kill=False)
            raise
        self.do_step = self._step
        self._step_call = f"{self.api}DoStep" if desc.kind.endswith("-cs") else "the Model Exchange integration step"
        self.get = {kind: self._getter(kind) for kind in KINDS}
        self.set = {kind: self._setter(kind) for kind in KINDS}

    # ----------------------------------------------------------------- the wire

    def _request(self, op: int, what: str, slot: int = 0, n: int = 0, t: float = 0.0, h: float = 0.0,
                 flag: int = 0, payload: bytes = b"") -> int:
        if op != OP_GET:  # a read leaves the FMU as it was; anything else makes the reads ahead stale
            self._fresh.clear()
            self._after_step = False
        if self._pid is None:
            raise ComponentLost(f"{what} called after the component's process ended.", outcome="crashed",
                                time=self._time, component=self.name, element=self._element())
        try:
            self._sock.sendall(REQUEST.pack(op, slot, n, t, h, flag, len(payload)) + payload)
        except (BrokenPipeError, ConnectionResetError):
            self._lost(what)
        return self._answer(what)

    def _answer(self, what: str) -> int:
        if self.call_timeout is not None and not self._poll.poll(self.call_timeout * 1000):
            self._timed_out(what)
        if not receive_exactly(self._sock, self._view):
            self._lost(what)
        status, flags, length = RESPONSE.unpack(self._head)
        self._data = None
        if length:
            payload = bytearray(length)
            if not receive_exactly(self._sock, memoryview(payload)):
                self._lost(what)
            messages, self._data = loads(payload)
            self.messages.extend(messages)
        if status == RAISED:
            error, self._data = self._data, None
            raise error
        return status

    def _element(self) -> str:
        return f"component '{self.name}' ({self.desc.path.name})"

    def _lost(self, what: str):
        status = self._reap(kill=False)
        how = (f"crashed with {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
               else f"exited with status {os.WEXITSTATUS(status)}")
        raise ComponentLost(f"{how} during {what} at t = {self._time:g}.{self.last_messages()}", outcome="crashed",
                            time=self._time, component=self.name, element=self._element())

    def _timed_out(self, what: str):
        self._reap(kill=True)
        raise ComponentLost(f"{what} did not return within {self.call_timeout:g} s at t = {self._time:g}; the "
                            f"component's process was killed.{self.last_messages()}", outcome="timeout",
                            time=self._time, component=self.name, element=self._element())

    def _reap(self, kill: bool) -> int:
        """Close the socket and wait for the process (killed first when ``kill``); its wait status."""
        _OPEN.discard(self._sock)
        self._sock.close()
        pid, self._pid = self._pid, None
        if kill:
            os.kill(pid, signal.SIGKILL)
        else:  # it exits when it reads the end of its socket; one that does not is killed
            deadline = time.monotonic() + EXIT_GRACE
            while time.monotonic() < deadline:
                done, status = os.waitpid(pid, os.WNOHANG)
                if done:
                    self._release()
                    return status
                time.sleep(0.001)
            os.kill(pid, signal.SIGKILL)
        status = os.waitpid(pid, 0)[1]
        self._release()
        return status

    def _release(self) -> None:
        del self._anchor
        self._shared.close()

    def _slot(self, kind: str, vrs, n: int, values) -> tuple:
        """This call site's slot (declared to the component's process on first use): its index
        and the address of its values in the shared memory."""
        key = (id(vrs), id(values))
        slot = self._slots.get(key)
        if slot is None:
            offset = self._used
            if offset + n * VALUE_BYTES > self._size:
                raise SetupError(f"more values are exchanged than its {self._size} bytes of shared memory hold "
                                 f"({len(self._slots)} call sites).", element=self._element())
            self._request(OP_SLOT, f"declaring a {kind} exchange", payload=dumps((kind, offset, list(vrs[:n]))))
            self._used += -(-n * VALUE_BYTES // 16) * 16
            # vrs and values kept: their ids key the slot
            slot = self._slots[key] = (len(self._slots), self._base + offset, vrs, values)
        return slot

    def _call_name(self, kind: str, direction: str) -> str:
        suffix = FMI3_FUNCTIONS[kind][0] if self.api == "fmi3" and kind in FMI3_FUNCTIONS else kind
        return f"{self.api}{direction}{suffix}"

    # ----------------------------------------------------------------- hot-loop callables

    def _step(self, component, t: float, h: float, no_prior_state: int) -> int:
        self._time = t
        told = b""
        if len(self._read_ahead) != self._told:
            told, self._told = dumps(self._read_ahead), len(self._read_ahead)
        status = self._request(OP_STEP, self._step_call, 0, 0, t, h, no_prior_state, told)
        if status <= 1:
            self._fresh.update(self._read_ahead)
            self._after_step = True
        self._time = t + h
        return status

    def _getter(self, kind: str):
        what = self._call_name(kind, "Get")
        if kind in NUMBERS:
            size = ctypes.sizeof(NUMBERS[kind])

            def get(component, vrs, n: int, values) -> int:
                index, address, _, _ = self._slot(kind, vrs, n, values)
                if index in self._fresh:  # read by the component's process right after the step
                    self._fresh.discard(index)
                    status = self._statuses[index]
                    if status != NOT_READ:
                        ctypes.memmove(values, address, n * size)
                        return status
                elif self._after_step and index < READ_AHEAD_SLOTS and index not in self._read_ahead:
                    self._read_ahead.append(index)  # told to the component's process with the next step
                status = self._request(OP_GET, what, index, n)
                ctypes.memmove(values, address, n * size)
                return status
            return get

        def get_pointers(component, vrs, n: int, values) -> int:
            index = self._slot(kind, vrs, n, values)[0]
            status = self._request(OP_GET, what, index, n)
            if self._data is not None:
                self._keep = self._data
                for i, value in enumerate(self._data):
                    if kind == "String":
                        values[i] = value
                    else:  # Binary: memory the caller copies before the next call (cosim.run.exchange.TypedBuffers)
                        values[i].data = ctypes.cast(ctypes.c_char_p(value), type(values[i].data))
                        values[i].size = len(value)
            return status
        return get_pointers

    def _setter(self, kind: str):
        what = self._call_name(kind, "Set")
        if kind in NUMBERS:
            size = ctypes.sizeof(NUMBERS[kind])

            def set_(component, vrs, n: int, values) -> int:
                index, address, _, _ = self._slot(kind, vrs, n, values)
                ctypes.memmove(address, values, n * size)
                return self._request(OP_SET, what, index, n)
            return set_

        def set_pointers(component, vrs, n: int, values) -> int:
            index = self._slot(kind, vrs, n, values)[0]
            if kind == "String":
                sent = [values[i] for i in range(n)]
            else:
                sent = [ctypes.string_at(values[i].data, values[i].size) if values[i].size else b""
                        for i in range(n)]
            return self._request(OP_SET, what, index, n, payload=dumps(sent))
        return set_pointers

    # ----------------------------------------------------------------- set-up calls

    def _remote(self, method: str, what: str, *args):
        self._request(OP_CALL, what, payload=dumps((method, args)))
        return self._data

    def instantiate(self, fmu_log: str = "errors") -> None:
        self._remote("instantiate", f"{self.api}Instantiate", fmu_log)
        self.component = self.name  # the handle the hot-loop callables are given (and ignore)

    def setup_experiment(self, start: float, stop: float) -> None:
        self._time = start
        self._remote("setup_experiment", f"{self.api}SetupExperiment" if self.api == "fmi2"
                     else "the experiment set-up", start, stop)

    def set_start(self, variable, value) -> None:
        self._remote("set_start", f"{self.api}Set (start value of {variable.name})", variable, value)

    def step_outcome(self, t: float, h: float, status: int) -> int:
        """The component's process applied its own post-step (`Instance.step_outcome`) before it
        answered: ``status`` is the outcome."""
        return status

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        return self._remote("step_end", f"{self.api}DoStep's status", t, h)

    def enter_initialization_mode(self) -> None:
        self._remote("enter_initialization_mode", f"{self.api}EnterInitializationMode")

    def exit_initialization_mode(self) -> None:
        self._remote("exit_initialization_mode", f"{self.api}ExitInitializationMode")

    def free(self) -> None:
        """Terminate and free the instance in its process (as the FMI state machine allows after
        ``failed``), then reap the process.  A process that crashes or hangs while freeing is
        a warning: every row of the run is recorded by then."""
        if self._pid is None:
            return
        try:
            self._request(OP_FREE, f"{self.api}Terminate/{self.api}FreeInstance", payload=dumps(self.failed))
        except ComponentLost as e:
            warnings.warn(str(e), RuntimeWarning, stacklevel=2)
        finally:
            if self._pid is not None:
                self._reap(kill=False)
            self.component = None

    def native_step(self) -> str:
        """Why the compiled loop cannot make its calls (`cosim.run.instances.base.NativeInstance`):
        its FMI functions live in another process."""
        return f"component '{self.name}' runs in a process of its own (--isolate)"

    def native_exchange(self, type_name) -> str:
        return self.native_step()

    def last_messages(self) -> str:
        return (" FMU log: " + " | ".join(self.messages)) if self.messages else ""
