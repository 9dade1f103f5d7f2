"""FMI 2.0 plumbing shared by the greyfmu slaves; embedded in every FMU next to the slave module.

A slave declares its variables with ``parameter``/``input``/``output`` and implements
``build()`` (create the greyfmu objects from the parameters) and ``advance(t, h)`` (one
communication step).  This base class

- tracks the experiment's start time (``setup_experiment``) and the current time,
- re-creates the greyfmu objects when they are next used after a parameter or the start
  time was set (so outputs read during initialisation already use the parameters the
  master set, and ``exit_initialization_mode`` refuses invalid parameters),
- refuses non-finite inputs and outputs in ``do_step``: it logs a message naming the
  variable and returns an error status instead of passing NaN on,
- forwards the warnings raised in its calls (greyfmu's ``logging`` warnings and Python warnings) to
  the FMU log of the instance that raised them, as fmi2Warning (greyfmu.forwarding: routes
  installed once per process, paid only when a warning fires),
- gets, sets and serialises the FMU state (FMI 2.0 §2.1.8, fmi2GetFMUstate ... fmi2DeSerializeFMUstate):
  the whole instance but its declarations (see `GreyfmuSlave.fmu_state_attributes`), deep-copied,
  so a restored instance replays bit for bit: parameters, inputs, time, the greyfmu objects with
  their history buffers and random generators; serialised by fmus/_state.py;
- survives an exception in any call pythonfmu makes: it is said in one line of category
  `PYTHON_EXCEPTION` (the loader's guard answers fmi2Error and the instance lives on, FMI 2.0
  §2.1.3) and what pythonfmu 0.7.0 releases twice is given back (fmus/_inprocess.py);
- takes its resources folder off ``sys.path`` again and points its private package at it
  (fmus/_inprocess.py, settle_imports);
- answers ``fmi2Get*``/``fmi2Set*`` through accessors compiled once per list of value
  references (see `CompiledAccessors`), instead of pythonfmu's generic per-variable lookup;
- declares a mode parameter whose start is an ``IntEnum`` member as an FMI Integer whose range
  and description name the IntEnum's members, and refuses, when the objects are built, a value
  that is not one of them.  Not an FMI 2.0 Enumeration: libcosim 0.11.2, a peer SSP master,
  applies no ``ssv:Integer`` binding to an Enumeration variable and aborts on ``ssv:Enumeration``
  (tests/peers/test_crosscheck.py; an FMI 3.0 slave, PID3, does declare one).

Units: a physical variable declares its unit (``unit=``; dimensionless ones "1").  A generic
block's signal (PID, FOPDT, Gain, Sum, sources, tables) declares none: it takes the unit of the
signals wired to it (a gain: the output's per the input's), and documentation/index.html says
"as wired".  A declared "1" would make an importer that converts units (cosim, SSP tools)
refuse a connection to a force in N or from a kgf/cm2 output, and rescale a % signal by 0.01.
The descriptions do not say it: hosts, cosim's plots among them, label a signal with its description.
"""

from __future__ import annotations

import copy
import functools
from abc import abstractmethod
from collections.abc import Callable
from enum import IntEnum
from math import isfinite
from operator import attrgetter
from typing import Any, ClassVar
from xml.etree.ElementTree import Element

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status
from pythonfmu.variables import ScalarVariable

from _inprocess import give_back, settle_imports
from _state import state_bytes, state_from_bytes
from greyfmu.forwarding import forward_from, keep_routing

REQUIREMENTS = "Requires Python 3.10+ with numpy and scipy on the target; the greyfmu package is embedded as FMU resources."


