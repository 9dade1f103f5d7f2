"""What every live instance offers the execution (`Instance`), and what they share.

An instance is one FMU driven through one interface: FMI 2.0 Co-Simulation
(`cosim.run.instances.fmi2`), FMI 3.0 Co-Simulation (`cosim.run.instances.fmi3`) or FMI 2.0
Model Exchange integrated by the master (`cosim.run.instances.me`).  The execution
sees only `Instance`: raw ctypes-callable ``do_step``/``get``/``set`` for the hot
loop, a handful of set-up calls, and the log messages the FMU sent (kept so a
failure can be explained).
"""
from __future__ import annotations

import collections
import ctypes
import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal, Protocol, runtime_checkable


from ...model.fmu import ExchangeType, FMUDescription, Variable
from ...errors import RunError, SetupError
from .loading import exports
from .pythonfmu_state import release_pythonfmu_state

FMU_LOG_LEVELS = ("errors", "all", "off")
STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}

#: ``do_step(component, t, h, no_prior_state) -> status``
StepFunction = Callable[..., int]
#: ``get(component, vrs, n, values) -> status`` / ``set(...)`` on ctypes arrays
ExchangeFunction = Callable[..., int]


@runtime_checkable
class Instance(Protocol):
    """One live FMU as the execution drives it (`cosim.run.execution`).

    * ``do_step(component, t, h, no_prior_state) -> status`` and, per exchange type
      ("Real", "Integer", "Boolean", "String"), ``get[type](component, vrs, n, values) -> status``
      and ``set[type](...)``: called with ctypes arrays of value references and values
      (c_double for Real, c_int for Integer and Boolean, char* for String, as fmi2 declares them);
    * ``api``: the prefix of its FMI functions ("fmi2" or "fmi3"), for messages;
    * ``component`` (the handle passed back to those calls), ``failed`` (the FMI status name
      after an Error/Fatal, else None), ``messages``;
    * ``instantiate``, ``setup_experiment``, ``set_start``, ``enter_initialization_mode``,
      ``exit_initialization_mode``, ``free`` (these raise on a status above Warning);
    * ``step_end``: after ``do_step`` returned Discard, how far the FMU's outputs are valid;
    * ``step_outcome``: the post-step of a doStep made outside ``do_step`` (by the compiled loop,
      `cosim.kernel`), which turns its raw status into the one ``do_step`` would have returned;
    * ``last_messages``: the FMU's last log messages, as a sentence to append to an error.
    """
    name: str
    desc: FMUDescription
    api: Literal["fmi2", "fmi3"]
    component: object
    failed: str | None
    messages: collections.deque[str]
    do_step: StepFunction
    get: Mapping[ExchangeType, ExchangeFunction]
    set: Mapping[ExchangeType, ExchangeFunction]

    def instantiate(self, fmu_log: str = "errors") -> None:
        """Instantiate; ``fmu_log`` ("errors", "all" or "off") says which of the FMU's log
        categories are turned on."""
        ...

    def setup_experiment(self, start: float, stop: float) -> None:
        """The experiment from ``start`` to ``stop`` (FMI 2.0: fmi2SetupExperiment; FMI 3.0 keeps it
        for entering initialization mode)."""
        ...

    def set_start(self, variable: Variable, value: float | int | bool | str) -> None:
        """Set ``variable``'s start ``value`` before initialization (a parameter, a start value)."""
        ...

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        """After ``do_step(t, h)`` ended the run (returned Discard): the time up to which the
        FMU's outputs are valid (None when it does not say) and what the FMU reported."""
        ...

    def step_outcome(self, t: float, h: float, status: int) -> int:
        """The status ``do_step(t, h)`` returns, from the ``status`` of a doStep(t, h) the
        compiled loop made with this instance's C functions (FMI 3.0: read from the out-arguments
        the FMU wrote; FMI 2.0: ``status`` itself)."""
        ...

    def enter_initialization_mode(self) -> None:
        """Enter initialization mode."""
        ...

    def exit_initialization_mode(self) -> None:
        """Exit initialization mode: the instance steps from here on."""
        ...

    def free(self) -> None:
        """End the instance as the FMI state machine allows after its last status (`end_instance`)
        and unload its library."""
        ...

    def last_messages(self) -> str:
        """The FMU's last log messages, as a suffix for an error message (empty if none)."""
        ...


