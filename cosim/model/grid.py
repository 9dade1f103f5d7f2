"""The communication grid of a run: t_k = t0 + k·h (computed, never accumulated); when
(stop − t0)/h is not a whole number the last step is shortened to end at stop."""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from functools import cached_property

from ..errors import SetupError

#: most communication steps of a run (10^9 steps at the fastest ~5 µs/step is over an hour)
MAX_STEPS = 10**9
#: the smallest step, in multiples of the spacing of doubles at the run's largest time
RESOLUTION_STEPS = 1024


@dataclass(frozen=True)
class Grid:
    """Start, stop and step of a run, checked: finite, stop after start, a step the doubles
    between start and stop can resolve, at most `MAX_STEPS` steps."""
    start: float
    stop: float
    step: float

    def __post_init__(self):
        if not (math.isfinite(self.step) and self.step > 0):
            raise SetupError(f"the step size must be a positive number; got {self.step}.", element="step size")
        for what, value in (("start time", self.start), ("stop time", self.stop)):
            if not math.isfinite(value):
                raise SetupError(f"the {what} must be a finite number; got {value}.", element=what)
        if self.stop <= self.start:
            raise SetupError(f"the stop time {self.stop} is not after the start time {self.start}.",
                             element="stop time")
        resolution = math.ulp(max(abs(self.start), abs(self.stop)))
        if self.step < RESOLUTION_STEPS * resolution:
            raise SetupError(f"the step size {self.step:g} s is below the time resolution at t = "
                             f"{max(abs(self.start), abs(self.stop)):g} s ({RESOLUTION_STEPS} x {resolution:g} s, "
                             "the spacing of doubles there): communication times would repeat or drift.",
                             element="step size")
        if not math.isfinite(self.stop - self.start):
            raise SetupError(f"the stop time {self.stop:g} is {self.stop - self.start} s after the start time "
                             f"{self.start:g}: the span overflows a double (at most {sys.float_info.max:g} s).",
                             element="stop time", hint="Choose a stop time nearer the start.")
        steps = (self.stop - self.start) / self.step
        if not steps <= MAX_STEPS:
            raise SetupError(f"{self.stop:g} - {self.start:g} s in steps of {self.step:g} s is {steps:.3g} "
                             f"communication steps; at most {MAX_STEPS:.0e} are run.", element="step size")

    @cached_property
    def steps(self) -> int:
        """The number of communication steps (the last one shortened to end at stop)."""
        return max(1, math.ceil((self.stop - self.start) / self.step - 1e-9))

    def time(self, k: int) -> float:
        """t_k, and stop from the last step on."""
        return self.stop if k >= self.steps else self.start + k * self.step
