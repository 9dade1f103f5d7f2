"""FMI 3.0 plumbing for the greyfmu slaves built with pythonfmu3; embedded in every FMI 3.0
FMU next to the slave module.  The FMI 3.0 counterpart of ``fmus/_slave.py``, with the same
contract for a slave: declare variables with ``parameter``/``input``/``output``, implement
``build()`` (create the greyfmu objects from the parameters) and ``advance(t, h)`` (one
communication step).  This base class

- re-creates the greyfmu objects when they are next used after a parameter was set, so
  outputs read during initialisation already use the parameters the master set;
- takes the start time from the first ``do_step``: pythonfmu3 0.3.4 drops the startTime
  of fmi3EnterInitializationMode (FMI 3.0 §2.3.2) and never calls ``setup_experiment``;
- refuses non-finite inputs and outputs in ``do_step``: it logs a message naming the
  variable and returns an error status instead of passing NaN on;
- forwards the warnings raised in its calls (greyfmu's ``logging`` warnings and Python warnings) to
  the FMU log of the instance that raised them (greyfmu.forwarding: routes installed once per
  process, paid only when a warning fires);
- declares the independent variable ``time`` that FMI 3.0 requires (§2.4.7.4);
- keeps a host alive after a call raised: pythonfmu3 0.3.4 answers an exception with fmi3Fatal
  after releasing the instance, its class and its log queue (PySlaveInstance.cpp,
  handle_py_exception calls cleanPyObject) and releases them again when the instance is freed
  (~PySlaveInstance), which frees objects still in use and crashes the host at a later garbage
  collection.  Each call pythonfmu3 makes on an instance gives one reference of each back when
  it raises (fmus/_inprocess.py, give_back), and the class-level FMU-state conversions never
  raise: the FMUs declare no FMU state (canGetAndSetFMUState="false"), so getting or setting one
  is refused;
- takes its resources folder off ``sys.path`` again and points its private package at it
  (fmus/_inprocess.py, settle_imports: the FMU's code, pythonfmu3's run-time included, is
  imported under a name private to the FMU, greyfmu.privatise);
- keeps a host alive at exit: pythonfmu3 0.3.4's library (binaries/x86_64-linux/<model>.so) holds
  its interpreter state in a static std::shared_ptr whose destructor (registered with
  __cxa_atexit when the library is loaded) frees it at exit, after which the library's
  destructor function onLibraryUnload (.fini_array, run later by _dl_fini) calls
  finalizePythonInterpreter on the freed block and decrements a word in it: valgrind shows the
  invalid read and write in finalizePythonInterpreter in every process that loaded the FMU, and
  glibc aborts ("corrupted double-linked list") when the block was reused.  The same bug as
  pythonfmu 0.7.0's, which greyfmu/loader/fmi2_loader.c answers the same way: the library's
  exported finalizePythonInterpreter, which empties the pointer, is registered as an exit
  handler after the library was loaded (`_finalize_before_exit`), so it runs before the static
  destructor and both later releases find the pointer empty.
"""

from __future__ import annotations

import ctypes
import functools
import os
import re
import sys
from abc import abstractmethod
from collections.abc import Callable
from pathlib import Path
from enum import IntEnum
from math import isfinite
from typing import Any, ClassVar

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Slave, Fmi3Status, Fmi3StepResult, Fmi3Variability, Int32
from pythonfmu3.variable_types import EnumerationType
from pythonfmu3.variables import Enumeration

from _inprocess import give_back, settle_imports
from greyfmu.forwarding import forward_from, keep_routing

REQUIREMENTS = "Requires Python 3.10+ with numpy and scipy on the target; the greyfmu package is embedded as FMU resources."


STEPPED = Fmi3StepResult()
"""What ``do_step`` returns after a step that went well (an immutable NamedTuple, made once)."""

_FINALIZED_BEFORE_EXIT: dict[str, ctypes.CDLL] = {}
"""The pythonfmu3 libraries whose finalizePythonInterpreter is registered to run at exit, by
path; each handle is kept for the life of the process, so the library is never unloaded under
its exit handler."""
_FOLDERS_DONE: set[str] = set()
"""The binaries folders whose library is registered: a later instance of the same FMU looks no further."""