@dataclass(frozen=True)
class NativeStep:
    """An instance's doStep as the compiled loop calls it (`cosim.kernel`): ``api`` 2 or 3 (the
    C signature of the function at address ``do_step``), the instance handle ``component``;
    ``post_step``: the addresses of fmi3DoStep's four out-arguments (eventHandlingNeeded,
    terminateSimulation, earlyReturn, lastSuccessfulTime), which the instance's post-step
    (`Instance.step_outcome`) reads, zeros for FMI 2.0; ``serial``: why it must not run
    concurrently with other instances' doSteps ("": it may)."""
    api: int
    component: int
    do_step: int
    post_step: tuple[int, int, int, int] = (0, 0, 0, 0)
    serial: str = ""


def serial_reason(inst: InstanceBase) -> str:
    """Why an instance's FMI calls must stay on one thread with the others' ("" if they need not):
    its model description says canBeInstantiatedOnlyOncePerProcess (FMI 2.0 §4.3.1, FMI 3.0
    §4.2.1: the FMU may keep global state), or it is a pythonfmu FMU (its library exports
    ``finalizePythonInterpreter``, or, behind our drop-in loader, its generationTool says
    PythonFMU), whose Python do_step holds the GIL: nothing to gain."""
    if inst.desc.instantiated_once_per_process:
        return f"component '{inst.name}' says canBeInstantiatedOnlyOncePerProcess"
    if exports(inst.slave, "finalizePythonInterpreter") \
            or (inst.desc.generation_tool or "").lower().startswith("pythonfmu"):
        return f"component '{inst.name}' is a pythonfmu FMU (its Python do_step holds the GIL)"
    return ""


@runtime_checkable
class NativeInstance(Protocol):
    """An instance whose hot-loop calls the compiled loop can make itself, call by call: where
    it cannot, the operation stays with Python (`cosim.run.program`)."""

    def native_step(self) -> NativeStep | str:
        """Its doStep as a C function, or why it has none (a sentence naming the component)."""
        ...

    def native_exchange(self, type_name: ExchangeType) -> tuple[int, int] | str:
        """The C addresses of its get and set functions for ``type_name`` (called with the
        C signature of its FMI version on the exchange buffers), or why it has none."""
        ...


def fmi_failure(inst: Instance, what: str, status: int, t: float) -> RunError:
    """The error of ``inst``'s FMI call ``what`` (its name without the API prefix: "DoStep",
    "Get") that returned ``status`` above Warning at ``t``, with the FMU's last messages; after
    Error or Fatal the instance is marked ``failed`` (how `end_instance` may end it)."""
    if status >= 3:
        inst.failed = STATUS.get(status, "Fatal")
    return RunError(f"{inst.api}{what} returned {STATUS.get(status, status)} at t = {t:g}.{inst.last_messages()}",
                    time=t, component=inst.name, status=status,
                    element=f"component '{inst.name}' ({inst.desc.path.name})")


def address(function) -> int:
    """The C address of a ctypes foreign function (kept on it: the instances of one library share
    their function objects, `cosim.run.instances.loading`)."""
    try:
        return function.c_address
    except AttributeError:
        function.c_address = ctypes.cast(function, ctypes.c_void_p).value
        return function.c_address


def log_line(status: int, category: bytes | None, message: bytes | None) -> str:
    """One FMU log message as the master keeps it: ``[Status] category: text``."""
    text = message.decode("utf-8", "replace") if message else ""
    cat = category.decode("utf-8", "replace") if category else ""
    return f"[{STATUS.get(status, status)}] {cat}: {text}".strip()


