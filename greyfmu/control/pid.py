"""Sampled ideal (ISA) PID with the three integral modes of the thesis, §2.3.2, (2.10)-(2.12)."""

from __future__ import annotations

import math
from enum import IntEnum

from greyfmu.control.limits import OutputLimits


class IntegralMode(IntEnum):
    """How the integral term follows a change of Kc or Ti (thesis §2.3.2).

    With constant gains the three are the same controller.  The thesis recommends
    METHOD1 when only the plant's time constant or dead time varies, METHOD2/METHOD3
    when its gain varies, and METHOD3 as the general-purpose trade-off.
    """

    METHOD1 = 1
    """(2.10): I(k) = I(k−1) + Kc(k)·Ts/Ti(k)·e(k): the historic integral output is kept."""
    METHOD2 = 2
    """(2.11): the accumulated ∫e is kept; the integral output is rescaled by Kc(k)/Ti(k)."""
    METHOD3 = 3
    """(2.12): the accumulated ∫e/Ti is kept; the integral output is rescaled by Kc(k)."""


class PIForm(IntEnum):
    """How Kc enters the integral and derivative terms."""

    ISA = 0
    """Ideal (ISA): u = Kc·[e + (1/Ti)∫e dt + Td·de/dt], the thesis's (2.6a)/(2.9a) (our default)."""
    PARALLEL = 1
    """Parallel: u = Kc·e + (1/Ti)∫e dt + Td·de/dt, as §4.2 of the thesis prints the fuel and level PIs."""


class DerivativeOn(IntEnum):
    """Which signal the D term differentiates."""

    MEASUREMENT = 0
    """−y: no derivative kick on set-point steps (our default, a practical refinement)."""
    ERROR = 1
    """e = r − y, as the thesis writes every PID law: Td·de(t)/dt in (2.6a), (2.7a), (2.8a), (2.9a)."""


def integral_step(
    mode: IntegralMode | int,
    I_prev: float,
    e: float,
    Kc: float,
    Ti: float,
    Kc_prev: float,
    Ti_prev: float,
    Ts: float,
) -> float:
    """Integral output I(k) from I(k−1), the error e(k) and the gains at k and k−1 (sample time Ts).

    The thesis writes the laws for Ts = 1; with a sample time Ts each error sample adds
    the rectangle Ts·e(k):

    - METHOD1 (2.10): I(k) = I(k−1) + Kc(k)·Ts/Ti(k)·e(k)
    - METHOD2 (2.11): I1(k−1) = I(k−1) / (Kc(k−1)/Ti(k−1)),  I(k) = Kc(k)/Ti(k)·(I1(k−1) + Ts·e(k))
    - METHOD3 (2.12): I1(k−1) = I(k−1) / Kc(k−1),           I(k) = Kc(k)·(I1(k−1) + Ts·e(k)/Ti(k))

    The §2.3.2 example (I(k) = 60, Kc 4.5 → 5, Ti 15 → 10, e = 1, Ts = 1) gives
    60.5, 100.5 and 67.1667 (the thesis prints 90.5 and 67.15; see tests/greyfmu/test_pid.py).
    Gain-scheduled controllers call this with the gains of the previous and the current sample.
    """
    mode = IntegralMode(mode)
    if mode is IntegralMode.METHOD1:
        return I_prev + Kc * Ts / Ti * e
    if mode is IntegralMode.METHOD2:
        I1_prev = I_prev / (Kc_prev / Ti_prev)
        return (Kc / Ti) * (I1_prev + Ts * e)
    I1_prev = I_prev / Kc_prev
    return Kc * (I1_prev + Ts * e / Ti)


def _check_gains(Kc: float, Ti: float, Td: float) -> None:
    if not (math.isfinite(Kc) and Kc != 0.0):
        raise ValueError(f"PID: controller gain Kc must be a finite nonzero number, got {Kc}")
    if not (math.isfinite(Ti) and Ti > 0.0):
        raise ValueError(f"PID: integral time Ti must be a finite number > 0, got {Ti}")
    if not (math.isfinite(Td) and Td >= 0.0):
        raise ValueError(f"PID: derivative time Td must be a finite number >= 0, got {Td}")