def _finalize_before_exit(resources: str) -> str | None:
    """Register the finalizePythonInterpreter of the FMU library next to ``resources`` (Linux:
    ``binaries/x86_64-linux/*.so``) as an exit handler, once per library and process (see the
    module docstring); the reason it could not be registered, or None."""
    if not sys.platform.startswith("linux"):
        return None  # the Windows DLL's statics are released by DLL_PROCESS_DETACH in one order
    folder = Path(resources).parent / "binaries" / "x86_64-linux"
    if str(folder) in _FOLDERS_DONE:
        return None
    libraries = sorted(folder.glob("*.so"))
    if len(libraries) != 1:
        return f"{folder}: expected one FMU library, found {len(libraries)}"
    path = os.path.realpath(libraries[0])
    if path in _FINALIZED_BEFORE_EXIT:
        _FOLDERS_DONE.add(str(folder))
        return None
    try:
        library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_NOW)
        finalize = ctypes.cast(library.finalizePythonInterpreter, ctypes.c_void_p).value
    except (OSError, AttributeError) as error:
        return f"{path}: finalizePythonInterpreter not found in the loaded library ({error})"
    register = ctypes.CDLL(None).__cxa_atexit
    register.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    register.restype = ctypes.c_int
    if register(finalize, None, None) != 0:
        return f"{path}: __cxa_atexit refused finalizePythonInterpreter"
    _FINALIZED_BEFORE_EXIT[path] = library
    _FOLDERS_DONE.add(str(folder))
    return None


_CALLED_BY_PYTHONFMU3 = re.compile(r"(get|set)_[a-z0-9_]+|setup_experiment|enter_initialization_mode|"
                                   r"exit_initialization_mode|do_step|terminate|_get_fmu_state|_set_fmu_state")
"""The methods pythonfmu3 0.3.4's C++ wrapper calls on an instance."""


def _given_back_when_raising(method: Callable[..., Any]) -> Callable[..., Any]:
    """``method``, which gives back what pythonfmu3 will release twice when it raises."""

    @functools.wraps(method)
    def guarded(self: Fmi3Slave, *args: Any) -> Any:
        try:
            return method(self, *args)
        except BaseException:
            give_back(self, type(self), self.log_queue)
            raise

    guarded.given_back_when_raising = True
    return guarded


class ScalarEnumeration(Enumeration):
    """pythonfmu3 0.3.4's Enumeration lacks the ``dimensions`` and ``size`` its get_int64 and
    set_int64 read: a scalar has no dimensions and size 1."""

    dimensions: tuple[()] = ()

    def size(self, variables: dict) -> int:
        return 1


