"""The parameters a tuning searches: each a variable ``component.variable`` of any FMU of the
scenario (ours or another tool's), with its bounds and scale.

``controller.Kc=0.1:10:log`` searches Kc between 0.1 and 10 evenly in log10(Kc) (``lin``, the
default, evenly in Kc).  An Integer (or Enumeration) variable is searched on the integers
between its bounds (linear scale only).  The optimiser works in the scaled coordinates x
(x = value, or log10(value)); `SearchSpace.values` turns a point x into the parameter values,
each checked by the master's own validation (`cosim.parameters.check_values`: causality, type,
the FMU's min and max) at both bounds before the first run.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..model.fmu import exchange_type
from ..errors import SetupError
from ..plan.parameters import check_values, split_system_name
from ..plan.prepare import Prepared
from ..model.structure import ParameterValue

SOURCE = "cosim tune --param"
SCALES = ("lin", "log")


@dataclass(frozen=True)
class Parameter:
    """``name`` searched in [low, high] on the ``scale`` ("lin" or "log"); ``type`` the FMU
    variable's ("Real" or "Integer", filled in by `SearchSpace.of`)."""
    name: str
    low: float
    high: float
    scale: str = "lin"
    type: str = "Real"

    def text(self) -> str:
        return f"{self.name}={self.low:g}:{self.high:g}" + (":log" if self.scale == "log" else "")

    def bounds(self) -> tuple[float, float]:
        """The bounds in the optimiser's coordinate."""
        return (math.log10(self.low), math.log10(self.high)) if self.scale == "log" else (self.low, self.high)

    def value(self, x: float) -> float | int:
        """The parameter's value at coordinate ``x`` (clipped into the bounds; an Integer rounded)."""
        lo, hi = self.bounds()
        x = min(max(float(x), lo), hi)
        if self.type == "Integer":
            return int(round(x))
        return min(max(10.0 ** x, self.low), self.high) if self.scale == "log" else x

    def coordinate(self, value: float) -> float:
        return math.log10(value) if self.scale == "log" else float(value)


def parse_parameter(text: str) -> Parameter:
    """``NAME=LOW:HIGH[:log|:lin]`` -> Parameter."""
    name, sep, spec = text.partition("=")
    parts = [p.strip() for p in spec.split(":")]
    if not sep or not name.strip() or len(parts) not in (2, 3):
        raise SetupError(f"'{text}' is not NAME=LOW:HIGH[:log] (e.g. controller.Kc=0.1:10:log or "
                         "controller.Ti=1:100).", element="--param")
    scale = parts[2].lower() if len(parts) == 3 else "lin"
    try:
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise SetupError(f"'{text}': the bounds are not numbers.", element="--param", variable=name.strip()) from None
    return checked(Parameter(name.strip(), low, high, scale))


def as_parameter(name: str, spec: Parameter | Sequence) -> Parameter:
    """A Python API entry: ``(low, high)``, ``(low, high, "log")`` or a `Parameter`."""
    if isinstance(spec, Parameter):
        return checked(spec)
    if isinstance(spec, str) or len(spec) not in (2, 3):
        raise SetupError(f"give (low, high) or (low, high, 'log'), not {spec!r}.", element="parameters", variable=name)
    return checked(Parameter(name, float(spec[0]), float(spec[1]), *([str(spec[2]).lower()] if len(spec) == 3 else [])))


def checked(p: Parameter) -> Parameter:
    """``p`` with finite bounds, low < high, a known scale and, on the log scale, low > 0."""
    where = {"element": "--param", "variable": p.name}
    if p.scale not in SCALES:
        raise SetupError(f"unknown scale '{p.scale}'; give lin or log.", **where)
    if not (math.isfinite(p.low) and math.isfinite(p.high)) or not p.low < p.high:
        raise SetupError(f"the bounds {p.low:g}:{p.high:g} are not finite with LOW < HIGH.", **where)
    if p.scale == "log" and p.low <= 0:
        raise SetupError(f"a log scale needs LOW > 0 (got {p.low:g}).", **where)
    return p


@dataclass(frozen=True)
class SearchSpace:
    parameters: tuple[Parameter, ...]
    #: each parameter's value in the scenario as given (its parameter sets, start values), or None
    current: tuple[float | int | None, ...]

    @classmethod
    def of(cls, prepared: Prepared, parameters: Sequence[Parameter]) -> SearchSpace:
        """The parameters typed by their FMU variables and checked at both bounds by the master's validation."""
        if not parameters:
            raise SetupError("nothing to tune: give at least one --param NAME=LOW:HIGH.", element="--param")
        names = [p.name for p in parameters]
        if len(set(names)) != len(names):
            twice = sorted({n for n in names if names.count(n) > 1})
            raise SetupError(f"{', '.join(twice)} given twice.", element="--param")
        plan = prepared.plan
        typed, current = [], []
        starts = {f"{sv.component}.{sv.variable.name}": sv.value for sv in plan.start_values}
        for p in parameters:
            comp, var_name = split_system_name(plan.components, ParameterValue(p.name, "Real", 0.0, SOURCE, 0))
            var = plan.fmus[comp].variable(var_name, f"{SOURCE} {p.name}", "")
            kind = exchange_type(var)
            if kind not in ("Real", "Integer"):
                raise SetupError(f"{p.name} is a {var.type}; a tuning searches Real and Integer variables.",
                                 element="--param", variable=p.name)
            if kind == "Integer":
                if p.scale == "log":
                    raise SetupError(f"{p.name} is an Integer; it is searched on a linear scale (drop ':log').",
                                     element="--param", variable=p.name)
                if not (float(p.low).is_integer() and float(p.high).is_integer()):
                    raise SetupError(f"{p.name} is an Integer; give integer bounds (not {p.low:g}:{p.high:g}).",
                                     element="--param", variable=p.name)
            p = Parameter(p.name, p.low, p.high, p.scale, kind)
            check_values(plan, [ParameterValue(p.name, kind, int(v) if kind == "Integer" else float(v), SOURCE, 0)
                                for v in (p.low, p.high)])
            value = starts.get(p.name, _number(var.start))
            typed.append(p)
            current.append(value if isinstance(value, (int, float)) and p.low <= value <= p.high else None)
        return cls(tuple(typed), tuple(current))

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    def bounds(self) -> list[tuple[float, float]]:
        return [p.bounds() for p in self.parameters]

    def integrality(self) -> np.ndarray:
        return np.array([p.type == "Integer" for p in self.parameters])

    def values(self, x: Sequence[float]) -> dict[str, float | int]:
        """The parameters' values at point ``x`` (the scenario's own value exactly at its coordinate)."""
        return {p.name: v if v is not None and _near(float(xi), p) == _near(p.coordinate(v), p) else p.value(xi)
                for p, v, xi in zip(self.parameters, self.current, x)}

    def x0(self) -> np.ndarray | None:
        """The scenario's own values as a point (None unless every parameter has one within its bounds)."""
        if any(v is None for v in self.current):
            return None
        return np.array([p.coordinate(v) for p, v in zip(self.parameters, self.current)])

    def describe(self) -> Mapping[str, str]:
        return {p.name: p.text() for p in self.parameters}


def _near(x: float, p: Parameter) -> float:
    """``x`` rounded to 1e-12 of the parameter's range: the optimiser's scaling to its unit box and
    back moves a coordinate by a few ulps, which must not make the scenario's own value another point."""
    lo, hi = p.bounds()
    return round((x - lo) / (hi - lo), 12)


def _number(text: str | None) -> float | None:
    try:
        return float(text) if text is not None else None
    except ValueError:
        return None
