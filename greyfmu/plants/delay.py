"""Exact transport delay of a piecewise-constant (zero-order-hold) signal."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator


class DelayLine:
    """History of a piecewise-constant signal as breakpoints ``(t_i, u_i)``: u = u_i on ``[t_i, t_{i+1})``.

    ``segments(t, h, delay)`` splits ``[t, t + h]`` at the instants ``t_i + delay`` where the
    delayed signal ``u(s − delay)`` switches, so a plant can integrate each piece exactly:
    no interpolation, no dependence on the caller's step.  Before the first breakpoint
    the signal is ``initial`` (for a plant, the input that holds its initial equilibrium).
    """

    def __init__(self, initial: float) -> None:
        if not math.isfinite(initial):
            raise ValueError(f"DelayLine: initial value must be finite, got {initial}")
        self.initial = initial
        self._breakpoints: deque[tuple[float, float]] = deque([(-math.inf, initial)])

    def push(self, t: float, value: float) -> None:
        """Record that the signal holds ``value`` from time ``t`` on (t never decreases)."""
        if not math.isfinite(value):
            raise ValueError(f"DelayLine: value at t = {t} must be finite, got {value}")
        last_time, last_value = self._breakpoints[-1]
        if t < last_time:
            raise ValueError(f"DelayLine: time went backwards, got t = {t} after t = {last_time}")
        if value == last_value:
            return
        if t == last_time:
            self._breakpoints.pop()
        self._breakpoints.append((t, value))

    def segments(self, t: float, h: float, delay: float) -> Iterator[tuple[float, float]]:
        """Pieces ``(duration, value)`` of the delayed signal ``u(s − delay)`` over ``s ∈ [t, t + h]``, in order."""
        end = t + h
        breakpoints = iter(self._breakpoints)
        _, value = next(breakpoints)
        start = t
        for time, next_value in breakpoints:
            switch = time + delay
            if switch <= t:
                value = next_value
                continue
            if switch >= end:
                break
            yield switch - start, value
            start, value = switch, next_value
        yield end - start, value

    def prune(self, t: float, delay: float) -> None:
        """Forget breakpoints no longer needed to evaluate ``u(s − delay)`` for ``s >= t``."""
        while len(self._breakpoints) > 1 and self._breakpoints[1][0] + delay <= t:
            self._breakpoints.popleft()

    def __len__(self) -> int:
        """Number of breakpoints held (the initial value counts as one)."""
        return len(self._breakpoints)

    def reset(self) -> None:
        self._breakpoints = deque([(-math.inf, self.initial)])