class GreyfmuSlave3(Fmi3Slave):
    """Base of the greyfmu FMI 3.0 slaves (see the module docstring)."""

    output_dependencies: ClassVar[dict[str, list[str]]]
    """For every output, the inputs it depends on at the same instant (read by ``greyfmu build``)."""
    requirements: ClassVar[tuple[str, ...]] = ("numpy", "scipy")
    """The modules the FMU imports from the host's Python (part of its private package's name)."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Every method pythonfmu3 calls on an instance of ``cls`` gives back its references when it raises."""
        super().__init_subclass__(**kwargs)
        for name in filter(_CALLED_BY_PYTHONFMU3.fullmatch, dir(cls)):
            method = getattr(cls, name)
            if callable(method) and not getattr(method, "given_back_when_raising", False):
                setattr(cls, name, _given_back_when_raising(method))

    def _get_fmu_state(self) -> dict[str, Any]:
        raise NotImplementedError(f"{self.instance_name}: this FMU has no FMU state (canGetAndSetFMUState is false)")

    def _set_fmu_state(self, state: Any) -> None:
        raise NotImplementedError(f"{self.instance_name}: this FMU has no FMU state (canGetAndSetFMUState is false)")

    @staticmethod
    def _fmu_state_to_bytes(state: Any) -> bytes:
        """No state to serialise; called on the class, so it must not raise (see the module docstring)."""
        return b""

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> None:
        """No state to restore (``_set_fmu_state`` refuses it); called on the class, so it must not raise."""
        return None

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        settle_imports(self.resources)
        self.author = "greyfmu"
        self.time = 0.0
        self.experiment_start = 0.0
        self._stepped = False
        self._input_names: list[str] = []
        self._output_values: dict[str, Callable[[], float]] = {}
        """Output name -> its value function, valid once the greyfmu objects are built."""
        self._built = False
        self.choices: dict[str, type[IntEnum]] = {}
        """Parameter name -> the IntEnum of each Enumeration parameter (``greyfmu build`` describes its items)."""
        self.register_variable(Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous,
                                       description="Simulation time"))
        if self.resources is not None and (why := _finalize_before_exit(self.resources)) is not None:
            self.log(f"{self.instance_name}: the host may crash at exit (pythonfmu3 0.3.4 releases its state "
                     f"twice there): {why}", Fmi3Status.warning)

    def parameter(self, name: str, start: float | int, description: str, unit: str | None = None) -> None:
        """Declare a fixed parameter (an ``int`` start makes it Int32, an ``IntEnum`` member an
        Enumeration of that IntEnum's members, FMI 3.0 §2.4.7.8); setting it makes the next use
        rebuild the greyfmu objects."""
        setattr(self, name, start)

        def setter(value: float | int) -> None:
            setattr(self, name, value)
            self._built = False

        declaration = {"description": description, "causality": Fmi3Causality.parameter,
                       "variability": Fmi3Variability.fixed, "setter": setter}
        if isinstance(start, IntEnum):
            self.choices[name] = type(start)
            self.register_variable(ScalarEnumeration(name, start=int(start), **declaration),
                                   var_type=EnumerationType(type(start).__name__, type(start)))
            return
        variable_type = Int32 if isinstance(start, int) else Float64
        extra = {"unit": unit} if unit is not None and variable_type is Float64 else {}
        self.register_variable(variable_type(name, start=start, **declaration, **extra))

    def input(self, name: str, start: float, description: str) -> None:
        """Declare a continuous Float64 input."""
        setattr(self, name, start)
        self.register_variable(Float64(name, start=start, description=description, causality=Fmi3Causality.input,
                                       variability=Fmi3Variability.continuous))
        self._input_names.append(name)

    def output(self, name: str, description: str, value: Callable[[], float], variability: Fmi3Variability) -> None:
        """Declare a Float64 output computed by ``value()`` from up-to-date greyfmu objects."""

        def getter() -> float:
            if not self._built:
                self._ensure_built()
            return value()

        self.register_variable(Float64(name, description=description, causality=Fmi3Causality.output,
                                       variability=variability, getter=getter))
        self._output_values[name] = value

    @abstractmethod
    def build(self) -> None:
        """Create the greyfmu objects from the current parameters and ``self.experiment_start``."""

    @abstractmethod
    def advance(self, t: float, h: float) -> None:
        """Advance the greyfmu objects over the communication step ``[t, t + h]``."""

    def exit_initialization_mode(self) -> None:
        self._ensure_built()

    def do_step(self, current_time: float, step_size: float) -> Fmi3StepResult:
        """One communication step, the path a host takes at every step with fmi3DoStep: the inputs
        checked, the objects rebuilt if a parameter changed, the warnings' route kept in front
        (greyfmu.forwarding, one comparison), ``advance``, the outputs checked.  Nothing allocated
        but the new time (a float) and what ``advance`` allocates.  Gives back its references when it raises, itself (one
        frame less than `_given_back_when_raising`'s)."""
        try:
            if not self._stepped:
                self._stepped = True
                if current_time != self.experiment_start:
                    self.experiment_start = current_time
                    self._built = False
            attributes = self.__dict__
            for name in self._input_names:  # plain attributes
                if not isfinite(attributes[name]):
                    return self._error(f"input {name} = {attributes[name]} at t = {current_time} s is not a finite number")
            if not self._built:
                self._ensure_built()
            keep_routing()
            self.advance(current_time, step_size)
            self.time = current_time + step_size
            for name, output_value in self._output_values.items():  # the objects are built: no getter's build check
                if not isfinite(output_value()):
                    return self._error(f"output {name} = {output_value()} at t = {self.time} s is not a finite number")
            return STEPPED
        except BaseException:
            give_back(self, type(self), self.log_queue)
            raise

    do_step.given_back_when_raising = True

    def _ensure_built(self) -> None:
        if not self._built:
            try:
                keep_routing()
                self.build()
            except (ValueError, ArithmeticError) as error:
                self.log(f"{self.instance_name}: invalid parameters: {error}", Fmi3Status.error)
                raise
            self._built = True

    def forward_warning(self, message: str) -> None:
        """A greyfmu warning raised in one of this instance's calls (greyfmu.forwarding): a warning in its FMU log."""
        self.log(f"{self.instance_name}: {message}", Fmi3Status.warning)

    def _error(self, message: str) -> Fmi3StepResult:
        self.log(f"{self.instance_name}: {message}", Fmi3Status.error)
        return Fmi3StepResult(status=Fmi3Status.error)


forward_from(_given_back_when_raising(GreyfmuSlave3.exit_initialization_mode), GreyfmuSlave3.do_step,
             GreyfmuSlave3._ensure_built)
"""A warning raised in a call pythonfmu3 makes (each wrapped by `_given_back_when_raising`) or in a
build reaches the instance's FMU log (`GreyfmuSlave3.forward_warning`)."""
