"""FMI 2.0 Co-Simulation instances (fmpy's `FMU2Slave`), and the process-wide FMI 2.0
callbacks that collect each instance's log messages."""
from __future__ import annotations

import collections
import ctypes

import fmpy
from fmpy.fmi2 import (FMU2Slave, printLogMessage, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from ...kernel import LogTarget, fmi2_logger
from ...model.fmu import ExchangeType, FMUDescription, Variable
from ...errors import SetupError
from .base import InstanceBase, NativeStep, address, end_instance, log_line, serial_reason
from .loading import quick

#: Log messages by instance name.  One logger serves the whole process (`cosim.kernel.fmi2_logger`
#: keeps one target), so it dispatches, and passes messages of instances that are not ours to
#: fmpy's default printer.
_LOG_TARGETS: dict[str, collections.deque] = {}
_CALLBACKS: list = []


def _log(env, instance_name, status, category, message) -> None:
    name = instance_name.decode("utf-8", "replace") if instance_name else ""
    target = _LOG_TARGETS.get(name)
    if target is not None:
        target.append(log_line(status, category, message))
    else:  # an FMU run by plain fmpy in the same process: fmpy's own default (print)
        printLogMessage(env, instance_name, status, category, message)


def _callbacks() -> fmi2CallbackFunctions:
    """The process-wide FMI callbacks, created once and kept alive for every instance.  The logger
    is `cosim.kernel`'s C logger, which formats a message's printf arguments only where it can
    safely (never a %n, never a %s argument that is not readable text: issue 41) and hands the
    text to `_log`; without the compiled library `_log` itself, which receives every message
    verbatim (ctypes cannot read variadic arguments).  Not fmpy's logger proxy: its vsnprintf
    dies of SIGSEGV on "%s%n" sent without arguments."""
    if not _CALLBACKS:
        target = LogTarget(_log)
        native = fmi2_logger(target)
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(native if native is not None else _log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        _CALLBACKS.extend([callbacks, target])
    return _CALLBACKS[0]


class FMI2Instance(InstanceBase):
    """One live FMI 2.0 Co-Simulation instance with raw FMI functions for the hot loop
    (`cosim.run.instances.Instance`)."""

    api = "fmi2"

    #: fmpy's class for the FMI 2.0 interface the instance drives
    interface = quick(FMU2Slave)

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str):
        super().__init__(name, desc)
        self.slave = self.interface(guid=desc.guid, unzipDirectory=unzip_dir,
                                    modelIdentifier=desc.model_identifier, instanceName=name)
        _LOG_TARGETS[name] = self.messages
        raw = self.slave._functions
        if "fmi2DoStep" in raw:  # Co-Simulation; a Model Exchange instance steps by its own method
            self.do_step = raw["fmi2DoStep"]
        self.get = {"Real": raw["fmi2GetReal"], "Integer": raw["fmi2GetInteger"],
                    "Boolean": raw["fmi2GetBoolean"], "String": raw["fmi2GetString"]}
        self.set = {"Real": raw["fmi2SetReal"], "Integer": raw["fmi2SetInteger"],
                    "Boolean": raw["fmi2SetBoolean"], "String": raw["fmi2SetString"]}

    def native_step(self) -> NativeStep | str:
        """fmi2DoStep as a C address (`cosim.kernel`); a Model Exchange instance (stepped by the
        master's integrator, in Python) has none."""
        raw = self.slave._functions
        if getattr(self, "do_step", None) is not raw.get("fmi2DoStep"):
            return f"component '{self.name}' is Model Exchange (integrated by the master)"
        return NativeStep(2, self.component, address(raw["fmi2DoStep"]), serial=serial_reason(self))

    def native_exchange(self, type_name: ExchangeType) -> tuple[int, int] | str:
        """fmi2Get/fmi2Set of Real, Integer or Boolean as C addresses (`cosim.kernel`); strings
        are copied by Python (`cosim.run.exchange.TypedBuffers.get_call`)."""
        if type_name not in ("Real", "Integer", "Boolean"):
            return f"component '{self.name}' exchanges {type_name} values"
        return address(self.get[type_name]), address(self.set[type_name])

    def instantiate(self, fmu_log: str = "errors") -> None:
        """Instantiate.  ``fmu_log``: "errors" (default) turns logging on with only the FMI 2.0
        status categories the FMU declares (logStatusWarning, logStatusError, ...), so an FMU
        that logs every call (OpenModelica's logFmi2Call) does not slow the run; "all" turns
        every category on; "off" turns logging off (fastest: pythonfmu FMUs then skip their
        log queue, but a failing FMU's own explanation is lost)."""
        logging_on = self.logging_on(fmu_log)
        try:
            self.slave.instantiate(callbacks=_callbacks(), loggingOn=logging_on)
        except Exception as e:
            raise SetupError(f"fmi2Instantiate failed for {self.desc.path.name} (GUID {self.desc.guid}): {e}."
                             + self.last_messages(), element=f"component '{self.name}'") from None
        self.component = self.slave.component
        self.restrict_logging(fmu_log)

    def reuse(self, fmu_log: str) -> None:
        """After fmi2Reset (`cosim.run.instances.base.InstanceBase.reuse`); its log messages come
        here again (an instance of another FMU under the same name may have taken the name)."""
        super().reuse(fmu_log)
        _LOG_TARGETS[self.name] = self.messages

    def setup_experiment(self, start: float, stop: float) -> None:
        self.slave.setupExperiment(startTime=start, stopTime=stop)

    def set_start(self, variable: Variable, value: float | int | bool | str) -> None:
        """Set a parameter or start value before initialisation (FMI 2.0 §2.2.7)."""
        vr = [variable.vr]
        if variable.type == "String":  # fmpy's setString encodes to UTF-8 itself
            self.slave.setString(vr, [str(value)])
        else:  # an Enumeration is set as an Integer (FMI 2.0 §2.2.3)
            {"Real": self.slave.setReal, "Integer": self.slave.setInteger, "Enumeration": self.slave.setInteger,
             "Boolean": self.slave.setBoolean}[variable.type](vr, [value])

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        """After fmi2DoStep returned Discard: fmi2LastSuccessfulTime (None when the FMU does not
        give it) and fmi2Terminated, the two statuses FMI 2.0 §4.2.3 defines for that case."""
        raw = self.slave._functions
        last, terminated = ctypes.c_double(), ctypes.c_int()
        get_real, get_boolean = raw.get("fmi2GetRealStatus"), raw.get("fmi2GetBooleanStatus")
        last_time = last.value if get_real is not None and get_real(self.component, 2, ctypes.byref(last)) <= 1 \
            else None   # fmi2LastSuccessfulTime = 2, fmi2Terminated = 3 (fmi2StatusKind)
        said = get_boolean is not None and get_boolean(self.component, 3, ctypes.byref(terminated)) <= 1
        reason = "fmi2DoStep returned Discard"
        if said:
            reason += f" with fmi2Terminated = {'true' if terminated.value else 'false'}"
        if last_time is not None:
            reason += f" and fmi2LastSuccessfulTime = {last_time:g}"
        return last_time, reason

    def enter_initialization_mode(self) -> None:
        self.slave.enterInitializationMode()

    def exit_initialization_mode(self) -> None:
        self.slave.exitInitializationMode()

    def free(self) -> None:
        end_instance(self, lambda: self.slave.fmi2FreeInstance(self.component))
        if _LOG_TARGETS.get(self.name) is self.messages:
            del _LOG_TARGETS[self.name]
