"""Deterministic test signals: step, ramp and pulse train, as pure functions of time."""

from __future__ import annotations

import math

from greyfmu.signals.clock import time_reached


def _require_finite(block: str, **values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{block}: {name} must be finite, got {value}")


class Step:
    """Step from ``initial`` to ``final`` at ``t_step``; the output is ``final`` from ``t_step`` on."""

    def __init__(self, t_step: float, initial: float, final: float) -> None:
        _require_finite("Step", t_step=t_step, initial=initial, final=final)
        self.t_step = t_step
        self.initial = initial
        self.final = final

    def value(self, t: float) -> float:
        return self.final if time_reached(t, self.t_step) else self.initial


class Ramp:
    """Ramp leaving ``initial`` at ``start_time``.

    With ``final`` given, the output moves from ``initial`` toward ``final`` at ``|slope|``
    per second and stays at ``final`` once it arrives (a rate-limited set-point change);
    with ``final=None`` it is the unbounded ramp ``initial + slope·(t − start_time)``.
    """

    def __init__(self, start_time: float, slope: float, initial: float, final: float | None = None) -> None:
        _require_finite("Ramp", start_time=start_time, slope=slope, initial=initial)
        if final is not None:
            _require_finite("Ramp", final=final)
        self.start_time = start_time
        self.slope = slope
        self.initial = initial
        self.final = final

    def value(self, t: float) -> float:
        elapsed = max(0.0, t - self.start_time)
        if self.final is None:
            return self.initial + self.slope * elapsed
        travelled = abs(self.slope) * elapsed
        distance = self.final - self.initial
        if travelled >= abs(distance):
            return self.final
        return self.initial + math.copysign(travelled, distance)


class Pulse:
    """Rectangular pulses of height ``amplitude`` on top of ``offset``.

    The output is ``offset + amplitude`` on ``[start_time + n·period, start_time + n·period + width)``
    for n = 0, 1, 2, ... and ``offset`` elsewhere; ``period = 0`` gives a single pulse (n = 0).
    """

    def __init__(self, amplitude: float, start_time: float, width: float, period: float = 0.0, offset: float = 0.0) -> None:
        _require_finite("Pulse", amplitude=amplitude, start_time=start_time, width=width, period=period, offset=offset)
        if width < 0.0:
            raise ValueError(f"Pulse: width must be >= 0, got {width}")
        if period < 0.0 or (period > 0.0 and width > period):
            raise ValueError(f"Pulse: period must be 0 (single pulse) or >= width = {width}, got {period}")
        self.amplitude = amplitude
        self.start_time = start_time
        self.width = width
        self.period = period
        self.offset = offset

    def value(self, t: float) -> float:
        return self.offset + self.amplitude if self._is_high(t) else self.offset

    def _is_high(self, t: float) -> bool:
        if not time_reached(t, self.start_time):
            return False
        rising_edge = self.start_time
        if self.period > 0.0:
            n = math.floor((t - self.start_time) / self.period)
            if time_reached(t, self.start_time + (n + 1) * self.period):
                n += 1
            rising_edge = self.start_time + n * self.period
        return not time_reached(t, rising_edge + self.width)
