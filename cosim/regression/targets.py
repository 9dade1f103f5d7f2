"""Control-loop metrics as regression targets: ``{"plant.y": {"overshoot": (20, 2)}}`` asserts
that plant.y's overshoot is 20 % ± 2 — a property of the loop, not its samples.

Each signal's entry maps a metric of `cosim.present.metrics.EVENT_METRICS` (IAE, ISE, ITAE, overshoot
[%], rise_time [s], settling_time [s], peak_error) to (expected, tolerance), absolute; it may
also name ``"setpoint"`` (default: the set-point wired to the controller measuring the signal,
as the run report finds its loops, `cosim.present.plots.default_panels`), ``"event"`` (the k-th event
as ``cosim metrics`` numbers them, 1 first; default: the set-point's last change, measured to
the end of the run, as ``cosim metrics --t0`` does) and ``"band"`` (the settling band, 0.02).
A metric that cannot be measured fails, with `cosim.present.metrics.Response`'s reason.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError, did_you_mean
from ..present.metrics import EVENT_METRICS, event_metrics, find_events, step_response

OPTIONS = ("setpoint", "event", "band")


@dataclass(frozen=True)
class MetricVerdict:
    """One metric of one signal against its target."""
    signal: str
    metric: str
    expected: float
    tolerance: float
    measured: float
    window: str
    why: str = ""

    @property
    def passed(self) -> bool:
        return abs(self.measured - self.expected) <= self.tolerance

    def describe(self) -> str:
        state = "passed" if self.passed else "FAILED"
        measured = f"{self.measured:.6g}" if self.measured == self.measured else f"undefined ({self.why})"
        return (f"{self.signal} {self.metric}: {state}, measured {measured}, expected {self.expected:g} "
                f"± {self.tolerance:g} ({self.window})")


def find_setpoint(signal: str, names: list[str], metadata: Mapping) -> str:
    """The set-point of the loop that measures ``signal``, as the run report pairs them."""
    from ..present.plots import default_panels, setpoints

    marked = setpoints(metadata, names)
    for panel in default_panels(metadata, names):
        if len(panel) == 2 and panel[0] in marked and panel[1] == signal:
            return panel[0]
    raise SetupError(f"no controller in this run measures {signal}, so its set-point is unknown; name it: "
                     f"{{'{signal}': {{'setpoint': 'setpoint.y', ...}}}}.", variable=signal)


def _target(signal: str, metric: str, spec) -> tuple[float, float]:
    if metric not in EVENT_METRICS:
        raise SetupError(f"unknown metric '{metric}'; one of {', '.join(EVENT_METRICS + OPTIONS)}.",
                         variable=signal, hint=did_you_mean(metric, EVENT_METRICS + OPTIONS))
    try:
        expected, tolerance = (float(v) for v in spec)
    except (TypeError, ValueError):
        raise SetupError(f"the target of {metric} is (expected, tolerance), not {spec!r}.", variable=signal) from None
    if not (np.isfinite(expected) and tolerance >= 0):
        raise SetupError(f"the target of {metric} needs a finite expected value and a tolerance >= 0 "
                         f"({expected:g}, {tolerance:g}).", variable=signal)
    return expected, tolerance


def check_metrics(result: np.ndarray, targets: Mapping[str, Mapping], metadata: Mapping) -> list[MetricVerdict]:
    """A `MetricVerdict` per target (module docstring) on ``result`` (a run's structured array;
    ``metadata``: its JSON, which tells the loops)."""
    names = [n for n in result.dtype.names if n != "time"]
    time = np.asarray(result["time"], dtype=float)
    verdicts = []
    for signal, spec in targets.items():
        if signal not in names:
            raise SetupError("metric targets name a signal the run does not record.", variable=signal,
                             hint=did_you_mean(signal, names))
        setpoint = spec.get("setpoint") or find_setpoint(signal, names, metadata)
        if setpoint not in names:
            raise SetupError("the set-point named is not a signal of the run.", variable=setpoint,
                             hint=did_you_mean(setpoint, names))
        band = float(spec.get("band", 0.02))
        y, r = result[signal], result[setpoint]
        event = spec.get("event")
        if event is None:
            response = step_response(time, y, r, band=band)
            window = f"from the last change of {setpoint}"
        else:
            events = find_events(time, (setpoint, r))
            if not (isinstance(event, int) and 1 <= event <= len(events)):
                raise SetupError(f"event {event!r}: the run has {len(events)} event(s) of {setpoint} (1..{len(events)}).",
                                 variable=signal)
            response = event_metrics(time, y, r, events, band=band)[event - 1]
            ev = events[event - 1]
            window = f"event {event}: {ev.describe()} at {ev.t0:g} s"
        for metric, target in spec.items():
            if metric in OPTIONS:
                continue
            expected, tolerance = _target(signal, metric, target)
            why = response.undefined.get(metric, "") if metric in response.values else \
                f"{metric} is measured per event: name one with 'event': k"
            verdicts.append(MetricVerdict(signal, metric, expected, tolerance,
                                          response.values.get(metric, float("nan")), window, why))
    return verdicts
