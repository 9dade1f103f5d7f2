"""FMI 3.0 Co-Simulation FMUs behind the master's FMI 2.0-shaped instance interface.

`FMI3Instance` wraps fmpy's `FMU3Slave` and offers what `cosim.instances.Instance`
offers (see its docstring): ``do_step``/``get``/``set`` callables with the FMI
2.0 C signatures, called by the execution on its ctypes exchange buffers.  Most
are thin closures over the raw fmi3 functions; the differences they absorb:

* ``fmi3Get*``/``fmi3Set*`` take ``nValues`` besides ``nValueReferences``
  (FMI 3.0 §2.2.6.2): for scalars both are the same count.
* ``fmi3Boolean`` is a C ``bool`` (1 byte, FMI 3.0 §2.2.3) while the exchange
  buffer holds ``int`` as fmi2Boolean does: copied through a preallocated
  ``c_bool`` scratch array.
* Array variables (``<Dimension>``, FMI 3.0 §2.4.7.5, serialised row-major):
  a connector names one element (`cosim.description.ArrayElement`, a value reference of
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
from fmpy.fmi3 import FMU3Slave
from fmpy.model_description import ModelVariable

from ..description import ArrayElement, FMUDescription, exchange_type
from ..errors import SetupError
from .base import STATUS, InstanceBase, end_instance, log_line

FMI_WARNING, FMI_DISCARD = 1, 2

#: exchange type -> (fmi3 function suffix, C type the FMU reads and writes)
FMI3_FUNCTIONS: dict[str, tuple[str, type]] = {
    "Real": ("Float64", ctypes.c_double),
    "Integer": ("Int32", ctypes.c_int32),
    "Boolean": ("Boolean", ctypes.c_bool),
    "String": ("String", ctypes.c_char_p),
}

Adapter = Callable[..., int]


class FMI3Instance(InstanceBase):
    """One live FMI 3.0 Co-Simulation instance (`cosim.instances.Instance`)."""

    api = "fmi3"

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str):
        super().__init__(name, desc)
        self.slave = FMU3Slave(guid=desc.md.guid, unzipDirectory=unzip_dir,
                               modelIdentifier=desc.model_identifier, instanceName=name)
        self._start, self._stop = 0.0, None
        self._end: tuple[float | None, str] = (None, "fmi3DoStep returned Discard")
        raw = self.slave._functions
        self.do_step = self._do_step_adapter(raw["fmi3DoStep"])
        self.get = {t: self._get_adapter(t) for t in FMI3_FUNCTIONS}
        self.set = {t: self._set_adapter(t) for t in FMI3_FUNCTIONS}

    # ----------------------------------------------------------------- hot-loop adapters

    def _do_step_adapter(self, raw) -> Adapter:
        event, terminate, early = ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool()
        last = ctypes.c_double()
        out = (ctypes.byref(event), ctypes.byref(terminate), ctypes.byref(early), ctypes.byref(last))

        def do_step(component, t: float, h: float, no_prior_state: int) -> int:
            status = raw(component, t, h, no_prior_state, *out)
            if terminate.value and status <= FMI_WARNING:  # the step completed: its outputs are valid
                self._end = (t + h, f"fmi3DoStep returned {STATUS[status]} with terminateSimulation = true")
                return FMI_DISCARD
            if status == FMI_DISCARD:
                self._end = (last.value if last.value > t else None,
                             f"fmi3DoStep returned Discard with terminateSimulation = "
                             f"{'true' if terminate.value else 'false'} and lastSuccessfulTime = {last.value:g}")
            return status
        return do_step

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        """What ``do_step`` kept when it ended the run: t + h after OK or Warning with
        terminateSimulation (the step completed, FMI 3.0 §4.2.4), lastSuccessfulTime after Discard."""
        return self._end

    def _get_adapter(self, type_name: str) -> Adapter:
        suffix, ctype = FMI3_FUNCTIONS[type_name]
        raw = self.slave._functions[f"fmi3Get{suffix}"]
        plans: dict[int, _Gather] = {}
        elements = self.desc.elements

        if not any(exchange_type(e.array) == type_name for e in elements.values()) and ctype is not ctypes.c_bool:
            def get(component, vrs, n: int, values) -> int:
                return raw(component, vrs, n, values, n)
            return get

        def get(component, vrs, n: int, values) -> int:
            plan = plans.get(id(vrs))
            if plan is None or not plan.serves(vrs, values):
                plan = plans[id(vrs)] = _Gather(vrs, n, values, elements, ctype)
            status = raw(component, plan.vrs, plan.nvr, plan.scratch, plan.nvalues)
            if status <= FMI_WARNING:
                plan.copy_out()
            return status
        return get

    def _set_adapter(self, type_name: str) -> Adapter:
        suffix, ctype = FMI3_FUNCTIONS[type_name]
        raw = self.slave._functions[f"fmi3Set{suffix}"]
        raw_get = self.slave._functions[f"fmi3Get{suffix}"]
        plans: dict[int, _Gather] = {}
        elements = self.desc.elements

        if not any(exchange_type(e.array) == type_name for e in elements.values()) and ctype is not ctypes.c_bool:
            def set_(component, vrs, n: int, values) -> int:
                return raw(component, vrs, n, values, n)
            return set_

        def set_(component, vrs, n: int, values) -> int:
            plan = plans.get(id(vrs))
            if plan is None or not plan.serves(vrs, values):
                plan = _Gather(vrs, n, values, elements, ctype)
                # the whole input arrays as the FMU holds them; from then on only the master writes them
                status = raw_get(component, plan.vrs, plan.nvr, plan.scratch, plan.nvalues)
                if status > FMI_WARNING:
                    return status
                plans[id(vrs)] = plan
            plan.copy_in()
            return raw(component, plan.vrs, plan.nvr, plan.scratch, plan.nvalues)
        return set_

    # ----------------------------------------------------------------- set-up

    def _log(self, env, status: int, category: bytes | None, message: bytes | None) -> None:
        self.messages.append(log_line(status, category, message))

    def instantiate(self, fmu_log: str = "errors") -> None:
        """fmi3InstantiateCoSimulation (FMI 3.0 §4.2.1); ``fmu_log`` as in `cosim.instances.Instance`."""
        logging_on = self.logging_on(fmu_log)
        try:
            self.slave.instantiate(loggingOn=logging_on, logMessage=self._log)
        except Exception as e:
            raise SetupError(f"fmi3InstantiateCoSimulation failed for {self.desc.path.name} (instantiation "
                             f"token {self.desc.md.guid}): {e}." + self.last_messages(),
                             element=f"component '{self.name}'") from None
        self.component = self.slave.component
        self.restrict_logging(fmu_log)

    def setup_experiment(self, start: float, stop: float) -> None:
        """Kept for `enter_initialization_mode`: FMI 3.0 has no fmi3SetupExperiment."""
        self._start, self._stop = start, stop

    def set_start(self, variable: ModelVariable, value: float | int | bool | str) -> None:
        """Set a parameter or start value before initialisation (FMI 3.0 §2.2.6.2)."""
        vr = [variable.valueReference]
        kind = exchange_type(variable)
        if kind == "String":
            self.slave.setString(vr, [str(value)])
        else:
            {"Real": self.slave.setFloat64, "Integer": self.slave.setInt32,
             "Boolean": self.slave.setBoolean}[kind](vr, [value])

    def enter_initialization_mode(self) -> None:
        self.slave.enterInitializationMode(startTime=self._start, stopTime=self._stop)

    def exit_initialization_mode(self) -> None:
        self.slave.exitInitializationMode()

    def free(self) -> None:
        """As `cosim.instances.fmi2.FMI2Instance.free` (FMI 3.0 §2.3.1 state machine).  pythonfmu3 0.3.4
        libraries keep the same static interpreter state as pythonfmu 0.7.0 (they export
        ``finalizePythonInterpreter`` too), so it is released the same way before unloading."""
        end_instance(self, lambda: self.slave.fmi3FreeInstance(self.component))


class _Gather:
    """How the value references one get/set call names map onto fmi3 calls: the distinct
    variables (an array once, however many of its elements are named), a scratch buffer for
    their values in the FMU's C type, and the position of each named value in it.  Numbers
    and Booleans only: strings are exchanged scalar by scalar (String array elements are
    refused by `cosim.description.FMUDescription.variable`).

    A plan serves one pair of caller arrays (value references, values), as the execution
    passes the same ones at every call; it keeps them, so their ``id`` keys it safely."""

    def __init__(self, vrs, n: int, values, elements: dict[int, ArrayElement], ctype: type):
        self.caller = (vrs, values)
        self.out = np.ctypeslib.as_array(values, shape=(n,))
        variables: dict[int, int] = {}  # FMU value reference -> offset in scratch
        offsets: list[int] = []
        total = 0
        for vr in vrs[:n]:
            element = elements.get(vr)
            real_vr, size, index = (element.array.valueReference, element.size, element.index) \
                if element is not None else (vr, 1, 0)
            if real_vr not in variables:
                variables[real_vr] = total
                total += size
            offsets.append(variables[real_vr] + index)
        self.nvr = len(variables)
        self.vrs = (ctypes.c_uint * max(1, self.nvr))(*variables)
        self.nvalues = total
        self.scratch = (ctype * max(1, total))()
        self.positions = np.array(offsets, dtype=np.intp)
        self.view = np.ctypeslib.as_array(self.scratch)

    def serves(self, vrs, values) -> bool:
        return self.caller[0] is vrs and self.caller[1] is values

    def copy_out(self) -> None:
        self.out[:] = self.view[self.positions]

    def copy_in(self) -> None:
        self.view[self.positions] = self.out
