"""What a tuning measures on each run: objective terms and constraints, from the metrics
`cosim metrics` computes per event (`cosim.present.metrics.find_events`, `event_metrics`) or from a
Python callable on the result.

A metric term is ``[WEIGHT*]METRIC:SIGNAL[:SETPOINT][@EVENTS]``:

- METRIC one of IAE, ISE, ITAE, overshoot, rise_time, settling_time, peak_error (`EVENT_METRICS`);
- SIGNAL the controlled variable, SETPOINT the signal it follows (default: the set-point of
  SIGNAL's control loop, found as the report finds its loops: `cosim.present.plots.default_panels`);
- EVENTS which events count: ``all`` (default), ``set-point``, ``disturbance`` or an event's
  number as ``cosim metrics`` prints it (1 = the first);
- over several events the integrals (IAE, ISE, ITAE) are summed, each from its own event's
  start; overshoot and rise time are the largest over the set-point events, settling time and
  |peak error| the largest over all selected events (the worst event decides).

A constraint is a term (no weight) with a bound: ``overshoot:plant.y<=10%``,
``settling_time:plant.y<60s``, ``rise_time:plant.y>=2``.  ``%`` is allowed for the overshoot,
``s`` for the times.  `Measurement` runs in the worker (`cosim.sweep.dispatch.Task.measure`)
and returns one column per term: its value, or None with the reason in ``measure_error``.
"""
from __future__ import annotations

import math
import pickle
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..present.metrics import EVENT_METRICS, event_metrics, find_events

#: event selections besides an event's number
SELECTIONS = ("all", "set-point", "disturbance")
#: metrics an event of a disturbance does not have (`cosim.present.metrics.event_metrics`)
SETPOINT_ONLY = ("overshoot", "rise_time")
INTEGRALS = ("IAE", "ISE", "ITAE")
#: the column of a run's row (and of the tuning table) that says why a term has no value
ERROR_COLUMN = "measure_error"
_TERM = re.compile(r"^\s*(?:(?P<weight>[-+0-9.eE]+)\s*\*\s*)?(?P<metric>[A-Za-z_]+)\s*:\s*(?P<signal>[^:@<>=\s]+)"
                   r"(?:\s*:\s*(?P<setpoint>[^:@<>=\s]+))?(?:\s*@\s*(?P<events>[-\w]+))?\s*$")
_BOUND = re.compile(r"^(?P<term>.*?)\s*(?P<op><=|>=|<|>)\s*(?P<value>[-+0-9.eE]+)\s*(?P<unit>%|s)?\s*$")


@dataclass(frozen=True)
class MetricTerm:
    """METRIC of SIGNAL following SETPOINT over EVENTS (see the module docstring)."""
    metric: str
    signal: str
    setpoint: str | None = None
    events: str = "all"

    @property
    def name(self) -> str:
        """The term's column name: ``ITAE:plant.y`` (``@1`` etc. when not all events)."""
        return f"{self.metric}:{self.signal}" + ("" if self.events == "all" else f"@{self.events}")

    def measure(self, result: np.ndarray, disturbances: Sequence[str], band: float) -> tuple[float, str]:
        """The term's value on ``result``, or NaN and why not."""
        time, r = result["time"], result[self.setpoint]
        events = find_events(time, (self.setpoint, r), {d: result[d] for d in disturbances})
        rows = event_metrics(time, result[self.signal], r, events, band=band)
        chosen = [(i, ev, row) for i, (ev, row) in enumerate(zip(events, rows), 1) if self._selects(i, ev.kind)]
        if self.metric in SETPOINT_ONLY:
            chosen = [c for c in chosen if c[1].kind == "set-point"]
        if not chosen:
            return math.nan, (f"{self.name}: the run has no such event ({len(events)} event(s): "
                              + ", ".join(ev.describe() for ev in events) + ")")
        for i, ev, row in chosen:
            value = row.values[self.metric]
            if value != value:
                why = row.undefined.get(self.metric, "undefined")
                return math.nan, f"{self.name}: undefined in event {i} ({ev.describe()}): {why}"
        values = [row.values[self.metric] for _, _, row in chosen]
        if self.metric in INTEGRALS:
            return float(sum(values)), ""
        if self.metric == "peak_error":
            return float(max(abs(v) for v in values)), ""
        return float(max(values)), ""

    def _selects(self, number: int, kind: str) -> bool:
        if self.events == "all":
            return True
        if self.events in ("set-point", "disturbance"):
            return kind == self.events
        return number == int(self.events)


