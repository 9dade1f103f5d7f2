"""FMI 3.0 Co-Simulation FMUs behind the master's FMI 2.0-shaped instance interface.

`FMI3Instance` wraps fmpy's `FMU3Slave` and offers what `cosim.run.instances.Instance`
offers (see its docstring): ``do_step``/``get``/``set`` callables with the FMI
2.0 C signatures, called by the execution on its ctypes exchange buffers.  Most
are thin closures over the raw fmi3 functions; the differences they absorb:

* ``fmi3Get*``/``fmi3Set*`` take ``nValues`` besides ``nValueReferences``
  (FMI 3.0 §2.2.6.2): for scalars both are the same count.
* ``fmi3Boolean`` is a C ``bool`` (1 byte, FMI 3.0 §2.2.3) while the exchange
  buffer holds ``int`` as fmi2Boolean does: copied through a preallocated
  ``c_bool`` scratch array.
* Array variables (``<Dimension>``, FMI 3.0 §2.4.7.5, serialised row-major):
  a connector names one element (`cosim.model.fmu.ArrayElement`, a value reference of
  its own that only this module resolves).  Reading fetches the whole array into
  a scratch buffer and copies the element out; writing keeps a scratch copy of
  the whole input array (read once, then only the master writes it) and writes
  it back whole.
* ``fmi3DoStep`` reports ``terminateSimulation`` through an out-argument
  (FMI 3.0 §4.2.4): ``do_step`` then returns Discard, as fmi2DoStep does, and
  ``step_end`` says the step completed (OK or Warning: its outputs are valid).  Instances are created with ``eventModeUsed = earlyReturnAllowed =
  false``, so ``eventHandlingNeeded`` and ``earlyReturn`` carry nothing here.
* there is no ``fmi2SetupExperiment``: start and stop time go to
  ``fmi3EnterInitializationMode`` (FMI 3.0 §2.3.2).
* the log callback has no instance name (FMI 3.0 §2.3.1): one callback per
  instance, writing into that instance's ``messages``.
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable

import numpy as np
from fmpy.fmi3 import FMU3Slave, fmi3Binary

from ...model.fmu import ArrayElement, ExchangeType, FMUDescription, Variable, exchange_type
from ...errors import SetupError
from .base import STATUS, InstanceBase, NativeStep, address, end_instance, log_line, serial_reason
from .loading import quick

FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR = 0, 1, 2, 3

#: exchange type -> (fmi3 function suffix, C type the FMU reads and writes) of its native FMI 3.0 type
FMI3_FUNCTIONS: dict[str, tuple[str, type]] = {
    "Real": ("Float64", ctypes.c_double),
    "Integer": ("Int32", ctypes.c_int32),
    "Boolean": ("Boolean", ctypes.c_bool),
    "String": ("String", ctypes.c_char_p),
}

#: FMI 3.0 variable type -> (fmi3 function suffix, C type): the types exchanged through another
#: type's buffer (Float32 as Real, the integer types and Enumeration, an Int64, as Integer)
FMI3_TYPES: dict[str, tuple[str, type]] = {
    "Float64": ("Float64", ctypes.c_double), "Float32": ("Float32", ctypes.c_float),
    "Int8": ("Int8", ctypes.c_int8), "UInt8": ("UInt8", ctypes.c_uint8),
    "Int16": ("Int16", ctypes.c_int16), "UInt16": ("UInt16", ctypes.c_uint16),
    "Int32": ("Int32", ctypes.c_int32), "UInt32": ("UInt32", ctypes.c_uint32),
    "Int64": ("Int64", ctypes.c_int64), "UInt64": ("UInt64", ctypes.c_uint64),
    "Enumeration": ("Int64", ctypes.c_int64), "Boolean": ("Boolean", ctypes.c_bool),
    "String": ("String", ctypes.c_char_p),
}


class BinaryValue(ctypes.Structure):
    """One Binary value in the exchange buffer: fmi3GetBinary's pointer and size together."""
    _fields_ = [("data", fmi3Binary), ("size", ctypes.c_size_t)]


