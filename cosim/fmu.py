"""FMUs as the master sees them: their model description, checked, and live instances.

`describe` reads and checks a model description and decides which interface
the master drives (`FMUDescription.kind`): an FMI 2.0 Co-Simulation FMU
(``fmi2-cs``), an FMI 3.0 Co-Simulation FMU (``fmi3-cs``, cosim.fmi3) or an
FMI 2.0 Model Exchange FMU integrated by the master (``fmi2-me``, cosim.me).
`open_instance` returns the matching instance.  Every instance offers the
same small interface to the execution (see `Instance`): raw ctypes-callable
``do_step``/``get``/``set`` for the hot loop and a handful of set-up calls,
plus the log messages the FMU sent (kept so a failure can be explained).
"""
from __future__ import annotations

import atexit
import collections
import ctypes
import os
import re
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import fmpy
from attrs import define, field as attrs_field
from fmpy.fmi2 import (FMU2Slave, printLogMessage, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.model_description import ModelDescription, ModelVariable

from .errors import SetupError, did_you_mean
from .safeio import extract_archive

FMU_LOG_LEVELS = ("errors", "all", "off")
STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}


#: SSP 1.0 Component ``implementation`` values (SystemStructureDescription.xsd).
IMPLEMENTATIONS = ("any", "CoSimulation", "ModelExchange")


@dataclass
class FMUDescription:
    """A checked model description and the interface the master drives it through."""
    path: Path
    md: ModelDescription
    variables: dict[str, ModelVariable]
    #: For each output: the inputs it depends on at the same instant (FMI 2.0 ModelStructure).
    #: An output without a ``dependencies`` attribute depends on every input (FMI 2.0 §2.2.8).
    output_dependencies: dict[str, list[str]]
    #: "fmi2-cs", "fmi3-cs" or "fmi2-me"
    kind: str = "fmi2-cs"

    @property
    def model_identifier(self) -> str:
        interface = self.md.modelExchange if self.kind == "fmi2-me" else self.md.coSimulation
        return interface.modelIdentifier

    #: Array elements named by connectors (``vector[2]``), by the value reference the master
    #: gives them (not the FMU's; cosim.fmi3 maps it back to the array and the index).
    elements: dict[int, ArrayElement] = field(default_factory=dict)

    def variable(self, name: str, where: str, file: str) -> ModelVariable:
        """The variable called ``name``, or the element ``name`` names of an FMI 3.0 array."""
        var = self.variables.get(name)
        if var is not None:
            return var
        match = _ELEMENT.fullmatch(name)
        if match is not None and match.group(1) in self.variables and self.variables[match.group(1)].dimensions:
            return self._element(self.variables[match.group(1)], match.group(2), name, where, file)
        raise SetupError(f"the FMU {self.path.name} has no variable '{name}'.", file=file,
                         element=where, variable=name, hint=did_you_mean(name, self.variables))

    def _element(self, array: ModelVariable, index_text: str, name: str, where: str, file: str) -> ArrayElement:
        """One element of a one-dimensional FMI 3.0 array, 1-based as in Modelica and in the
        FMI 2.0 structured names of scalarised arrays (``x[1]`` is the first element)."""
        known = next((e for e in self.elements.values() if e.name == name), None)
        if known is not None:
            return known
        if len(array.dimensions) != 1 or array.type == "String":
            raise SetupError(f"'{array.name}' is a {len(array.dimensions)}-dimensional {array.type} array; only "
                             "elements of one-dimensional numeric and Boolean arrays can be connected.",
                             file=file, element=where, variable=name)
        size = _dimension_size(array.dimensions[0])
        if not index_text.strip().isdigit() or not 1 <= int(index_text) <= size:
            raise SetupError(f"'{index_text}' is not an element of {array.name}, an array of {size} values in "
                             f"{self.path.name}; elements are numbered {array.name}[1] .. {array.name}[{size}].",
                             file=file, element=where, variable=name)
        used = {v.valueReference for v in self.md.modelVariables} | set(self.elements)
        vr = 0xFFFFFFFF
        while vr in used:
            vr -= 1
        element = ArrayElement(name=name, valueReference=vr, type=array.type, description=array.description,
                               causality=array.causality, variability=array.variability, initial=array.initial,
                               declaredType=array.declaredType, unit=array.unit, min=array.min, max=array.max,
                               array=array, index=int(index_text) - 1, size=size)
        self.elements[vr] = element
        for deps in self.output_dependencies.values():  # an input element is known as its array
            if array.name in deps:
                deps.append(name)
        if array.name in self.output_dependencies:  # an output element depends on what its array does
            self.output_dependencies[name] = list(self.output_dependencies[array.name])
        return element


