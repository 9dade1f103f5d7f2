"""The FMI 3.0 face of the greyfmu slaves: every FMU of ``fmus/`` is also an FMI 3.0
Co-Simulation FMU (``<Name>3.fmu``, greyfmu.build), computed by the same slave class with the
same declarations; embedded in the FMI 3.0 FMUs next to ``_slave.py``.

pythonfmu3 0.3.4's library (the binary behind greyfmu's FMI 3.0 loader, fmi3_loader.c) imports
the module named in ``resources/slavemodule.txt``, which is this one, and asks it for the slave
class by the name it reads in the stub ``resources/<package>._slave3.py``: the FMI 2.0 class's
name.  `__getattr__` answers with `fmi3_slave` of the FMI 2.0 slave class (``fmus/<Name>.py``),
a subclass made once that adds the calls pythonfmu3 makes and pythonfmu does not:

- ``get_float64``/``set_float64`` (FMI 2.0 Real), ``get_int32``/``set_int32`` (Integer),
  ``get_int64``/``set_int64`` (the mode parameters, FMI 3.0 Enumerations of their IntEnum),
  ``get_boolean``, ``get_string`` and their setters, through the FMI 2.0 slave's compiled
  accessors (`GreyfmuSlave._compile_get`), so a get or set costs what it costs in FMI 2.0;
- the independent variable ``time`` FMI 3.0 requires (§2.4.7.4), value reference `time_vr`:
  the instance's current time when read; setting it is how greyfmu's loader gives the
  experiment's start time (pythonfmu3 drops the startTime of fmi3EnterInitializationMode and
  never calls ``setup_experiment``), so the FMI 3.0 FMU builds its objects for the same start
  as its FMI 2.0 sibling;
- log lines carrying the ``debug`` flag pythonfmu3 reads;
- the FMI 3.0 name of the function in the line an exception is said in (``fmi3DoStep``, not
  ``fmi2DoStep``; `FMI3_CALLS`).

Everything else — do_step, initialisation, FMU states (get, set, serialise: fmus/_state.py,
interchangeable with the FMI 2.0 sibling's), the exception contract with the loader's guard,
the warnings forwarding — is the FMI 2.0 slave's own code.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from pythonfmu import Integer, Real
from pythonfmu.enums import Fmi2Status

from _slave import CALLED_BY_PYTHONFMU, CompiledAccessors, GreyfmuSlave

PACKAGE = __name__.rpartition(".")[0]
"""The FMU's private package ('' where this module runs under its own name: a build, the tests)."""

FMI3_CALLS = {call: call.replace("fmi2", "fmi3").replace("Real", "Float64").replace("Integer", "Int32")
              .replace("FMUstate", "FMUState") for call in CALLED_BY_PYTHONFMU.values()}
"""The FMI 2.0 function named in an exception's line -> the FMI 3.0 function pythonfmu3 called."""

ACCESSORS3 = ("_get_float64", "_get_int32", "_get_int64", "_set_float64", "_set_int32", "_set_int64")
"""The FMI 3.0 accessors an instance adds to its declarations (not FMU state)."""


