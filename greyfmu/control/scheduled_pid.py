"""Gain-scheduled PID: a schedule sets the gains of a `PID` at every sample (thesis §2.3, (2.6a)/(2.7a)/(2.9a))."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Generic, TypeVar

from greyfmu.control.pid import PID, DerivativeOn, IntegralMode
from greyfmu.control.scheduling import Gains

W = TypeVar("W")

logger = logging.getLogger(__name__)


class GainScheduledPID(Generic[W]):
    """``u = Kc(W)·[e + (1/Ti(W))∫e dt + Td(W)·de/dt]`` sampled at Ts (thesis (2.6a), (2.7a), (2.9a)).

    ``schedule(W) -> Gains`` is any gain schedule: a `GainSchedule` (W a float: the process
    output, a set-point or an exogenous variable) or the `ITAE` rule fed with the process
    parameters (``lambda p: itae(*p)``, W a tuple (Kp, T, τ)).

    ``step(r, y, W=W)`` is one sample k: the gains scheduled at W(k) are handed to
    ``PID.set_gains`` and the PID law runs, so the integral mode (2.10)/(2.11)/(2.12) sees
    Kc(k−1), Ti(k−1) and Kc(k), Ti(k) exactly as in `greyfmu.control.pid.integral_step`.
    The first sample's gains are also taken as the gains before it, so the bias u0 is not
    rescaled at the start.  ``anti_windup`` and ``derivative_on`` are the `PID`'s options
    (``anti_windup=False``, ``derivative_on=ERROR``: the thesis's law as written).

    Bad scheduling values: if ``schedule(W)`` refuses W (NaN, a non-positive process time
    constant, ...), the gains of the last sample are held, a warning is logged and
    ``held_samples`` counts it; the output is never NaN.  If the first sample's W is
    already refused there are no gains to hold and the ``ValueError`` propagates.
    """

    def __init__(
        self,
        schedule: Callable[[W], Gains],
        Ts: float = 1.0,
        *,
        N: float = 10.0,
        u_min: float = -math.inf,
        u_max: float = math.inf,
        du_max: float = 0.0,
        integral_mode: IntegralMode | int = IntegralMode.METHOD3,
        u0: float = 0.0,
        anti_windup: bool = True,
        derivative_on: DerivativeOn | int = DerivativeOn.MEASUREMENT,
    ) -> None:
        self.schedule = schedule
        self._pid_options = dict(N=N, u_min=u_min, u_max=u_max, du_max=du_max, integral_mode=integral_mode, u0=u0,
                                 anti_windup=anti_windup, derivative_on=derivative_on)
        PID(1.0, 1.0, 0.0, Ts, **self._pid_options)  # refuse bad options now, not at the first sample
        self.Ts = Ts
        self.u0 = u0
        self.reset()

    def reset(self) -> None:
        """Back to the state before the first sample (output u0, no gains yet)."""
        self.pid: PID | None = None
        self.gains: Gains | None = None
        self.held_samples = 0

    @property
    def u(self) -> float:
        """Controller output of the last sample (u0 before the first)."""
        return self.u0 if self.pid is None else self.pid.u

    @property
    def e(self) -> float:
        """Control error r − y at the last sample (0 before the first)."""
        return 0.0 if self.pid is None else self.pid.e

    def step(self, r: float, y: float, *, W: W) -> float:
        """One sample with set-point r, measurement y and scheduling variable W (a keyword: an extra
        measured input of the ``Controller`` protocol); returns u(k)."""
        try:
            gains = self.schedule(W)
        except ValueError as error:
            if self.gains is None:
                raise
            gains = self.gains
            self.held_samples += 1
            logger.warning("GainScheduledPID: scheduling variable refused (%s); holding Kc, Ti, Td = %s", error, gains)
        if self.pid is None:
            self.pid = PID(*gains, self.Ts, **self._pid_options)
        else:
            self.pid.set_gains(*gains)
        self.gains = gains
        return self.pid.step(r, y)