@dataclass(frozen=True)
class CallableTerm:
    """A Python callable on the run's result (a NumPy structured array: ``time`` and every
    recorded signal by name) returning a number; it runs in the worker, so it must pickle
    (a module-level function; with cloudpickle installed, any function)."""
    function: Callable[[np.ndarray], float]
    label: str = ""

    @property
    def name(self) -> str:
        return self.label or getattr(self.function, "__name__", "objective")

    def measure(self, result: np.ndarray, disturbances: Sequence[str], band: float) -> tuple[float, str]:
        value = float(self.function(result))
        return (value, "") if math.isfinite(value) else (math.nan, f"{self.name} returned {value}")


Term = MetricTerm | CallableTerm


@dataclass(frozen=True)
class Constraint:
    """``term <= upper`` and/or ``term >= lower``."""
    term: Term
    upper: float = math.inf
    lower: float = -math.inf

    @property
    def name(self) -> str:
        return self.term.name

    def text(self) -> str:
        bounds = ([f">= {self.lower:g}"] if self.lower > -math.inf else []) + \
                 ([f"<= {self.upper:g}"] if self.upper < math.inf else [])
        return f"{self.name} {' and '.join(bounds)}"

    def violation(self, value: float) -> float:
        """How far ``value`` is outside the bounds (0 inside; inf for a missing value)."""
        if value != value:
            return math.inf
        return max(self.lower - value, 0.0) + max(value - self.upper, 0.0)


def _weight(text: str | None, source: str) -> float:
    if text is None:
        return 1.0
    try:
        weight = float(text)
    except ValueError:
        weight = math.nan
    if not math.isfinite(weight) or weight <= 0:
        raise SetupError(f"the weight '{text}' of '{source}' is not a positive number.", element="--objective")
    return weight


def parse_term(text: str, element: str = "--objective") -> tuple[float, MetricTerm]:
    """``[WEIGHT*]METRIC:SIGNAL[:SETPOINT][@EVENTS]`` -> (weight, term)."""
    match = _TERM.match(text)
    if not match:
        raise SetupError(f"'{text}' is not [WEIGHT*]METRIC:SIGNAL[:SETPOINT][@EVENTS] (e.g. ITAE:plant.y, "
                         "0.5*overshoot:plant.y:setpoint.y@1, settling_time:plant.y@disturbance).", element=element)
    metric = match["metric"]
    if metric not in EVENT_METRICS:
        lower = {m.lower(): m for m in EVENT_METRICS}
        if metric.lower() not in lower:
            raise SetupError(f"unknown metric '{metric}' in '{text}'; the metrics are {', '.join(EVENT_METRICS)}.",
                             element=element)
        metric = lower[metric.lower()]
    events = match["events"] or "all"
    if events not in SELECTIONS and not (events.isdigit() and int(events) >= 1):
        raise SetupError(f"'@{events}' in '{text}' selects no events: give @all, @set-point, @disturbance or an "
                         "event's number (1 = the first, as cosim metrics prints them).", element=element)
    if match["weight"] is not None and element != "--objective":
        raise SetupError(f"'{text}': a constraint has no weight.", element=element)
    return _weight(match["weight"], text), MetricTerm(metric, match["signal"], match["setpoint"], events)


def parse_constraint(text: str) -> Constraint:
    """``TERM<=BOUND``, ``TERM>=BOUND`` (``<``, ``>`` the same), BOUND a number, ``%`` allowed for
    the overshoot and ``s`` for the times."""
    match = _BOUND.match(text)
    if not match:
        raise SetupError(f"'{text}' is not METRIC:SIGNAL[:SETPOINT][@EVENTS]<=BOUND or >=BOUND (e.g. "
                         "'overshoot:plant.y<=10%', 'settling_time:plant.y<=60s').", element="--constraint")
    _, term = parse_term(match["term"], "--constraint")
    unit = match["unit"]
    if unit == "%" and term.metric != "overshoot" or unit == "s" and term.metric not in ("rise_time", "settling_time"):
        raise SetupError(f"'{text}': {term.metric} is not measured in {unit} ('%' goes with overshoot, 's' with "
                         "rise_time and settling_time).", element="--constraint")
    try:
        bound = float(match["value"])
    except ValueError:
        bound = math.nan
    if not math.isfinite(bound):
        raise SetupError(f"'{text}': the bound is not a finite number.", element="--constraint")
    return Constraint(term, upper=bound) if match["op"].startswith("<") else Constraint(term, lower=bound)