class Fmi3Calls:
    """The calls pythonfmu3 0.3.4 makes that pythonfmu 0.7.0 does not (see the module docstring);
    mixed in before a `GreyfmuSlave` subclass by `fmi3_slave`."""

    fmi_calls = FMI3_CALLS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.time_vr = len(self.vars)
        """The value reference of ``time``: the first after the FMI 2.0 slave's variables (greyfmu.build)."""
        enumerations = {vr for vr, name in self._attributes.items() if name in self.choices}
        self._get_float64 = CompiledAccessors(lambda vrs: self._compile_float64(vrs, setting=False))
        self._set_float64 = CompiledAccessors(lambda vrs: self._compile_float64(vrs, setting=True))
        self._get_int32 = CompiledAccessors(lambda vrs: self._compile_get(Integer, self._typed(vrs, enumerations, False)))
        self._set_int32 = CompiledAccessors(lambda vrs: self._compile_set(Integer, self._typed(vrs, enumerations, False)))
        self._get_int64 = CompiledAccessors(lambda vrs: self._compile_get(Integer, self._typed(vrs, enumerations, True)))
        self._set_int64 = CompiledAccessors(lambda vrs: self._compile_set(Integer, self._typed(vrs, enumerations, True)))
        self._declarations |= {"time_vr", *ACCESSORS3}

    def _typed(self, vrs: tuple[int, ...], enumerations: set[int], enumeration: bool) -> tuple[int, ...]:
        """``vrs`` if each is an Enumeration (``enumeration``) or each is not; TypeError naming one that is not."""
        for vr in vrs:
            if (vr in enumerations) != enumeration:
                variable = self._variable(vr, Integer)
                raise TypeError(f"{self.instance_name}: variable {variable.name} (value reference {vr}) is "
                                + ("not an Enumeration: use fmi3Get/SetInt32" if enumeration
                                   else "an Enumeration: use fmi3Get/SetInt64"))
        return vrs

    def _compile_float64(self, vrs: tuple[int, ...], setting: bool) -> Callable:
        """FMI 2.0's Real accessor of ``vrs``; with ``time`` among them: its value, or the start time set."""
        if self.time_vr not in vrs:
            return self._compile_set(Real, vrs) if setting else self._compile_get(Real, vrs)
        if setting:
            if vrs != (self.time_vr,):
                raise TypeError(f"{self.instance_name}: time (value reference {self.time_vr}) is set alone, "
                                "by greyfmu's loader before initialisation")
            return lambda values: self.setup_experiment(float(values[0]))
        getters = [None if vr == self.time_vr else self._compile_get(Real, (vr,)) for vr in vrs]
        return lambda: [self.current_time if get is None else get()[0] for get in getters]

    def get_float64(self, vrs: list[int]) -> list[float]:
        try:
            return self._get_float64[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetReal", error)
            raise

    def get_int32(self, vrs: list[int]) -> list[int]:
        try:
            return self._get_int32[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetInteger", error)
            raise

    def get_int64(self, vrs: list[int]) -> list[int]:
        try:
            return self._get_int64[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi3GetInt64", error)
            raise

    def set_float64(self, vrs: list[int], values: list[float]) -> None:
        try:
            self._set_float64[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetReal", error)
            raise

    def set_int32(self, vrs: list[int], values: list[int]) -> None:
        try:
            self._set_int32[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetInteger", error)
            raise

    def set_int64(self, vrs: list[int], values: list[int]) -> None:
        try:
            self._set_int64[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi3SetInt64", error)
            raise

    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None, debug: None = None) -> None:
        """pythonfmu's log line, with the ``debug`` flag pythonfmu3's library reads from each (false: said
        as the guard's filter decides, greyfmu/loader/guard.h)."""
        super().log(msg, status, category)
        self.log_queue[-1].debug = False

_SLAVES: dict[type, type] = {}
"""FMI 2.0 slave class -> its FMI 3.0 class, made once per process and kept (pythonfmu3 holds it)."""


def fmi3_slave(slave: type[GreyfmuSlave]) -> type:
    """The FMI 3.0 class of ``slave``: `Fmi3Calls` before it, same name, module and qualified name, so
    FMU states name the same model and classes as the FMI 2.0 sibling's."""
    made = _SLAVES.get(slave)
    if made is None:
        made = _SLAVES[slave] = type(slave.__name__, (Fmi3Calls, slave),
                                     {"__module__": slave.__module__, "__qualname__": slave.__qualname__})
    return made


def __getattr__(name: str) -> type:
    """pythonfmu3 asks this module (its slave module) for the class ``name``: the FMI 3.0 class of
    the FMI 2.0 slave ``<package>.<name>.<name>``."""
    if not name.isidentifier() or name.startswith("_"):
        raise AttributeError(name)
    module = importlib.import_module(f"{PACKAGE}.{name}" if PACKAGE else name)
    slave = getattr(module, name, None)
    if not (isinstance(slave, type) and issubclass(slave, GreyfmuSlave)):
        raise AttributeError(f"{module.__name__} has no greyfmu slave class {name}")
    return fmi3_slave(slave)
