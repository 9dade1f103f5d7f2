"""FMI 2.0 plumbing shared by the greyfmu slaves; embedded in every FMU next to the slave module.

A slave declares its variables with ``parameter``/``input``/``output`` and implements
``build()`` (create the greyfmu objects from the parameters) and ``advance(t, h)`` (one
communication step).  This base class

- tracks the experiment's start time (``setup_experiment``) and the current time,
- re-creates the greyfmu objects when they are next used after a parameter or the start
  time was set (so outputs read during initialisation already use the parameters the
  master set, and ``exit_initialization_mode`` reports invalid parameters),
- refuses non-finite inputs and outputs in ``do_step``: it logs a message naming the
  variable and returns an error status instead of passing NaN on.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar
from xml.etree.ElementTree import Element

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

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


def _type_attributes(unit: str | None, minimum: float | None, maximum: float | None) -> dict[str, str]:
    attributes = {"unit": unit, "min": minimum, "max": maximum}
    return {key: str(value) for key, value in attributes.items() if value is not None}


class GreyfmuSlave(Fmi2Slave):
    """Base of the greyfmu slaves (see the module docstring)."""

    author = "greyfmu"
    output_dependencies: ClassVar[dict[str, list[str]]]
    """For every output, the inputs it depends on at the same instant (read by ``greyfmu build``)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.experiment_start = 0.0
        self.current_time = 0.0
        self._input_names: list[str] = []
        self._output_values: dict[str, Callable[[], float]] = {}
        self._built = False

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
        """Declare a parameter; an ``int`` start makes it an FMI Integer.

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
                retune(name, value)
            except ValueError as refusal:
                self.log(f"{self.instance_name}: {refusal}; {name} stays {getattr(self, name)}", Fmi2Status.warning)
                return
            setattr(self, name, value)

        variable_type = IntegerVariable if isinstance(start, int) else RealVariable
        self.register_variable(
            variable_type(
                name,
                start=start,
                description=description,
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed if retune is None else Fmi2Variability.tunable,
                setter=setter,
                type_attributes=_type_attributes(unit, minimum, maximum),
            )
        )

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
        self.parameter(
            "integral_mode", 3, "Integral mode: 1 = (2.10), 2 = (2.11), 3 = (2.12) of the thesis", minimum=1, maximum=3
        )
        self.parameter("u0", 0.0, "Initial output (bias): the integral starts here, so u = u0 while e = 0")

    def input(self, name: str, start: float, description: str, unit: str | None = None) -> None:
        """Declare a continuous Real input."""
        self._claim(name)
        setattr(self, name, start)
        self.register_variable(
            RealVariable(
                name,
                start=start,
                description=description,
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
                type_attributes=_type_attributes(unit, None, None),
            )
        )
        self._input_names.append(name)

    def output(
        self,
        name: str,
        description: str,
        value: Callable[[], float],
        unit: str | None = None,
        variability: Fmi2Variability = Fmi2Variability.continuous,
    ) -> None:
        """Declare a Real output computed by ``value()`` from up-to-date greyfmu objects (initial="exact")."""

        def getter() -> float:
            self._ensure_built()
            return value()

        self.register_variable(
            RealVariable(
                name,
                description=description,
                causality=Fmi2Causality.output,
                variability=variability,
                initial=Fmi2Initial.exact,
                getter=getter,
                type_attributes=_type_attributes(unit, None, None),
            )
        )
        self._output_values[name] = getter

    @abstractmethod
    def build(self) -> None:
        """Create the greyfmu objects from the current parameters and ``self.experiment_start``."""

    @abstractmethod
    def advance(self, t: float, h: float) -> None:
        """Advance the greyfmu objects over the communication step ``[t, t + h]``."""

    def setup_experiment(self, start_time: float, stop_time: float | None = None, tolerance: float | None = None) -> None:
        self.experiment_start = start_time
        self.current_time = start_time
        self._built = False

    def exit_initialization_mode(self) -> None:
        self._ensure_built()

    def do_step(self, current_time: float, step_size: float) -> bool:
        for name in self._input_names:
            value = getattr(self, name)
            if not math.isfinite(value):
                return self._error(f"input {name} = {value} at t = {current_time} s is not a finite number")
        self._ensure_built()
        self.advance(current_time, step_size)
        self.current_time = current_time + step_size
        for name, output_value in self._output_values.items():
            value = output_value()
            if not math.isfinite(value):
                return self._error(f"output {name} = {value} at t = {self.current_time} s is not a finite number")
        return True

    def _claim(self, name: str) -> None:
        if hasattr(self, name):
            raise ValueError(f"{type(self).__name__}: variable name {name!r} collides with an attribute of the slave")

    def _ensure_built(self) -> None:
        """Build from the current parameters; invalid parameters are logged (status error, with the
        greyfmu message naming the parameter) before the exception, which pythonfmu turns into
        fmi2Fatal, reaches the master."""
        if not self._built:
            try:
                self.build()
            except (ValueError, ArithmeticError) as error:
                self.log(f"{self.instance_name}: invalid parameters: {error}", Fmi2Status.error)
                raise
            self._built = True

    def _error(self, message: str) -> bool:
        self.log(f"{self.instance_name}: {message}", Fmi2Status.error)
        return False


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