def _integer_range(ctype: type) -> tuple[int, int]:
    bits = 8 * ctypes.sizeof(ctype)
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if ctype(-1).value == -1 else (0, (1 << bits) - 1)


Adapter = Callable[..., int]


class FMI3Instance(InstanceBase):
    """One live FMI 3.0 Co-Simulation instance (`cosim.run.instances.Instance`)."""

    api = "fmi3"

    #: fmpy's class for the FMI 3.0 interface the instance drives, and its instantiation function
    interface = quick(FMU3Slave)
    instantiate_function = "fmi3InstantiateCoSimulation"

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str):
        super().__init__(name, desc)
        self.slave = self.interface(guid=desc.guid, unzipDirectory=unzip_dir,
                                    modelIdentifier=desc.model_identifier, instanceName=name)
        self._start, self._stop = 0.0, None
        self._end: tuple[float | None, str] = (None, "fmi3DoStep returned Discard")
        self._by_reference = {v.vr: v for v in desc.variables.values()}
        #: fmi3DoStep's out-arguments: eventHandlingNeeded, terminateSimulation, earlyReturn, lastSuccessfulTime
        self._step_out = (ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double())
        raw = self.slave._functions
        if isinstance(self.slave, FMU3Slave):  # Co-Simulation; a Model Exchange instance steps by its own method
            self.do_step = self._do_step_adapter(raw["fmi3DoStep"])
        self.get = {t: self._get_adapter(t) for t in FMI3_FUNCTIONS}
        self.set = {t: self._set_adapter(t) for t in FMI3_FUNCTIONS}
        self.get["Binary"], self.set["Binary"] = self._binary_adapters()

    # ----------------------------------------------------------------- hot-loop adapters

    def _do_step_adapter(self, raw) -> Adapter:
        out = tuple(ctypes.byref(v) for v in self._step_out)

        def do_step(component, t: float, h: float, no_prior_state: int) -> int:
            return self.step_outcome(t, h, raw(component, t, h, no_prior_state, *out))
        return do_step

    def step_outcome(self, t: float, h: float, status: int) -> int:
        """The status of fmi3DoStep(t, h) as ``do_step`` returns it, from the out-arguments the
        FMU wrote (``_step_out``): Discard after a completed step (OK or Warning) with
        terminateSimulation, whose end `step_end` then gives, as after a Discard."""
        terminate, last = self._step_out[1], self._step_out[3]
        if terminate.value and status <= FMI_WARNING:  # the step completed: its outputs are valid
            self._end = (t + h, f"fmi3DoStep returned {STATUS[status]} with terminateSimulation = true")
            return FMI_DISCARD
        if status == FMI_DISCARD:
            self._end = (last.value if last.value > t else None,
                         f"fmi3DoStep returned Discard with terminateSimulation = "
                         f"{'true' if terminate.value else 'false'} and lastSuccessfulTime = {last.value:g}")
        return status

    def native_step(self) -> NativeStep | str:
        """fmi3DoStep as a C address, with the addresses of its out-arguments, which the
        post-step `step_outcome` reads (`cosim.kernel`); none for Model Exchange."""
        if not isinstance(self.slave, FMU3Slave):
            return f"component '{self.name}' is Model Exchange (integrated by the master)"
        return NativeStep(3, self.component, address(self.slave._functions["fmi3DoStep"]),
                          tuple(ctypes.addressof(v) for v in self._step_out), serial=serial_reason(self))

    def native_exchange(self, type_name: ExchangeType) -> tuple[int, int] | str:
        """fmi3Get/SetFloat64 or Int32 as C addresses (`cosim.kernel`); none when the type goes
        through `_Gather` (a C bool, array elements, another FMI 3.0 type exchanged as Real or
        Integer) or is a String or Binary."""
        if type_name not in ("Real", "Integer") or self._needs_gather(type_name):
            return f"component '{self.name}' exchanges {type_name} values through the master's FMI 3.0 conversion"
        raw, suffix = self.slave._functions, FMI3_FUNCTIONS[type_name][0]
        return address(raw[f"fmi3Get{suffix}"]), address(raw[f"fmi3Set{suffix}"])

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        """What ``do_step`` kept when it ended the run: t + h after OK or Warning with
        terminateSimulation (the step completed, FMI 3.0 §4.2.4), lastSuccessfulTime after Discard."""
        return self._end

    def _needs_gather(self, type_name: str) -> bool:
        """Whether ``type_name`` values go through `_Gather`: array elements, a Boolean (C bool),
        or a variable of another FMI 3.0 type exchanged as ``type_name`` (Float32, Int8...)."""
        native = FMI3_FUNCTIONS[type_name][0]
        return (FMI3_FUNCTIONS[type_name][1] is ctypes.c_bool
                or any(exchange_type(e.array) == type_name for e in self.desc.elements.values())
                or any(exchange_type(v) == type_name and FMI3_TYPES[v.type][0] != native
                       for v in self.desc.variables.values()))

    def _get_adapter(self, type_name: str) -> Adapter:
        suffix, ctype = FMI3_FUNCTIONS[type_name]
        raw = self.slave._functions[f"fmi3Get{suffix}"]
        if not self._needs_gather(type_name):
            def get(component, vrs, n: int, values) -> int:
                return raw(component, vrs, n, values, n)
            return get
        plans: dict[int, _Gather] = {}

        def get(component, vrs, n: int, values) -> int:
            plan = plans.get(id(vrs))
            if plan is None or not plan.serves(vrs, values):
                plan = plans[id(vrs)] = self._gather(vrs, n, values, type_name)
            for group in plan.groups:
                status = group.get(component, group.vrs, group.nvr, group.scratch, group.nvalues)
                if status > FMI_WARNING:
                    return status
                refused = group.copy_out(plan.out)
                if refused:
                    self.messages.append(f"[refused by the master, not the FMU] {refused}")
                    return FMI_ERROR
            return FMI_OK
        return get

    def _set_adapter(self, type_name: str) -> Adapter:
        suffix, ctype = FMI3_FUNCTIONS[type_name]
        raw = self.slave._functions[f"fmi3Set{suffix}"]
        if not self._needs_gather(type_name):
            def set_(component, vrs, n: int, values) -> int:
                return raw(component, vrs, n, values, n)
            return set_
        plans: dict[int, _Gather] = {}

        def set_(component, vrs, n: int, values) -> int:
            plan = plans.get(id(vrs))
            if plan is None or not plan.serves(vrs, values):
                plan = self._gather(vrs, n, values, type_name)
                # the whole input arrays as the FMU holds them; from then on only the master writes them
                for group in plan.groups:
                    status = group.get(component, group.vrs, group.nvr, group.scratch, group.nvalues)
                    if status > FMI_WARNING:
                        return status
                plans[id(vrs)] = plan
            for group in plan.groups:
                refused = group.copy_in(plan.out)
                if refused:
                    self.messages.append(f"[refused by the master, not the FMU] {refused}")
                    return FMI_ERROR
                status = group.set(component, group.vrs, group.nvr, group.scratch, group.nvalues)
                if status > FMI_WARNING:
                    return status
            return FMI_OK
        return set_

    def _binary_adapters(self) -> tuple[Adapter, Adapter]:
        """fmi3GetBinary/fmi3SetBinary take the sizes and the pointers as two arrays; the exchange
        buffer holds `BinaryValue` pairs: scalar Binary variables only (no arrays)."""
        raw_get, raw_set = self.slave._functions["fmi3GetBinary"], self.slave._functions["fmi3SetBinary"]
        scratch: dict[int, tuple] = {}

        def arrays(n: int) -> tuple:
            if n not in scratch:
                scratch[n] = ((ctypes.c_size_t * n)(), (fmi3Binary * n)())
            return scratch[n]

        def get(component, vrs, n: int, values) -> int:
            sizes, pointers = arrays(n)
            status = raw_get(component, vrs, n, sizes, pointers, n)
            if status <= FMI_WARNING:
                for i in range(n):
                    values[i].data, values[i].size = pointers[i], sizes[i]
            return status

        def set_(component, vrs, n: int, values) -> int:
            sizes, pointers = arrays(n)
            for i in range(n):
                pointers[i], sizes[i] = values[i].data, values[i].size
            return raw_set(component, vrs, n, sizes, pointers, n)
        return get, set_

    def _gather(self, vrs, n: int, values, type_name: str) -> _Gather:
        return _Gather(vrs, n, values, self.desc.elements, self._by_reference, self.slave._functions, type_name)

    # ----------------------------------------------------------------- set-up

    def _log(self, env, status: int, category: bytes | None, message: bytes | None) -> None:
        self.messages.append(log_line(status, category, message))

    def instantiate(self, fmu_log: str = "errors") -> None:
        """fmi3InstantiateCoSimulation (FMI 3.0 §4.2.1); ``fmu_log`` as in `cosim.run.instances.Instance`."""
        logging_on = self.logging_on(fmu_log)
        try:
            self.slave.instantiate(loggingOn=logging_on, logMessage=self._log)
        except Exception as e:
            raise SetupError(f"{self.instantiate_function} failed for {self.desc.path.name} (instantiation "
                             f"token {self.desc.guid}): {e}." + self.last_messages(),
                             element=f"component '{self.name}'") from None
        self.component = self.slave.component
        self.restrict_logging(fmu_log)

    def setup_experiment(self, start: float, stop: float) -> None:
        """Kept for `enter_initialization_mode`: FMI 3.0 has no fmi3SetupExperiment."""
        self._start, self._stop = start, stop

    def set_start(self, variable: Variable, value: float | int | bool | str) -> None:
        """Set a parameter or start value before initialisation (FMI 3.0 §2.2.6.2)."""
        vr = [variable.vr]
        if variable.type == "String":
            self.slave.setString(vr, [str(value)])
        else:  # fmpy's set<Type> for each FMI 3.0 type (an Enumeration is an Int64)
            getattr(self.slave, f"set{FMI3_TYPES[variable.type][0]}")(vr, [value])

    def reuse(self, fmu_log: str) -> None:
        """After fmi3Reset (`cosim.run.instances.base.InstanceBase.reuse`), also the experiment's times
        and doStep's out-arguments as a new instance has them."""
        super().reuse(fmu_log)
        self._start, self._stop = 0.0, None
        self._end = (None, "fmi3DoStep returned Discard")
        for out in self._step_out:
            out.value = type(out)().value

    def enter_initialization_mode(self) -> None:
        self.slave.enterInitializationMode(startTime=self._start, stopTime=self._stop)

    def exit_initialization_mode(self) -> None:
        self.slave.exitInitializationMode()

    def free(self) -> None:
        """As `cosim.run.instances.fmi2.FMI2Instance.free` (FMI 3.0 §2.3.1 state machine).  pythonfmu3 0.3.4
        libraries keep the same static interpreter state as pythonfmu 0.7.0 (they export
        ``finalizePythonInterpreter`` too), so it is released the same way before unloading."""
        end_instance(self, lambda: self.slave.fmi3FreeInstance(self.component))