@define(eq=False)
class ArrayElement(ModelVariable):
    """One element of an FMI 3.0 array variable, exchanged as a scalar of its own."""
    array: ModelVariable = attrs_field(default=None, repr=False)
    #: 0-based position in the array's values (FMI 3.0 serialises arrays row-major, §2.4.7.5)
    index: int = 0
    size: int = 1


_ELEMENT = re.compile(r"(.+)\[([^\]]*)\]")


def _dimension_size(dimension) -> int:
    """A Dimension's extent: its ``start``, or the start of the structural parameter it names."""
    if dimension.start is not None:
        return int(dimension.start)
    return int(dimension.variable.start)


#: The exchange types of the master (the FMI 2.0 type names) for the FMI types it connects.
_EXCHANGE_TYPES = {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean", "String": "String",
                   "Float64": "Real", "Int32": "Integer"}


def exchange_type(variable: ModelVariable) -> str | None:
    """How the master exchanges ``variable``: "Real" (C double), "Integer" (C int), "Boolean"
    or "String", for FMI 2.0 variables of those types and FMI 3.0 Float64, Int32, Boolean and
    String; None for the types it does not connect (FMI 2.0 Enumeration, FMI 3.0 Float32,
    Int8..UInt64 but Int32, Enumeration, Binary, Clock)."""
    return _EXCHANGE_TYPES.get(variable.type)


_cache: dict[tuple[Path, str], FMUDescription] = {}


def describe(path: Path, where: str, file: str, implementation: str = "any") -> FMUDescription:
    """Read and check an FMU's model description; ``where``/``file`` say who refers to it and
    ``implementation`` is the SSD Component's choice of interface (SSP 1.0: any,
    CoSimulation, ModelExchange; "any" prefers Co-Simulation when the FMU has both)."""
    path = path.resolve()
    key = (path, implementation)
    if key in _cache and _cache[key].path.stat().st_mtime == path.stat().st_mtime:
        return _cache[key]
    try:
        md = fmpy.read_model_description(str(path), validate=True)
    except Exception as e:  # fmpy raises several types for unreadable or invalid FMUs
        raise SetupError(f"cannot read the model description of {path.name}: {e}", file=file,
                         element=where) from None
    kind = _kind(md, path, implementation, where, file)
    if not md.guid or not md.guid.strip():
        raise SetupError(f"{path.name} has an empty GUID in its modelDescription.xml; an FMU without a GUID "
                         "cannot be instantiated.", file=file, element=where)
    variables = {v.name: v for v in md.modelVariables}
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    deps: dict[str, list[str]] = {}
    for unknown in md.outputs:
        if unknown.dependencies is None:
            deps[unknown.variable.name] = list(inputs)
        else:
            deps[unknown.variable.name] = [d.name for d in unknown.dependencies if d.causality == "input"]
    for v in md.modelVariables:
        if v.causality == "output" and v.name not in deps:
            deps[v.name] = list(inputs)
    desc = FMUDescription(path=path, md=md, variables=variables, output_dependencies=deps, kind=kind)
    _cache[key] = desc
    return desc


def _kind(md: ModelDescription, path: Path, implementation: str, where: str, file: str) -> str:
    """The interface the master drives: the SSD's ``implementation`` if the FMU has it, else
    Co-Simulation when present, else Model Exchange (FMI 2.0 only)."""
    if implementation not in IMPLEMENTATIONS:
        raise SetupError(f"implementation='{implementation}' is not one of {', '.join(IMPLEMENTATIONS)} "
                         "(SSP 1.0 Component).", file=file, element=where)
    if md.fmiVersion not in ("2.0", "3.0"):
        raise SetupError(f"{path.name} is an FMI {md.fmiVersion} FMU; this master runs FMI 2.0 and 3.0 FMUs.",
                         file=file, element=where)
    has_cs, has_me = md.coSimulation is not None, md.modelExchange is not None
    if implementation == "CoSimulation" and not has_cs:
        raise SetupError(f"implementation='CoSimulation' but {path.name} has no Co-Simulation interface.",
                         file=file, element=where)
    if implementation == "ModelExchange" and not has_me:
        raise SetupError(f"implementation='ModelExchange' but {path.name} has no Model Exchange interface.",
                         file=file, element=where)
    use_me = implementation == "ModelExchange" or (implementation == "any" and not has_cs)
    if md.fmiVersion == "3.0":
        if use_me:
            raise SetupError(f"{path.name} would run through its FMI 3.0 Model Exchange interface; this master "
                             "hosts Model Exchange FMUs of FMI 2.0 and FMI 3.0 Co-Simulation FMUs.",
                             file=file, element=where)
        return "fmi3-cs"
    return "fmi2-me" if use_me else "fmi2-cs"