class PID:
    """Discrete ideal PID ``u = Kc·[e + (1/Ti)∫e dt + Td·de/dt]``, ``e = r − y`` (thesis (2.6a)).

    ``form = PIForm.PARALLEL`` gives §4.2's printed ``u = Kc·e + (1/Ti)∫e dt + Td·de/dt``: the
    integral and derivative terms below then use the gain 1 where they use Kc (so the integral
    modes (2.10)-(2.12) rescale by 1/Ti only).

    ``step(r, y)`` is one sample k (sample time Ts):

    - ``P(k) = Kc·e(k)``
    - ``I(k) = integral_step(mode, I(k−1), e(k), Kc(k), Ti(k), Kc(k−1), Ti(k−1), Ts)``, (2.10)-(2.12)
    - ``D(k)``: derivative of ``x = −y`` (``derivative_on = MEASUREMENT``, the default: no kick
      on set-point steps) or of ``x = e`` (``ERROR``, the thesis's Td·de/dt of (2.6a)) through the
      filter ``1/(1 + s·Td/N)``, discretised by backward Euler with ``Tf = Td/N``:
      ``D(k) = [Tf·D(k−1) + Kc·Td·(x(k) − x(k−1))] / (Tf + Ts)``.  Backward Euler is stable
      and free of ringing for every Tf ≥ 0 (Tustin rings when Tf < Ts/2); its response to a
      step Δx has exactly the area ``Kc·Td·Δx`` of the continuous term; ``Td = 0`` gives D ≡ 0.
    - ``u(k)`` = ``P + I + D`` limited to ``u(k−1) ± du_max·Ts`` (rate limit, ``du_max`` in
      units per second, 0 or inf = none), then to ``[u_min, u_max]`` (the limits win).

    Anti-windup by conditional integration (``anti_windup=True``, the default; the thesis never
    mentions one): when the output is limited and this sample's integral increment points
    further beyond the limit, the increment is dropped (the mode's rescaling for a gain change
    still applies) and u is recomputed.  ``anti_windup=False`` is the thesis's controller: the
    integral always integrates, the output is still limited.  (The thesis's Simulink PIs have
    no output limits either; give ``u_min``/``u_max`` = ±inf and let the actuator clip.)

    Bumpless start: the integral starts at the bias ``u0`` and the first sample takes
    x(k−1) = x(k), so the output holds u0 while e = 0.  The bias is part of the integral
    (the thesis's "historic output"), so METHOD2/METHOD3 rescale it when the gains change.

    ``set_gains`` changes Kc, Ti, Td for the next sample (gain scheduling); that sample's
    integral law sees the gains of the previous sample as Kc(k−1), Ti(k−1).
    """

    def __init__(
        self,
        Kc: float,
        Ti: float,
        Td: float = 0.0,
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
        form: PIForm | int = PIForm.ISA,
    ) -> None:
        _check_gains(Kc, Ti, Td)
        if not (math.isfinite(Ts) and Ts > 0.0):
            raise ValueError(f"PID: sample time Ts must be a finite number > 0, got {Ts}")
        if not N > 0.0:
            raise ValueError(f"PID: derivative filter factor N must be > 0, got {N}")
        self.limits = OutputLimits("PID", Ts, u_min, u_max, du_max)
        self.limits.check_start(u0)
        self.Ts = Ts
        self.N = N
        self.integral_mode = IntegralMode(integral_mode)
        self.u0 = u0
        self.anti_windup = bool(anti_windup)
        self.derivative_on = DerivativeOn(derivative_on)
        self.form = PIForm(form)
        self._initial_gains = (Kc, Ti, Td)
        self.reset()

    def reset(self) -> None:
        """Return to the state right after construction (initial gains, output u0)."""
        self.Kc, self.Ti, self.Td = self._initial_gains
        self._Kc_prev, self._Ti_prev = self.Kc, self.Ti
        self.u = self.u0
        self.e = 0.0
        self.I = self.u0
        self.D = 0.0
        self._x_prev: float | None = None

    def set_gains(self, Kc: float, Ti: float, Td: float) -> None:
        """Use the gains Kc, Ti, Td from the next sample on."""
        _check_gains(Kc, Ti, Td)
        self.Kc, self.Ti, self.Td = Kc, Ti, Td

    def step(self, r: float, y: float) -> float:
        """One sample: set-point r, measurement y; returns the controller output u(k)."""
        e = r - y
        x = e if self.derivative_on is DerivativeOn.ERROR else -y
        x_prev = x if self._x_prev is None else self._x_prev
        Tf = self.Td / self.N
        D = (Tf * self.D + self._id_gain(self.Kc) * self.Td * (x - x_prev)) / (Tf + self.Ts)
        P = self.Kc * e
        I = self._integral(e)
        v = P + I + D
        u = self._limit(v)
        if u != v and self.anti_windup:
            I_held = self._integral(0.0)
            if (v - u) * (I - I_held) > 0.0:
                I = I_held
                u = self._limit(P + I + D)
        self.e, self.u, self.I, self.D, self._x_prev = e, u, I, D, x
        self._Kc_prev, self._Ti_prev = self.Kc, self.Ti
        return u

    def _id_gain(self, Kc: float) -> float:
        """The gain of the integral and derivative terms: Kc (ISA) or 1 (PARALLEL)."""
        return Kc if self.form is PIForm.ISA else 1.0

    def _integral(self, e: float) -> float:
        return integral_step(self.integral_mode, self.I, e, self._id_gain(self.Kc), self.Ti,
                             self._id_gain(self._Kc_prev), self._Ti_prev, self.Ts)

    def _limit(self, v: float) -> float:
        return self.limits.apply(v, self.u)
