"""Gain schedules for a PID: threshold switching, FGS1 (2.6), FGS2 (2.7), MFGS (2.9) and the ITAE rule (2.8).

Chen (1999), thesis 000_*, §2.3.1.  A schedule maps the scheduling variable W to the PID
gains (Kc, Ti, Td) from a table of operating points (W_i, Kc_i, Ti_i, Td_i), W_1 < ... < W_n.
Between two neighbouring points W_i < W < W_{i+1}, with q2 = (W − W_i)/(W_{i+1} − W_i) and
q1 = 1 − q2 ((2.6e) = (2.7e) = (2.9e)):

- FGS1 (2.6): Kc = q1·Kc_i + q2·Kc_{i+1}; Kc/Ti and Kc·Td are interpolated linearly
  (the integral and derivative gains), Ti and Td follow from them.
- FGS2 (2.7): Kc, Ti and Td are each interpolated linearly.
- MFGS (2.9): 1/Kc is interpolated linearly; Ti and Td as FGS2.
- THRESHOLD: the gains of W_i below the threshold W*_i, of W_{i+1} above it (§2.3.1's
  switching; the default threshold is the midpoint).

The thesis writes two points; any number n >= 1 works here (one point = fixed gains).
W outside [W_1, W_n] is clamped to the table's range.

ITAE (2.8) is the reference the chapter compares them against: the gains computed from the
process's current gain Kp, dead time τ and time constant T.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple


class Gains(NamedTuple):
    """PID gains: controller gain Kc, integral time Ti, derivative time Td."""

    Kc: float
    Ti: float
    Td: float


class Interpolation(IntEnum):
    """How a schedule computes the gains between two operating points (thesis §2.3.1)."""

    THRESHOLD = 0
    """Switch from the gains of W_i to those of W_{i+1} at the threshold W*_i."""
    FGS1 = 1
    """(2.6): Kc, Kc/Ti and Kc·Td linear in W."""
    FGS2 = 2
    """(2.7): Kc, Ti and Td linear in W."""
    MFGS = 3
    """(2.9): 1/Kc, Ti and Td linear in W."""


@dataclass(frozen=True)
class OperatingPoint:
    """PID gains designed at the scheduling value W."""

    W: float
    Kc: float
    Ti: float
    Td: float = 0.0


class ScheduleError(ValueError):
    """An operating-point table or threshold that cannot define a schedule."""


def _check_point(index: int, point: OperatingPoint) -> None:
    n = index + 1
    if not math.isfinite(point.W):
        raise ScheduleError(f"operating point {n}: W_{n} must be finite, got {point.W}")
    if not (math.isfinite(point.Kc) and point.Kc != 0.0):
        raise ScheduleError(f"operating point {n}: Kc_{n} must be a finite nonzero number, got {point.Kc}")
    if not (math.isfinite(point.Ti) and point.Ti > 0.0):
        raise ScheduleError(f"operating point {n}: Ti_{n} must be a finite number > 0, got {point.Ti}")
    if not (math.isfinite(point.Td) and point.Td >= 0.0):
        raise ScheduleError(f"operating point {n}: Td_{n} must be a finite number >= 0, got {point.Td}")


class GainSchedule:
    """Gains as a function of the scheduling variable W, from a table of operating points.

    ``GainSchedule(points, Interpolation.MFGS)(W) -> Gains``.  The table must be non-empty
    with strictly increasing W; the controller gains of all points must have the same sign
    (MFGS interpolates 1/Kc, which has no meaning across a sign change).  ``thresholds``
    (THRESHOLD only): the n − 1 switching values, W*_i in (W_i, W_{i+1}); default the midpoints.
    A non-finite W is refused with ``ValueError`` (the caller decides what to hold).
    """

    def __init__(
        self,
        points: Sequence[OperatingPoint],
        interpolation: Interpolation | int = Interpolation.MFGS,
        thresholds: Sequence[float] | None = None,
    ) -> None:
        points = list(points)
        if not points:
            raise ScheduleError("the operating-point table is empty: give at least one point (W, Kc, Ti, Td)")
        for index, point in enumerate(points):
            _check_point(index, point)
        for index in range(1, len(points)):
            if not points[index].W > points[index - 1].W:
                raise ScheduleError(
                    f"operating points must have strictly increasing W: W_{index + 1} = {points[index].W} "
                    f"does not exceed W_{index} = {points[index - 1].W}"
                )
        if len({math.copysign(1.0, point.Kc) for point in points}) > 1:
            raise ScheduleError("the controller gains Kc_i of the table must all have the same sign")
        self.points = tuple(points)
        self.interpolation = Interpolation(interpolation)
        self._W = [point.W for point in points]
        if thresholds is None:
            thresholds = [(a.W + b.W) / 2.0 for a, b in zip(points, points[1:])]
        thresholds = list(thresholds)
        if len(thresholds) != len(points) - 1:
            raise ScheduleError(f"{len(points)} operating points need {len(points) - 1} thresholds, got {len(thresholds)}")
        for index, (W_star, a, b) in enumerate(zip(thresholds, points, points[1:])):
            if not a.W < W_star < b.W:
                raise ScheduleError(
                    f"threshold W*_{index + 1} = {W_star} must lie strictly between W_{index + 1} = {a.W} "
                    f"and W_{index + 2} = {b.W}"
                )
        self.thresholds = tuple(thresholds)

    def bracket(self, W: float) -> tuple[int, float]:
        """Index i of the interval [W_i, W_{i+1}] holding W (clamped to the table) and q2 of (2.6e)."""
        if not math.isfinite(W):
            raise ValueError(f"scheduling variable W must be finite, got {W}")
        if len(self._W) == 1 or W <= self._W[0]:
            return 0, 0.0
        if W >= self._W[-1]:
            return len(self._W) - 2, 1.0
        i = bisect.bisect_right(self._W, W) - 1
        return i, (W - self._W[i]) / (self._W[i + 1] - self._W[i])

    def __call__(self, W: float) -> Gains:
        """The gains at the scheduling value W."""
        i, q2 = self.bracket(W)
        a = self.points[i]
        if len(self.points) == 1:
            return Gains(a.Kc, a.Ti, a.Td)
        b = self.points[i + 1]
        q1 = 1.0 - q2
        law = self.interpolation
        if law is Interpolation.THRESHOLD:
            chosen = a if W <= self.thresholds[i] else b
            return Gains(chosen.Kc, chosen.Ti, chosen.Td)
        if law is Interpolation.MFGS:
            Kc = 1.0 / (q1 / a.Kc + q2 / b.Kc)  # (2.9b)
        else:
            Kc = q1 * a.Kc + q2 * b.Kc  # (2.6b), (2.7b)
        if law is Interpolation.FGS1:
            Ti = Kc / (q1 * a.Kc / a.Ti + q2 * b.Kc / b.Ti)  # (2.6c)
            Td = (q1 * a.Kc * a.Td + q2 * b.Kc * b.Td) / Kc  # (2.6d)
        else:
            Ti = q1 * a.Ti + q2 * b.Ti  # (2.7c), (2.9c)
            Td = q1 * a.Td + q2 * b.Td  # (2.7d), (2.9d)
        return Gains(Kc, Ti, Td)


class ITAE:
    """ITAE tuning of a PID for a first-order-plus-dead-time process, thesis (2.8) after [16].

    ``ITAE()(Kp, T, tau) -> Gains`` with
    Kc = (A/Kp)·(τ/T)^(−B) (2.8b), Ti = C·τ^D·T^(1−D) (2.8c), Td = E·τ^F·T^(1−F) (2.8d),
    A = 1.357, B = 0.947, C = 1.176, D = 0.738, E = 0.381, F = 0.995.

    The chapter de-tunes the controller gain by lowering A: its Simulations 2.1, 2.4 and 2.5
    print Kc = 1.6069/Kp, 0.4709·T^0.947 and 29.8616·τ^(−0.947), all (2.8b) with A = 0.350
    (``ITAE(A=0.35)``); Simulation 2.3 prints Kc = 0.2961/Kp, i.e. A = 0.2961·0.2^0.947 = 0.0645.
    """

    def __init__(
        self,
        A: float = 1.357,
        B: float = 0.947,
        C: float = 1.176,
        D: float = 0.738,
        E: float = 0.381,
        F: float = 0.995,
    ) -> None:
        for name, value in zip("ABCDEF", (A, B, C, D, E, F)):
            if not math.isfinite(value):
                raise ValueError(f"ITAE: constant {name} must be finite, got {value}")
        if A == 0.0 or C <= 0.0 or E < 0.0:
            raise ValueError(f"ITAE: need A != 0, C > 0 and E >= 0, got A = {A}, C = {C}, E = {E}")
        self.A, self.B, self.C, self.D, self.E, self.F = A, B, C, D, E, F

    def __call__(self, Kp: float, T: float, tau: float) -> Gains:
        """The gains for process gain Kp, time constant T > 0 and dead time τ > 0."""
        if not (math.isfinite(Kp) and Kp != 0.0):
            raise ValueError(f"ITAE: process gain Kp must be a finite nonzero number, got {Kp}")
        if not (math.isfinite(T) and T > 0.0):
            raise ValueError(f"ITAE: process time constant T must be a finite number > 0, got {T}")
        if not (math.isfinite(tau) and tau > 0.0):
            raise ValueError(f"ITAE: process dead time tau must be a finite number > 0, got {tau}")
        Kc = self.A / Kp * (tau / T) ** (-self.B)
        Ti = self.C * tau**self.D * T ** (1.0 - self.D)
        Td = self.E * tau**self.F * T ** (1.0 - self.F)
        return Gains(Kc, Ti, Td)