def open_instance(name: str, desc: FMUDescription, unzip_dir: str, solver=None) -> "Instance":
    """The live instance for ``desc.kind`` (not yet instantiated); ``solver`` is the component's
    ``org.greyfmu.solver`` options (`cosim.structure.SolverOptions`) for a Model Exchange FMU."""
    if desc.kind == "fmi3-cs":
        from .fmi3 import FMI3Instance
        return FMI3Instance(name, desc, unzip_dir)
    if desc.kind == "fmi2-me":
        from .me import MEInstance
        return MEInstance(name, desc, unzip_dir, solver)
    return Instance(name, desc, unzip_dir)


def unit_of(v: ModelVariable) -> str | None:
    if v.unit:
        return v.unit
    return v.declaredType.unit if v.declaredType is not None and v.declaredType.unit else None


#: Log messages by instance name.  fmpy's native logger proxy (which formats the printf
#: arguments) keeps one Python logger for the whole process, so one logger dispatches, and
#: passes messages of instances that are not ours to fmpy's default printer.
_LOG_TARGETS: dict[str, collections.deque] = {}
_CALLBACKS: list[fmi2CallbackFunctions] = []


def log_line(status: int, category: bytes | None, message: bytes | None) -> str:
    """One FMU log message as the master keeps it: ``[Status] category: text``."""
    text = message.decode("utf-8", "replace") if message else ""
    cat = category.decode("utf-8", "replace") if category else ""
    return f"[{STATUS.get(status, status)}] {cat}: {text}".strip()


def _log(env, instance_name, status, category, message) -> None:
    name = instance_name.decode("utf-8", "replace") if instance_name else ""
    target = _LOG_TARGETS.get(name)
    if target is not None:
        target.append(log_line(status, category, message))
    else:  # an FMU run by plain fmpy in the same process: fmpy's own default (print)
        printLogMessage(env, instance_name, status, category, message)


def _callbacks() -> fmi2CallbackFunctions:
    """The process-wide FMI callbacks, created once and kept alive for every instance."""
    if not _CALLBACKS:
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(_log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(callbacks))
        except OSError:  # no native proxy for this platform: messages arrive unformatted
            pass
        _CALLBACKS.append(callbacks)
    return _CALLBACKS[0]


class InstanceBase:
    """What every instance kind keeps besides its FMI functions: its name and description, the
    last log messages of its FMU (to explain a failure), the component handle and the status
    it failed with; and how logging is turned on (``fmu_log``, see `Instance.instantiate`)."""

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
        status_categories = [c.name for c in self.desc.md.logCategories if c.name.startswith("logStatus")]
        if fmu_log == "errors" and status_categories:
            self.slave.setDebugLogging(True, status_categories)

    def last_messages(self) -> str:
        return (" FMU log: " + " | ".join(self.messages)) if self.messages else ""


class Instance(InstanceBase):
    """One live FMI 2.0 Co-Simulation instance with raw FMI functions for the hot loop.

    The interface every instance kind offers the execution:

    * ``do_step(component, t, h, no_prior_state) -> status`` and, per exchange type
      ("Real", "Integer", "Boolean", "String"), ``get[type](component, vrs, n, values) -> status``
      and ``set[type](...)``: called with ctypes arrays of value references and values
      (c_double for Real, c_int for Integer and Boolean, char* for String, as fmi2 declares them);
    * ``component`` (the handle passed back to those calls), ``failed`` (the FMI status name
      after an Error/Fatal, else None), ``messages``;
    * ``instantiate``, ``setup_experiment``, ``set_start``, ``enter_initialization_mode``,
      ``exit_initialization_mode``, ``free`` (these raise on a status above Warning).
    """

    #: fmpy's class for the FMI 2.0 interface the instance drives
    interface = FMU2Slave

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str):
        super().__init__(name, desc)
        md = desc.md
        self.slave = self.interface(guid=md.guid, unzipDirectory=unzip_dir,
                                    modelIdentifier=desc.model_identifier, instanceName=name)
        _LOG_TARGETS[name] = self.messages
        raw = self.slave._functions
        if "fmi2DoStep" in raw:  # Co-Simulation; a Model Exchange instance steps by its own method
            self.do_step = raw["fmi2DoStep"]
        self.get = {"Real": raw["fmi2GetReal"], "Integer": raw["fmi2GetInteger"],
                    "Boolean": raw["fmi2GetBoolean"], "String": raw["fmi2GetString"]}
        self.set = {"Real": raw["fmi2SetReal"], "Integer": raw["fmi2SetInteger"],
                    "Boolean": raw["fmi2SetBoolean"], "String": raw["fmi2SetString"]}

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
            raise SetupError(f"fmi2Instantiate failed for {self.desc.path.name} (GUID {self.desc.md.guid}): {e}."
                             + self.last_messages(), element=f"component '{self.name}'") from None
        self.component = self.slave.component
        self.restrict_logging(fmu_log)

    def setup_experiment(self, start: float, stop: float) -> None:
        self.slave.setupExperiment(startTime=start, stopTime=stop)

    def set_start(self, variable: ModelVariable, value: float | int | bool | str) -> None:
        """Set a parameter or start value before initialisation (FMI 2.0 §2.2.7)."""
        vr = [variable.valueReference]
        if variable.type == "String":
            self.slave.setString(vr, [str(value).encode()])
        else:
            {"Real": self.slave.setReal, "Integer": self.slave.setInteger,
             "Boolean": self.slave.setBoolean}[variable.type](vr, [value])

    def enter_initialization_mode(self) -> None:
        self.slave.enterInitializationMode()

    def exit_initialization_mode(self) -> None:
        self.slave.exitInitializationMode()

    def free(self) -> None:
        end_instance(self, lambda: self.slave.fmi2FreeInstance(self.component))
        if _LOG_TARGETS.get(self.name) is self.messages:
            del _LOG_TARGETS[self.name]