class _Gather:
    """How the value references one get/set call names map onto fmi3 calls, one group per FMI
    3.0 type (`_Group`): the distinct variables (an array once, however many of its elements
    are named), a scratch buffer for their values in the FMU's C type, and the position of
    each named value in it.  Numbers and Booleans only: strings are exchanged scalar by scalar
    (String array elements are refused by `cosim.model.fmu.FMUDescription.variable`).

    A plan serves one pair of caller arrays (value references, values), as the execution
    passes the same ones at every call; it keeps them, so their ``id`` keys it safely."""

    def __init__(self, vrs, n: int, values, elements: dict[int, ArrayElement], variables: dict[int, Variable],
                 functions: dict, type_name: str):
        self.caller = (vrs, values)
        self.out = np.ctypeslib.as_array(values, shape=(n,))
        groups: dict[str, _Group] = {}
        for i, vr in enumerate(vrs[:n]):
            element = elements.get(vr)
            var = element.array if element is not None else variables[vr]
            real_vr, size, index = (var.vr, element.size, element.index) if element is not None \
                else (vr, 1, 0)
            suffix, ctype = FMI3_TYPES[var.type]
            group = groups.get(suffix)
            if group is None:
                group = groups[suffix] = _Group(suffix, ctype, functions, type_name, self.out.dtype)
            group.add(i, real_vr, size, index, var.name)
        self.groups = [g.finish() for g in groups.values()]

    def serves(self, vrs, values) -> bool:
        return self.caller[0] is vrs and self.caller[1] is values