class _TypeAttributes:
    """Writes unit/min/max on the type element, which pythonfmu 0.7.0 variables cannot express."""

    def __init__(self, name: str, *, type_attributes: dict[str, str], **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self._type_attributes = type_attributes

    def to_xml(self) -> Element:
        node = super().to_xml()
        node[0].attrib.update(self._type_attributes)
        return node


class RealVariable(_TypeAttributes, Real):
    """pythonfmu ``Real`` with optional unit, min and max."""


class IntegerVariable(_TypeAttributes, Integer):
    """pythonfmu ``Integer`` with optional min and max."""


class AntiWindup(IntEnum):
    """Anti-windup of the PI(D) controller FMUs at the output limits."""

    NONE = 0
    """None: the integral always integrates, as in the thesis's PI."""
    CONDITIONAL_INTEGRATION = 1
    """Conditional integration: the integral stops while the output is limited (ours)."""


class Estimator(IntEnum):
    """The on-line estimator of the TS models' consequents (greyfmu.control.ts_fuzzy.FuzzyRLS)."""

    GLOBAL_FRLS = 1
    """Global FRLS: one RLS on the stacked regressor, cost J_G."""
    LOCAL_FRLS = 2
    """Local FRLS (Angelov and Filev 2004): one RLS per rule weighted by its firing, cost J_L."""
    MFRLS = 3
    """Mixed FRLS, our reconstruction: a global update weighted 1 - mu_m and local updates weighted mu_m, (21) and (25)."""

    @property
    def rls_method(self) -> str:
        """The ``method`` name greyfmu.control.ts_fuzzy.FuzzyRLS takes."""
        return ("global", "local", "mixed")[self.value - 1]


def _type_attributes(unit: str | None, minimum: float | None, maximum: float | None) -> dict[str, str]:
    attributes = {"unit": unit, "min": minimum, "max": maximum}
    return {key: str(value) for key, value in attributes.items() if value is not None}


DECLARATIONS = frozenset({"_declarations", "_input_names", "_attributes", "_outputs", "_output_functions", "choices",
                          "_get_real", "_get_integer", "_get_boolean", "_get_string",
                          "_set_real", "_set_integer", "_set_boolean", "_set_string"})
"""`GreyfmuSlave`'s attributes that declare the variables (fixed after ``__init__``), not FMU state."""

_CONVERSIONS: dict[type[ScalarVariable], type] = {Real: float, Integer: int, Boolean: bool, String: str}
"""The Python type each FMI type is returned as, as pythonfmu's generic ``Fmi2Slave.get_*`` converts."""


class CompiledAccessors(dict):
    """Accessors of one FMI type, keyed by the tuple of value references of a get or set call.

    pythonfmu's C++ wrapper calls ``get_real(vrs)``/``set_real(vrs, values)`` with a fresh list
    of value references on every fmi2GetReal/fmi2SetReal; a master calls with the same few
    lists at every step, so each list's accessor is compiled once (``compile(vrs)``) and looked
    up by value afterwards.  A list that is refused raises from ``compile`` and is not stored.
    """

    def __init__(self, compile_accessor: Callable[[tuple[int, ...]], Callable]) -> None:
        super().__init__()
        self._compile = compile_accessor

    def __missing__(self, vrs: tuple[int, ...]) -> Callable:
        accessor = self[vrs] = self._compile(vrs)
        return accessor


PYTHON_EXCEPTION = "logPythonException"
"""The log category of the line that says a call raised (`GreyfmuSlave._raised`): the loader's guard
(greyfmu/loader/guard.h) then answers fmi2Error, not pythonfmu's fmi2Fatal, since the instance lives on."""

CALLED_BY_PYTHONFMU = {
    "setup_experiment": "fmi2SetupExperiment", "enter_initialization_mode": "fmi2EnterInitializationMode",
    "exit_initialization_mode": "fmi2ExitInitializationMode", "do_step": "fmi2DoStep", "terminate": "fmi2Terminate",
    **{f"{verb}_{kind}": f"fmi2{verb.capitalize()}{kind.capitalize()}" for verb in ("get", "set")
       for kind in ("real", "integer", "boolean", "string")},
    "_get_fmu_state": "fmi2GetFMUstate", "_set_fmu_state": "fmi2SetFMUstate"}
"""The methods pythonfmu 0.7.0's C++ wrapper calls on an instance, and the FMI function of each."""


def _reporting(method: Callable[..., Any], call: str) -> Callable[..., Any]:
    """A subclass's override of a method pythonfmu calls, reporting an exception as the base's methods do."""

    @functools.wraps(method)
    def reported(self: GreyfmuSlave, *args: Any) -> Any:
        try:
            return method(self, *args)
        except BaseException as error:
            self._raised(call, error)
            raise

    return reported


class GreyfmuSlave(Fmi2Slave):
    """Base of the greyfmu slaves (see the module docstring)."""

    author = "greyfmu"
    output_dependencies: ClassVar[dict[str, list[str]]]
    """For every output, the inputs it depends on at the same instant (read by ``greyfmu build``)."""
    requirements: ClassVar[tuple[str, ...]] = ("numpy", "scipy")
    """The modules the FMU imports from the target's Python: the loader checks them at
    instantiation, ``greyfmu build`` checks that the description names them."""

    fmi_calls: ClassVar[dict[str, str]] = {}
    """The FMI function named in an exception's line for each FMI 2.0 one (`_raised`): the FMI 3.0
    class (fmus/fmi3/_slave3.py) names its own."""
    log_categories = {**Fmi2Slave.log_categories,
                      PYTHON_EXCEPTION: "A Python exception in a call of the FMU's code (the call returns fmi2Error)."}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A subclass's override of a method pythonfmu calls reports its exceptions too (`_raised`)."""
        super().__init_subclass__(**kwargs)
        for name, call in CALLED_BY_PYTHONFMU.items():
            if name in cls.__dict__:
                setattr(cls, name, _reporting(cls.__dict__[name], call))

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        settle_imports(self.resources)
        self._declarations = frozenset(self.__dict__) | DECLARATIONS
        """The attributes that are not FMU state: pythonfmu's (variables, log queue, names) and
        `DECLARATIONS`; everything else, set later, is (`fmu_state_attributes`)."""
        self.experiment_start = 0.0
        self.current_time = 0.0
        self._input_names: list[str] = []
        self._attributes: dict[int, str] = {}
        """Value reference -> attribute name of the parameters and inputs (plain attributes of the slave)."""
        self._outputs: dict[int, Callable[[], float]] = {}
        """Value reference -> value function of each output, valid once the greyfmu objects are built."""
        self._output_functions: tuple[Callable[[], float], ...] = ()
        """The value functions of `_outputs`, in order: what `do_step` checks."""
        self._built = False
        self.choices: dict[str, type[IntEnum]] = {}
        """Parameter name -> the IntEnum of each mode parameter (its values checked before a build)."""
        self._get_real = CompiledAccessors(lambda vrs: self._compile_get(Real, vrs))
        self._get_integer = CompiledAccessors(lambda vrs: self._compile_get(Integer, vrs))
        self._get_boolean = CompiledAccessors(lambda vrs: self._compile_get(Boolean, vrs))
        self._get_string = CompiledAccessors(lambda vrs: self._compile_get(String, vrs))
        self._set_real = CompiledAccessors(lambda vrs: self._compile_set(Real, vrs))
        self._set_integer = CompiledAccessors(lambda vrs: self._compile_set(Integer, vrs))
        self._set_boolean = CompiledAccessors(lambda vrs: self._compile_set(Boolean, vrs))
        self._set_string = CompiledAccessors(lambda vrs: self._compile_set(String, vrs))

    def parameter(
        self,
        name: str,
        start: float | int,
        description: str,
        unit: str | None = None,
        minimum: float | None = None,
        maximum: float | None = None,
        retune: Callable[[str, float], None] | None = None,
    ) -> None:
        """Declare a parameter; an ``int`` start makes it an FMI Integer, and so does an ``IntEnum``
        member: a mode parameter, whose description gets the members (``(1 = METHOD1, ...)``) and
        whose ``minimum``/``maximum`` default to the smallest and largest value.

        Without ``retune`` it is fixed: setting it makes the next use rebuild the greyfmu
        objects.  With ``retune`` it is tunable: set during a run, ``retune(name, value)``
        applies it to the running objects; a ValueError from it refuses the value (logged as a
        warning, the old value stays; raising into pythonfmu would be fmi2Fatal).
        """
        self._claim(name)
        setattr(self, name, start)

        def setter(value: float | int) -> None:
            if retune is None or not self._built:
                setattr(self, name, value)
                self._built = False
                return
            try:
                keep_routing()
                retune(name, value)
            except ValueError as refusal:
                self.log(f"{self.instance_name}: {refusal}; {name} stays {getattr(self, name)}", Fmi2Status.warning)
                return
            setattr(self, name, value)

        declaration: dict[str, Any] = {
            "start": start,
            "description": description,
            "causality": Fmi2Causality.parameter,
            "variability": Fmi2Variability.fixed if retune is None else Fmi2Variability.tunable,
            "setter": setter,
        }
        if isinstance(start, IntEnum):
            choices = type(start)
            self.choices[name] = choices
            minimum = min(choices) if minimum is None else minimum
            maximum = max(choices) if maximum is None else maximum
            items = ", ".join(f"{member.value} = {member.name}" for member in choices)
            declaration.update(start=int(start), description=f"{description} ({items})")
            variable = IntegerVariable(name, **declaration, type_attributes=_type_attributes(None, int(minimum), int(maximum)))
        else:
            variable_type = IntegerVariable if isinstance(start, int) else RealVariable
            variable = variable_type(name, **declaration, type_attributes=_type_attributes(unit, minimum, maximum))
        self.register_variable(variable)
        self._attributes[variable.value_reference] = name

    def output_limit_parameters(self) -> None:
        """u_min, u_max, du_max: the output limits of every controller FMU (greyfmu.control.PID's)."""
        self.parameter("u_min", -1e10, "Lower output limit")
        self.parameter("u_max", 1e10, "Upper output limit")
        self.parameter("du_max", 0.0, "Output rate limit in units of u per second (0 = none)", minimum=0.0)

    def output_limits(self) -> dict[str, float]:
        """The values of `output_limit_parameters`, as keyword arguments of the greyfmu controllers."""
        return {"u_min": self.u_min, "u_max": self.u_max, "du_max": self.du_max}

    def integral_options(self) -> dict[str, float | int]:
        """The values of `integral_parameters`, as keyword arguments of the greyfmu controllers."""
        return {"integral_mode": self.integral_mode, "u0": self.u0}

    def integral_parameters(self) -> None:
        """integral_mode and u0 of the PI(D) controller FMUs: the thesis's (2.10)-(2.12)."""
        from greyfmu.control.pid import IntegralMode  # only the controller FMUs import greyfmu.control

        self.parameter("integral_mode", IntegralMode.METHOD3,
                       "Integral mode: METHOD1 = (2.10), METHOD2 = (2.11), METHOD3 = (2.12) of the thesis")
        self.parameter("u0", 0.0, "Initial output (bias): the integral starts here, so u = u0 while e = 0")

    def input(self, name: str, start: float, description: str, unit: str | None = None) -> None:
        """Declare a continuous Real input (without ``unit``: as wired, see the module docstring)."""
        self._claim(name)
        setattr(self, name, start)
        variable = RealVariable(
            name,
            start=start,
            description=description,
            causality=Fmi2Causality.input,
            variability=Fmi2Variability.continuous,
            type_attributes=_type_attributes(unit, None, None),
        )
        self.register_variable(variable)
        self._attributes[variable.value_reference] = name
        self._input_names.append(name)

    def output(
        self,
        name: str,
        description: str,
        value: Callable[[], float],
        unit: str | None = None,
        variability: Fmi2Variability = Fmi2Variability.continuous,
    ) -> None:
        """Declare a Real output computed by ``value()`` from up-to-date greyfmu objects (initial="exact";
        without ``unit``: as wired, see the module docstring)."""

        def getter() -> float:
            self._ensure_built()
            return value()

        variable = RealVariable(
            name,
            description=description,
            causality=Fmi2Causality.output,
            variability=variability,
            initial=Fmi2Initial.exact,
            getter=getter,
            type_attributes=_type_attributes(unit, None, None),
        )
        self.register_variable(variable)
        self._outputs[variable.value_reference] = value
        self._output_functions = tuple(self._outputs.values())

    @abstractmethod
    def build(self) -> None:
        """Create the greyfmu objects from the current parameters and ``self.experiment_start``."""

    @abstractmethod
    def advance(self, t: float, h: float) -> None:
        """Advance the greyfmu objects over the communication step ``[t, t + h]``."""

    # The methods pythonfmu calls (CALLED_BY_PYTHONFMU): an exception leaving one is said and
    # given back first (`_raised`); try/except costs nothing while nothing is raised.

    def setup_experiment(self, start_time: float, stop_time: float | None = None, tolerance: float | None = None) -> None:
        self.experiment_start = start_time
        self.current_time = start_time
        self._built = False

    def enter_initialization_mode(self) -> None:
        pass

    def exit_initialization_mode(self) -> None:
        try:
            self._ensure_built()
        except BaseException as error:
            self._raised("fmi2ExitInitializationMode", error)
            raise

    def terminate(self) -> None:
        pass

    def do_step(self, current_time: float, step_size: float) -> bool:
        """One communication step, the path a host takes at every step with fmi2DoStep: the inputs
        checked, the objects rebuilt if a parameter changed, the warnings' route kept in front
        (greyfmu.forwarding, one comparison), ``advance``, the outputs checked.  Nothing allocated
        but the new time (a float) and what ``advance`` allocates."""
        try:
            attributes = self.__dict__
            for name in self._input_names:  # plain attributes (`_compile_set`)
                if not isfinite(attributes[name]):
                    return self._error(f"input {name} = {attributes[name]} at t = {current_time} s is not a finite number")
            if not self._built:
                self._ensure_built()
            keep_routing()
            self.advance(current_time, step_size)
            self.current_time = current_time + step_size
            for output_value in self._output_functions:  # the objects are built: no getter's build check
                if not isfinite(output_value()):
                    return self._non_finite_output(output_value)
            return True
        except BaseException as error:
            self._raised("fmi2DoStep", error)
            raise

    # FMI get/set: the compiled accessors of `CompiledAccessors` (the C++ wrapper reads the result
    # with PyList_GetItem, so a get returns a list).

    def get_real(self, vrs: list[int]) -> list[float]:
        try:
            return self._get_real[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetReal", error)
            raise

    def get_integer(self, vrs: list[int]) -> list[int]:
        try:
            return self._get_integer[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetInteger", error)
            raise

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        try:
            return self._get_boolean[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetBoolean", error)
            raise

    def get_string(self, vrs: list[int]) -> list[str]:
        try:
            return self._get_string[tuple(vrs)]()
        except BaseException as error:
            self._raised("fmi2GetString", error)
            raise

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        try:
            self._set_real[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetReal", error)
            raise

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        try:
            self._set_integer[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetInteger", error)
            raise

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        try:
            self._set_boolean[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetBoolean", error)
            raise

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        try:
            self._set_string[tuple(vrs)](values)
        except BaseException as error:
            self._raised("fmi2SetString", error)
            raise

    def _raised(self, call: str, error: BaseException) -> None:
        """Before ``error`` leaves ``call`` for pythonfmu: one line saying it (category
        `PYTHON_EXCEPTION`) and one reference given back of each object pythonfmu releases for it
        (fmus/_inprocess.py), once per exception (an override calling the base's method raises it twice)."""
        if getattr(error, "_greyfmu_given_back", False):
            return
        try:
            error._greyfmu_given_back = True
        except AttributeError:  # an exception class with __slots__: said (and given back) again by an override
            pass
        call = self.fmi_calls.get(call, call)
        self.log(f"{self.instance_name}: {call}: {type(error).__name__}: {error}", Fmi2Status.error, PYTHON_EXCEPTION)
        give_back(self, type(self), self.log_queue)

    def _variable(self, vr: int, kind: type[ScalarVariable]) -> ScalarVariable:
        """The variable of ``vr``; a KeyError (unknown) or TypeError (another type) as Fmi2Slave's get/set raise."""
        variable = self.vars.get(vr)
        if variable is None:
            raise KeyError(f"{self.instance_name}: no variable has the value reference {vr}")
        if not isinstance(variable, kind):
            raise TypeError(f"{self.instance_name}: variable {variable.name} (value reference {vr}) "
                            f"is not of type {kind.__name__}")
        return variable

    def _compile_get(self, kind: type[ScalarVariable], vrs: tuple[int, ...]) -> Callable[[], list]:
        """``get_<kind>(vrs)`` as one closure, with the values, Python types and refusals of
        Fmi2Slave's generic get.  Parameters and inputs are plain attributes, read by one
        ``attrgetter``; outputs build the greyfmu objects once, then call their value functions."""
        variables = [self._variable(vr, kind) for vr in vrs]
        convert = _CONVERSIONS[kind]
        if vrs and all(vr in self._attributes for vr in vrs):
            read = attrgetter(*(self._attributes[vr] for vr in vrs))
            if len(vrs) == 1:
                return lambda: [convert(read(self))]
            return lambda: list(map(convert, read(self)))
        getters = tuple(self._outputs.get(vr, variable.getter) for vr, variable in zip(vrs, variables))
        if not any(vr in self._outputs for vr in vrs):
            return lambda: [convert(get()) for get in getters]
        if len(getters) == 1:  # one output: the most frequent call of a master, kept to one Python call
            (get,) = getters

            def read_one_built() -> list:
                if not self._built:
                    self._ensure_built()
                return [convert(get())]

            return read_one_built

        def read_built() -> list:
            if not self._built:
                self._ensure_built()
            return [convert(get()) for get in getters]

        return read_built

    def _compile_set(self, kind: type[ScalarVariable], vrs: tuple[int, ...]) -> Callable[[list], None]:
        """``set_<kind>(vrs, values)`` as one closure calling the setters Fmi2Slave's generic set
        calls: an input is a plain attribute (all-input lists update the instance dictionary in
        one call); a parameter's setter marks the objects for a rebuild or retunes them.  Refused
        as the generic set refuses: an unknown value reference (KeyError), another type or a
        variable without a setter, such as an output (TypeError) — here before any value is set."""
        variables = [self._variable(vr, kind) for vr in vrs]
        for vr, variable in zip(vrs, variables):
            if variable.setter is None:
                raise TypeError(f"{self.instance_name}: variable {variable.name} (value reference {vr}) has no "
                                "setter: only parameters and inputs can be set")
        if all(variable.causality == Fmi2Causality.input and vr in self._attributes
               for vr, variable in zip(vrs, variables)):
            names = tuple(self._attributes[vr] for vr in vrs)
            attributes = self.__dict__
            if len(names) == 1:
                (name,) = names
                return lambda values: attributes.__setitem__(name, values[0])
            return lambda values: attributes.update(zip(names, values))
        setters = tuple(variable.setter for variable in variables)

        def write(values: list) -> None:
            for set_value, value in zip(setters, values):
                set_value(value)

        return write

    # FMU state (FMI 2.0 §2.1.8).  pythonfmu 0.7.0's C++ wrapper keeps the object `_get_fmu_state`
    # returns as the fmi2FMUstate and passes it back to `_set_fmu_state`; the loader's guard
    # (greyfmu/loader/guard.h) serialises it with the class's `_fmu_state_to_bytes` and
    # `_fmu_state_from_bytes` (fmus/_state.py), whose exceptions it answers with fmi2Error.

    def fmu_state_attributes(self) -> dict[str, Any]:
        """The instance's state: every attribute but the declarations (``_declarations``)."""
        return {name: value for name, value in self.__dict__.items() if name not in self._declarations}

    def _get_fmu_state(self) -> dict[str, Any]:
        """A deep copy of the state, tagged with the model's name (fmi2GetFMUstate)."""
        try:
            return {"model": type(self).__name__, "attributes": copy.deepcopy(self.fmu_state_attributes())}
        except BaseException as error:
            self._raised("fmi2GetFMUstate", error)
            raise

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore ``state`` (fmi2SetFMUstate): a deep copy of it, so it can be restored again.
        A state of another model is refused (ValueError)."""
        try:
            model = state.get("model") if isinstance(state, dict) else None
            if model != type(self).__name__:
                raise ValueError(f"fmi2SetFMUstate got a state of {model!r}, not of {type(self).__name__}")
            for name in set(self.fmu_state_attributes()) - set(state["attributes"]):
                delattr(self, name)
            self.__dict__.update(copy.deepcopy(state["attributes"]))
        except BaseException as error:
            self._raised("fmi2SetFMUstate", error)
            raise

    @classmethod
    def _fmu_state_to_bytes(cls, state: dict[str, Any]) -> bytes:
        """The serialised state (fmi2SerializeFMUstate, fmus/_state.py)."""
        return state_bytes(state, cls.__module__.rpartition(".")[2])

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes) -> dict[str, Any]:
        """The state `_fmu_state_to_bytes` wrote (fmi2DeSerializeFMUstate); ValueError saying why if
        the bytes are not one."""
        return state_from_bytes(data, cls.__name__, cls.__module__.rpartition(".")[2])

    def _claim(self, name: str) -> None:
        if hasattr(self, name):
            raise ValueError(f"{type(self).__name__}: variable name {name!r} collides with an attribute of the slave")

    def _ensure_built(self) -> None:
        """Build from the current parameters; invalid parameters raise a ValueError "invalid
        parameters: <greyfmu's message naming the parameter>", which the calling method says
        (`_raised`) and the loader's guard answers with fmi2Error."""
        if not self._built:
            try:
                self._check_choices()
                keep_routing()
                self.build()
            except (ValueError, ArithmeticError) as error:
                raise ValueError(f"invalid parameters: {error}") from error
            self._built = True

    def _check_choices(self) -> None:
        """Refuse an Enumeration parameter whose value is not one of its items (ValueError naming it)."""
        for name, choices in self.choices.items():
            value = getattr(self, name)
            if value not in set(choices):
                items = ", ".join(f"{member.value} = {member.name}" for member in choices)
                raise ValueError(f"{name} = {value} is not an item of {choices.__name__} ({items})")

    def forward_warning(self, message: str) -> None:
        """A greyfmu warning raised in one of this instance's calls (greyfmu.forwarding): an fmi2Warning in its FMU log."""
        self.log(f"{self.instance_name}: {message}", Fmi2Status.warning)

    def _error(self, message: str) -> bool:
        self.log(f"{self.instance_name}: {message}", Fmi2Status.error)
        return False

    def _non_finite_output(self, output_value: Callable[[], float]) -> bool:
        """The error of `do_step` for the output ``output_value`` computes (not a finite number)."""
        vr = next(vr for vr, value in self._outputs.items() if value is output_value)
        return self._error(f"output {self.vars[vr].name} = {output_value()} at t = {self.current_time} s "
                           "is not a finite number")


forward_from(*(function for name, function in vars(GreyfmuSlave).items() if name in CALLED_BY_PYTHONFMU),
             GreyfmuSlave._ensure_built, _reporting(GreyfmuSlave.do_step, "fmi2DoStep"))
"""A warning raised in a call pythonfmu makes (the base's methods, a subclass's override wrapped by
`_reporting`) or in a build reaches the instance's FMU log (`GreyfmuSlave.forward_warning`)."""


class SourceSlave(GreyfmuSlave):
    """A source: output ``y = signal.value(time)`` at the FMU's current time, computed when read.

    After setup and initialisation it is ``value(t0)`` with the parameters the master set;
    after ``do_step(t, h)`` it is ``value(t + h)``.  Nothing to integrate.
    """

    output_dependencies = {"y": []}

    def source_output(self, description: str, variability: Fmi2Variability) -> None:
        """Declare the output ``y`` as the value of ``self.signal`` (set by ``build``) at the current time."""
        self.output("y", description, lambda: self.signal.value(self.current_time), variability=variability)

    def advance(self, t: float, h: float) -> None:
        """Sources are functions of time only; ``do_step`` moves ``self.current_time``."""