class InstanceBase:
    """What every instance kind keeps besides its FMI functions: its name and description, the
    last log messages of its FMU (to explain a failure), the component handle and the status
    it failed with; and how logging is turned on (``fmu_log``, see `cosim.run.instances.fmi2.FMI2Instance.instantiate`)."""

    def __init__(self, name: str, desc: FMUDescription):
        self.name = name
        self.desc = desc
        self.messages: collections.deque[str] = collections.deque(maxlen=20)
        self.component = None
        self.failed: str | None = None

    @staticmethod
    def logging_on(fmu_log: str) -> bool:
        """Whether to instantiate with logging on; refuses an unknown level."""
        if fmu_log not in FMU_LOG_LEVELS:
            raise SetupError(f"unknown FMU log level '{fmu_log}'; choose one of {', '.join(FMU_LOG_LEVELS)}.")
        return fmu_log != "off"

    def restrict_logging(self, fmu_log: str) -> None:
        """After instantiation: with "errors", only the FMU's logStatus* categories."""
        status_categories = [c for c in self.desc.log_categories if c.startswith("logStatus")]
        if fmu_log == "errors" and status_categories:
            self.slave.setDebugLogging(True, status_categories)

    def step_outcome(self, t: float, h: float, status: int) -> int:
        """FMI 2.0's fmi2DoStep has no out-arguments: its status is the outcome (`Instance`)."""
        return status

    def last_messages(self) -> str:
        return (" FMU log: " + " | ".join(self.messages)) if self.messages else ""

    def reuse(self, fmu_log: str) -> None:
        """Before a run on this instance after its reset (`cosim.run.instances.reuse`): forget the
        last run's log messages and log as ``fmu_log`` asks, as after `instantiate`."""
        self.messages.clear()
        self.restrict_logging(fmu_log)



def end_instance(inst: InstanceBase, free_instance: Callable[[], None]) -> None:
    """End an instance as the FMI state machine allows after its last status: terminate and
    free after OK/Warning/Discard, only free after Error, nothing after Fatal ("it is not
    possible to call any other function", FMI 2.0 §2.1.3, FMI 3.0 §2.3.1; freeing a pythonfmu
    instance after Fatal corrupted the interpreter's memory here).  Then release the pythonfmu
    interpreter state (`release_pythonfmu_state`), unload the library and forget the FMU's
    ``resources`` folder, which pythonfmu and pythonfmu3 put on the host's ``sys.path`` at
    every instantiation and never take off: our FMUs embed a copy of ``greyfmu`` there, and a
    later ``import greyfmu.build`` in this process (or in a worker spawned from it, which
    inherits ``sys.path``) would find that copy instead of the installed package."""
    if inst.component is not None and inst.failed != "Fatal":
        if inst.failed is None:
            try:
                inst.slave.terminate()
            except Exception:  # terminate refused: the instance is still freed
                pass
        free_instance()
        if exports(inst.slave, "finalizePythonInterpreter"):
            release_pythonfmu_state(inst.slave.dll)
        inst.slave.freeLibrary()
    inst.component = None
    _forget_path(os.path.normpath(os.path.join(inst.slave.unzipDirectory, "resources")))


#: sys.path as last seen by `_forget_path`, and its entries normalised
_seen_path: tuple[list[str], list[str]] = ([], [])


def _forget_path(folder: str) -> None:
    """Take the normalised ``folder`` off ``sys.path`` (each entry normalised once while sys.path
    does not change: 1000 instances freed read it 1000 times)."""
    global _seen_path
    if _seen_path[0] != sys.path:
        _seen_path = (list(sys.path), [os.path.normpath(entry) for entry in sys.path])
    if folder in _seen_path[1]:
        sys.path[:] = [entry for entry, norm in zip(*_seen_path) if norm != folder]