class _Group:
    """The variables of one FMI 3.0 type in a `_Gather`, and the conversions between the
    FMU's C type and the exchange buffer's: a value the target cannot represent (an Int64
    beyond the 32-bit Integer exchange, an Integer beyond an Int8 input, a Real beyond
    Float32) is refused, naming the variable; Float64 to Float32 rounds."""

    def __init__(self, suffix: str, ctype: type, functions: dict, type_name: str, exchange_dtype: np.dtype):
        self.suffix, self.ctype, self.type_name = suffix, ctype, type_name
        self.get, self.set = functions[f"fmi3Get{suffix}"], functions[f"fmi3Set{suffix}"]
        self.variables: dict[int, int] = {}  # FMU value reference -> offset in scratch
        self.out_index: list[int] = []
        self.offsets: list[int] = []
        self.names: list[str] = []
        self.total = 0
        integer = type_name == "Integer"
        self.fmu_range = _integer_range(ctype) if integer else None
        self.exchange_range = _integer_range(np.ctypeslib.as_ctypes_type(exchange_dtype)) if integer else None

    def add(self, position: int, vr: int, size: int, index: int, name: str) -> None:
        if vr not in self.variables:
            self.variables[vr] = self.total
            self.total += size
        self.out_index.append(position)
        self.offsets.append(self.variables[vr] + index)
        self.names.append(name)

    def finish(self) -> _Group:
        self.nvr = len(self.variables)
        self.vrs = (ctypes.c_uint * max(1, self.nvr))(*self.variables)
        self.nvalues = self.total
        self.scratch = (self.ctype * max(1, self.total))()
        self.view = np.ctypeslib.as_array(self.scratch)
        self.positions = np.array(self.offsets, dtype=np.intp)
        self.out_positions = np.array(self.out_index, dtype=np.intp)
        return self

    def _outside(self, values: np.ndarray, bounds: tuple[int, int] | None, what: str) -> str | None:
        if bounds is None:
            if self.suffix == "Float32" and what != "read":
                big = np.isfinite(values) & (np.abs(values) > np.finfo(np.float32).max)
                if big.any():
                    i = int(np.argmax(big))
                    return f"the Real value {values[i]} cannot be represented as Float32 {self.names[i]}"
            return None
        lo, hi = bounds
        bad = (values < lo) | (values > hi)
        if not bad.any():
            return None
        i = int(np.argmax(bad))
        if what == "read":
            return (f"{self.suffix} {self.names[i]} = {int(values[i])} cannot be represented in the master's 32-bit "
                    "Integer exchange")
        return f"the Integer value {int(values[i])} cannot be represented as {self.suffix} {self.names[i]}"

    def copy_out(self, out: np.ndarray) -> str | None:
        values = self.view[self.positions]
        refused = self._outside(values, self.exchange_range, "read")
        if refused is None:
            out[self.out_positions] = values
        return refused

    def copy_in(self, out: np.ndarray) -> str | None:
        values = out[self.out_positions]
        refused = self._outside(values, self.fmu_range, "write")
        if refused is None:
            self.view[self.positions] = values
        return refused