def end_instance(inst, free_instance) -> None:
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
        release_pythonfmu_state(inst.slave.dll)
        inst.slave.freeLibrary()
    inst.component = None
    resources = os.path.join(inst.slave.unzipDirectory, "resources")
    sys.path[:] = [entry for entry in sys.path if os.path.normpath(entry) != os.path.normpath(resources)]


def release_pythonfmu_state(library: ctypes.CDLL) -> bool:
    """Empty the interpreter state a pythonfmu 0.7.0 library keeps, before it is unloaded.

    Such a library keeps its state in a static ``std::shared_ptr`` that the C++ runtime
    destroys when the library is unloaded (or at exit) and that the library's
    ``__attribute__((destructor))`` then assigns ``nullptr`` again (pythonfmu-export
    ``PySlaveInstance.cpp``, ``onLibraryUnload``): the second release writes into freed
    memory, and glibc aborts the process with "corrupted double-linked list" when that memory
    was reused (seen here in test runs and ``fmpy simulate`` processes).  Calling the
    library's exported ``finalizePythonInterpreter`` first empties the pointer, so both later
    releases are no-ops.  In a Python host the state holds nothing an instance still uses
    (the next instantiation makes a new one).  Returns whether the library is such a one.
    """
    release = getattr(library, "finalizePythonInterpreter", None)
    if release is None:
        return False
    release()
    return True


def release_pythonfmu_libraries() -> list[str]:
    """At exit: `release_pythonfmu_state` for every pythonfmu library still loaded (found
    in /proc/self/maps and opened with RTLD_NOLOAD, so nothing new is loaded)."""
    released: list[str] = []
    try:
        maps = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return released
    for line in maps:
        parts = line.split(None, 5)
        path = parts[5].strip().removesuffix(" (deleted)") if len(parts) == 6 else ""
        if not path.endswith(".so") or path in released:
            continue
        try:
            library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD)
        except OSError:
            continue
        if release_pythonfmu_state(library):
            released.append(path)
    return released


if sys.platform.startswith("linux"):
    atexit.register(release_pythonfmu_libraries)


class Unzipped:
    """Extracts each FMU file once per process (keyed by path, size and mtime), so repeated
    runs of the same system (tests, sweeps, benchmarks) do not unzip again.  FMUs are
    archives from elsewhere: `cosim.safeio.extract_archive` checks member names, the
    compression ratio and the expanded size (the `--max-unpacked` limit) as it extracts."""

    _tmp: tempfile.TemporaryDirectory | None = None
    _dirs: dict[tuple, str] = {}

    def __call__(self, path: Path) -> str:
        path = path.resolve()
        stat = path.stat()
        key = (path, stat.st_size, stat.st_mtime_ns)
        if key not in Unzipped._dirs:
            if Unzipped._tmp is None:
                Unzipped._tmp = tempfile.TemporaryDirectory(prefix="cosim-fmu-")
            target = Path(Unzipped._tmp.name) / str(len(Unzipped._dirs))
            target.mkdir()
            extract_archive(path, target, required="modelDescription.xml")  # size, names, ratio checked
            Unzipped._dirs[key] = str(target)
        return Unzipped._dirs[key]