def resolve_setpoints(terms: Sequence[Term], loops: Sequence[Sequence[str]], recorded: Sequence[str],
                      element: str) -> list[Term]:
    """Each metric term with its set-point named (the loop of its signal when not given) and its
    signals checked to be recorded."""
    from ..errors import did_you_mean

    out = []
    for term in terms:
        if isinstance(term, MetricTerm):
            if term.setpoint is None:
                found = [sp for sp, measured in loops if measured == term.signal]
                if not found:
                    pairs = ", ".join(f"{m} following {sp}" for sp, m in loops) or "none"
                    raise SetupError(f"'{term.name}': {term.signal} is the controlled variable of no control loop "
                                     f"found (loops: {pairs}); name its set-point: {term.metric}:{term.signal}:SETPOINT.",
                                     element=element, variable=term.signal)
                term = MetricTerm(term.metric, term.signal, found[0], term.events)
            for name in (term.signal, term.setpoint):
                if name not in recorded:
                    raise SetupError(f"no recorded signal '{name}' (signals are the components' connectors).",
                                     element=element, variable=name, hint=did_you_mean(name, recorded))
        out.append(term)
    return out


@dataclass(frozen=True)
class Measurement:
    """Every term a tuning needs, measured in the worker on one run's result (`__call__`)."""
    terms: tuple[Term, ...]
    disturbances: tuple[str, ...] = ()
    band: float = 0.02
    #: the run's stop time: a result ending before it (an FMU that terminated the run) is refused
    stop: float = math.inf
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(dict.fromkeys(t.name for t in self.terms)))

    def __call__(self, result: np.ndarray | None) -> dict[str, float | str | None]:
        out: dict[str, float | str | None] = dict.fromkeys(self.names)
        if result is None:
            return {**out, ERROR_COLUMN: "the run failed"}
        if not len(result) or result["time"][-1] < self.stop - 1e-9 * max(1.0, abs(self.stop)):
            end = f"{result['time'][-1]:g} s" if len(result) else "its start"
            return {**out, ERROR_COLUMN: f"the run ended at {end}, before the stop time {self.stop:g} s"}
        reasons = []
        for term in self.terms:
            if out[term.name] is not None:
                continue
            try:
                value, why = term.measure(result, self.disturbances, self.band)
            except Exception as e:  # noqa: BLE001 -- a user's callable: its error is the evaluation's
                value, why = math.nan, f"{term.name} raised {type(e).__name__}: {e}"
            out[term.name] = None if value != value else value
            if why:
                reasons.append(why)
        out[ERROR_COLUMN] = "; ".join(reasons) or None
        return out


def shippable(measurement: Measurement) -> Measurement:
    """``measurement`` as it can travel to a worker process: as it is when it pickles, else its
    callables by value with cloudpickle (a lambda, a function of a notebook); a `SetupError` when
    neither works."""
    try:
        pickle.dumps(measurement)
        return measurement
    except (pickle.PicklingError, AttributeError, TypeError):
        pass
    try:
        import cloudpickle
    except ImportError:
        names = [t.name for t in measurement.terms if isinstance(t, CallableTerm)]
        raise SetupError(f"the objective or constraint callable(s) {', '.join(names)} cannot be sent to the worker "
                         "processes (pickle refuses them: a lambda or a function defined in __main__ of a notebook?); "
                         "define them at module level in a file you import, install cloudpickle, or tune with "
                         "executor='serial'.", element="objective") from None
    terms = tuple(CallableTerm(ByValue(cloudpickle.dumps(t.function)), t.name) if isinstance(t, CallableTerm) else t
                  for t in measurement.terms)
    return Measurement(terms, measurement.disturbances, measurement.band, measurement.stop)


@dataclass(frozen=True)
class ByValue:
    """A callable pickled by value (cloudpickle's bytes), loaded at its first call in the worker."""
    data: bytes

    def __call__(self, result: np.ndarray) -> float:
        return pickle.loads(self.data)(result)
