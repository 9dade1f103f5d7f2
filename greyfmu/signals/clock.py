"""Sample instants of a sampled block, robust against floating-point drift.

A master hands a block communication points ``t0 + k*h`` computed in floating point, so
an instant that should coincide with a sample time may miss it by an ulp.  Everything
here works with integer sample indices (``t_k = t0 + k*Ts``, never accumulated) and
treats an instant closer than ``TOLERANCE`` sample periods (relative to the index for
large indices) as reached.
"""

from __future__ import annotations

import math

TOLERANCE = 1e-9
"""Fraction of a sample period (times ``max(1, |k|)``) within which an instant counts as reached."""


def _tolerance(position: float) -> float:
    return TOLERANCE * max(1.0, abs(position))


def time_reached(t: float, instant: float) -> bool:
    """True if time ``t`` is at or after ``instant``, allowing ``TOLERANCE·max(1, |instant|)`` seconds of drift."""
    return t >= instant - _tolerance(instant)


class SampleClock:
    """Sample instants ``t_k = t0 + k·Ts`` (k = 0, 1, ...) of a controller with sample time ``Ts``."""

    def __init__(self, Ts: float, t0: float = 0.0) -> None:
        if not (math.isfinite(Ts) and Ts > 0.0):
            raise ValueError(f"SampleClock: sample time Ts must be a finite number > 0, got {Ts}")
        if not math.isfinite(t0):
            raise ValueError(f"SampleClock: start time t0 must be finite, got {t0}")
        self.Ts = Ts
        self.t0 = t0

    def time(self, k: int) -> float:
        """The instant of sample ``k``."""
        return self.t0 + k * self.Ts

    def index_at(self, t: float) -> int:
        """Index of the last sample instant at or before ``t`` (negative before ``t0``)."""
        position = (t - self.t0) / self.Ts
        return math.floor(position + _tolerance(position))

    def samples_in(self, t: float, h: float) -> range:
        """Indices ``k >= 0`` of the sample instants in the interval ``[t, t + h)``."""
        return range(self._first_at_or_after(t), self._first_at_or_after(t + h))

    def _first_at_or_after(self, t: float) -> int:
        position = (t - self.t0) / self.Ts
        return max(0, math.ceil(position - _tolerance(position)))
