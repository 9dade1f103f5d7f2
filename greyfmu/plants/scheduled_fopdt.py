"""First-order plus dead-time plant whose gain, lag and dead time move with its output, thesis (2.13).

Chen (1999), thesis 000_*, §2.3.3:

    T(y)·dx/dt + x = Kp(y)·u(t) + Kp(y)·d(t)          (2.13a)
    y(t) = x(t − τ(y(t − D)))                         (2.13b)

with D a small delay that makes the dead time's dependence on y realisable.  Each of
Kp(y), T(y), τ(y) is a `PiecewiseParameter`: constant below y_lo and above y_hi, a power
law a·(b·y + c)^n between, which covers the Situations 1–6 of §2.3.3 (linear n = 1,
above-linear and below-linear; increasing, decreasing or constant).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PiecewiseParameter:
    """``p(y) = lo`` for y <= y_lo, ``hi`` for y >= y_hi, ``a·(b·y + c)^n`` in between.

    Examples from Simulations 2.1–2.5: Kp(y) = √(y − 0.72) on (0.76, 7) is
    ``PiecewiseParameter(0.2, 2.5, 0.76, 7, a=1, b=1, c=-0.72, n=0.5)``; T(y) = −2.5641y + 21.9487
    is ``a=1, b=-2.5641, c=21.9487, n=1``; a constant 20 is ``PiecewiseParameter.constant(20)``.
    The ends need not meet the middle piece exactly (the thesis's √(7 − 0.72) = 2.506 against
    its 2.5 above y = 7).
    """

    lo: float
    hi: float
    y_lo: float
    y_hi: float
    a: float = 1.0
    b: float = 1.0
    c: float = 0.0
    n: float = 1.0

    @classmethod
    def constant(cls, value: float) -> PiecewiseParameter:
        """Situation 4: the parameter does not move with y."""
        return cls(value, value, 0.0, 0.0, a=value, b=0.0, c=1.0, n=1.0)

    def __call__(self, y: float) -> float:
        if y <= self.y_lo:
            return self.lo
        if y >= self.y_hi:
            return self.hi
        return self.a * (self.b * y + self.c) ** self.n

    def check(self, name: str, *, positive: bool, nonzero: bool = False) -> None:
        """Refuse a function that is not finite (and > 0, or nonzero) for every y; ``name`` prefixes the message."""
        values = dict(zip(("lo", "hi", "y_lo", "y_hi", "a", "b", "c", "n"), (
            self.lo, self.hi, self.y_lo, self.y_hi, self.a, self.b, self.c, self.n)))
        for key, value in values.items():
            if not math.isfinite(value):
                raise ValueError(f"{name}_{key} must be finite, got {value}")
        if self.y_lo > self.y_hi:
            raise ValueError(f"{name}_y_lo = {self.y_lo} must not exceed {name}_y_hi = {self.y_hi}")
        samples = {f"{name}_lo": self.lo, f"{name}_hi": self.hi}
        if self.y_lo < self.y_hi:
            # b·y + c is linear, so a power of it is monotone on [y_lo, y_hi]: the two ends bound it.
            for end in (self.y_lo, self.y_hi):
                base = self.b * end + self.c
                if base < 0.0 and self.n != round(self.n) or base == 0.0 and self.n < 0.0:
                    raise ValueError(
                        f"{name}(y) = {name}_a·({name}_b·y + {name}_c)^{name}_n is undefined at y = {end}: "
                        f"the base {base} needs to be positive for the power {self.n}"
                    )
                samples[f"{name}({end})"] = self.a * base**self.n
        for label, value in samples.items():
            if positive and not value > 0.0 or nonzero and value == 0.0:
                raise ValueError(f"{label} = {value} must be {'> 0' if positive else 'nonzero'}")


class _History:
    """x(s) as exponential pieces: x = target + (x_k − target)·exp(−(s − t_k)/T_k) from t_k on; x0 before the first."""

    def __init__(self, x0: float) -> None:
        self.x0 = x0
        self._times: list[float] = []
        self._pieces: list[tuple[float, float, float]] = []

    def push(self, t: float, x: float, T: float, target: float) -> None:
        self._times.append(t)
        self._pieces.append((x, T, target))

    def __call__(self, s: float) -> float:
        k = bisect.bisect_right(self._times, s) - 1
        if k < 0:
            return self.x0
        x, T, target = self._pieces[k]
        return target + (x - target) * math.exp(-(s - self._times[k]) / T)

    def prune(self, keep_from: float) -> None:
        """Forget the pieces not needed to evaluate x(s) for s >= keep_from."""
        k = bisect.bisect_right(self._times, keep_from) - 1
        if k > 0:
            del self._times[:k], self._pieces[:k]


class ScheduledFOPDT:
    """The process (2.13): ``advance(t, h, u, d)`` integrates [t, t + h] with u and d held.

    Integration: the step is cut into sub-steps of at most ``dt``.  Over a sub-step Kp and T
    are frozen at the output's value at its start and x is advanced exactly (the exponential
    ZOH solution), and the piece is kept, so x(s) is known exactly at every past instant.
    The output y(s) = x(s − τ(y(s − D))) reads that history; y(s − D) is interpolated
    linearly between the recorded outputs (or, if D is shorter than the last sub-step, the
    last recorded output is used).  With constant Kp, T, τ the result is exact whatever the
    steps; when they move, freezing them over a sub-step is a first-order error in dt
    (documented in docs/gain_scheduling.md).

    Start: x = y = y0 on all of the past (the plant is in equilibrium if u + d = y0/Kp(y0)).
    """

    def __init__(
        self,
        Kp: PiecewiseParameter,
        T: PiecewiseParameter,
        tau: PiecewiseParameter,
        y0: float = 0.0,
        D: float = 0.01,
        dt: float = 0.01,
    ) -> None:
        Kp.check("Kp", positive=False, nonzero=True)
        T.check("T", positive=True)
        tau.check("tau", positive=False)
        for name, value in (("tau_lo", tau.lo), ("tau_hi", tau.hi), ("tau(y_lo)", tau(tau.y_lo)), ("tau(y_hi)", tau(tau.y_hi))):
            if value < 0.0:
                raise ValueError(f"ScheduledFOPDT: dead time {name} = {value} must be >= 0")
        if not (math.isfinite(y0)):
            raise ValueError(f"ScheduledFOPDT: initial output y0 must be finite, got {y0}")
        if not (math.isfinite(D) and D >= 0.0):
            raise ValueError(f"ScheduledFOPDT: small delay D must be a finite number >= 0, got {D}")
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"ScheduledFOPDT: internal step dt must be a finite number > 0, got {dt}")
        self.Kp_of, self.T_of, self.tau_of = Kp, T, tau
        self.y0, self.D, self.dt = y0, D, dt
        self._tau_max = max(tau.lo, tau.hi, tau(tau.y_lo), tau(tau.y_hi))
        self.reset()

    def reset(self) -> None:
        """Back to x = y = y0 on all of the past."""
        self.t: float | None = None
        self.x = self.y0
        self._x_history = _History(self.y0)
        self._y_times: list[float] = []
        self._y_values: list[float] = []
        self.y = self.y0
        self.tau = self.tau_of(self.y0)
        self.Kp = self.Kp_of(self.y0)
        self.T = self.T_of(self.y0)

    def _y_delayed(self, s: float) -> float:
        """y(s) for a past instant s, linear between the recorded outputs (y0 before the first)."""
        times = self._y_times
        if not times or s <= times[0]:
            return self._y_values[0] if times else self.y0
        if s >= times[-1]:
            return self._y_values[-1]
        k = bisect.bisect_right(times, s) - 1
        t0, t1 = times[k], times[k + 1]
        y0, y1 = self._y_values[k], self._y_values[k + 1]
        return y0 + (y1 - y0) * (s - t0) / (t1 - t0)

    def _output(self, s: float) -> None:
        """Compute and record y(s), τ, Kp and T at the instant s (x known up to s)."""
        self.tau = self.tau_of(self._y_delayed(s - self.D))
        self.y = self._x_history(s - self.tau) if self.tau > 0.0 else self.x
        self.Kp = self.Kp_of(self.y)
        self.T = self.T_of(self.y)
        if self._y_times and s <= self._y_times[-1]:
            self._y_values[-1] = self.y
        else:
            self._y_times.append(s)
            self._y_values.append(self.y)

    def advance(self, t: float, h: float, u: float, d: float = 0.0) -> float:
        """Integrate over ``[t, t + h]`` with input u and disturbance d held from t; return y(t + h)."""
        if h < 0.0:
            raise ValueError(f"ScheduledFOPDT: step h must be >= 0, got {h}")
        if self.t is None:
            self.t = t
            self._output(t)
        n = max(1, math.ceil(h / self.dt - 1e-9))
        for j in range(n):
            s = t + h * j / n
            hs = h / n
            target = self.Kp * (u + d)
            self._x_history.push(s, self.x, self.T, target)
            self.x = target + (self.x - target) * math.exp(-hs / self.T)
            self._output(t + h * (j + 1) / n)
        self.t = t + h
        keep_from = self.t - self._tau_max - self.D - self.dt
        self._x_history.prune(keep_from)
        k = bisect.bisect_right(self._y_times, self.t - self.D - self.dt) - 1
        if k > 0:
            del self._y_times[:k], self._y_values[:k]
        return self.y
