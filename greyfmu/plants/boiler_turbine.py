"""Bell–Åström 160 MW boiler-turbine-generator unit with its valve actuators.

The model is the canonical three-state form of Bell & Åström (1987) as recovered in
`shared/models/recovered-models.md` §1, with the valve positions scaled 0–100 % (the §1
"variant with inputs scaled 0–100 %"); the thesis's printed (4.2a) has sign and typing errors
(thesis `000_*` ch. 4), §1 gives the corrected equations checked against two public codes:

    dP/dt     = -1.8e-5 v2 P^(9/8) + 0.009 v1 - 0.0015 v3
    dE/dt     = ((0.0073 v2 - 0.16) P^(9/8) - E) / 10
    drho_f/dt = (1.41 v3 - (0.011 v2 - 0.19) P) / 85
    L         = 50 (0.13073 rho_f + 100 alpha_cs + q_e/9 - 67.975)          [mm]
    alpha_cs  = (1 - 0.001538 rho_f)(0.8 P - 25.6) / (rho_f (1.0394 - 0.0012304 P))
    q_e       = (0.00854 v2 - 0.147) P + 0.4559 v1 - 0.02514 v3 - 2.096

P drum pressure [kgf/cm²], E electric output [MW], rho_f fluid density [kg/m³], L drum level
[mm] (§1's y3 in metres × 1000, the unit the thesis's level loop uses), v1 fuel, v2 governor
(steam) valve, v3 feedwater valve, positions in %.

Actuators (thesis (4.2b)): each position follows its command clipped to 0–100 % at a bounded
rate, 0.7 %/s (fuel), 2 %/s (governor) and 5 %/s (feedwater).  The thesis states symmetric
rates; §1's canonical governor limit closes at 200 %/s — pass ``rates`` to use it.  A fuel
disturbance [%] adds to the fuel valve's effect after its actuator (a change of fuel quality
or of a mill's feed, not rate limited).

Integration: classical RK4 with sub-steps of at most ``max_substep`` (0.05 s by default:
the fastest dynamics, the 10 s power lag, then contribute errors below 1e-9 per second);
valve positions are evaluated exactly at every RK4 stage (they are piecewise linear in time).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from greyfmu.plants.integration import rk4

#: Thesis (4.2b): rate limits of fuel, governor and feedwater valves [%/s].
THESIS_RATES = (0.7, 2.0, 5.0)
#: The thesis's variant-pressure operating line, ch. 4: load [MW] -> throttle pressure [kgf/cm²]
#: (governor near 75 %); "Fcn Gen" interpolates linearly between these points.
PRESSURE_SCHEDULE = ((58.0, 86.0), (76.0, 109.0), (101.0, 140.0))


def derivatives(x: np.ndarray, v: Sequence[float], fuel_disturbance: float = 0.0) -> np.ndarray:
    """dx/dt for x = (P, E, rho_f) and valve positions v [%] (recovered-models.md §1)."""
    P, E, _ = x
    v1, v2, v3 = v
    p98 = max(P, 0.0) ** 1.125
    fuel = v1 + fuel_disturbance
    return np.array([-1.8e-5 * v2 * p98 + 0.009 * fuel - 0.0015 * v3,
                     ((0.0073 * v2 - 0.16) * p98 - E) / 10.0,
                     (1.41 * v3 - (0.011 * v2 - 0.19) * P) / 85.0])


def drum_level(x: Sequence[float], v: Sequence[float], fuel_disturbance: float = 0.0) -> float:
    """Drum level [mm]: §1's y3 (metres) × 1000."""
    P, _, rho = x
    v1, v2, v3 = v
    alpha_cs = (1 - 0.001538 * rho) * (0.8 * P - 25.6) / (rho * (1.0394 - 0.0012304 * P))
    q_e = (0.00854 * v2 - 0.147) * P + 0.4559 * (v1 + fuel_disturbance) - 0.02514 * v3 - 2.096
    return 50.0 * (0.13073 * rho + 100.0 * alpha_cs + q_e / 9.0 - 67.975)


def scheduled_pressure(load: float) -> float:
    """The thesis's "Fcn Gen": pressure setpoint for a load, linear between its three points
    (and along the end segments beyond them)."""
    (l0, p0), (l1, p1), (l2, p2) = PRESSURE_SCHEDULE
    (la, pa), (lb, pb) = ((l0, p0), (l1, p1)) if load < l1 else ((l1, p1), (l2, p2))
    return pa + (pb - pa) / (lb - la) * (load - la)


@dataclass(frozen=True)
class OperatingPoint:
    P: float
    E: float
    rho_f: float
    fuel: float
    governor: float
    feedwater: float
    level: float

    @property
    def state(self) -> np.ndarray:
        return np.array([self.P, self.E, self.rho_f])

    @property
    def valves(self) -> tuple[float, float, float]:
        return (self.fuel, self.governor, self.feedwater)


def equilibrium(load: float, pressure: float | None = None, level: float | None = None) -> OperatingPoint:
    """Steady state at a load [MW]: the pressure from the thesis's schedule unless given and the
    valves from §1's equilibrium recipe.  rho_f is free at equilibrium: by default it follows
    §1's operating table (rho_f = 3.963 P, i.e. 428/108 · P); with ``level`` [mm] it is the
    density on the physical (upper) branch of L(rho_f) giving that level.  A level below that
    branch's minimum cannot be held at this load and raises ValueError naming the minimum."""
    P = scheduled_pressure(load) if pressure is None else pressure
    p98 = P ** 1.125
    gov = (load / p98 + 0.16) / 0.73 * 100.0
    feed = (0.011 * gov - 0.19) * P / 1.41
    fuel = (1.8e-5 * gov * p98 + 0.0015 * feed) / 0.009
    valves = (fuel, gov, feed)
    if level is None:
        rho = 428.0 / 108.0 * P
    else:
        from scipy.optimize import brentq, minimize_scalar

        def level_at(rho_f: float) -> float:
            return drum_level((P, load, rho_f), valves)

        lowest = minimize_scalar(level_at, bounds=(150.0, 900.0), method="bounded")
        if level_at(lowest.x) > level:
            raise ValueError(f"a drum level of {level:g} mm cannot be held at {load:g} MW and {P:g} kgf/cm²: "
                             f"the level is at least {level_at(lowest.x):.1f} mm there")
        rho = brentq(lambda r: level_at(r) - level, lowest.x, 2000.0, xtol=1e-12)
    return OperatingPoint(P, load, rho, fuel, gov, feed, drum_level((P, load, rho), valves))


class Actuator:
    """A valve position following its command, clipped to 0–100 %, at a bounded rate."""

    def __init__(self, position: float, rate: float):
        if rate <= 0:
            raise ValueError(f"actuator rate must be positive, got {rate}")
        self.position = float(position)
        self.rate = float(rate)

    def trajectory(self, command: float, h: float) -> tuple[float, float, float]:
        """(start position, signed rate, time the target is reached) for a command held over h."""
        target = min(max(command, 0.0), 100.0)
        distance = target - self.position
        reach = abs(distance) / self.rate
        return self.position, math.copysign(self.rate, distance) if distance else 0.0, min(reach, h)

    @staticmethod
    def at(trajectory: tuple[float, float, float], s: float) -> float:
        start, rate, reach = trajectory
        return start + rate * min(s, reach)


class BoilerTurbine:
    """The unit with its three valve actuators; `advance` integrates one communication step."""

    def __init__(self, start: OperatingPoint, rates: Sequence[float] = THESIS_RATES, max_substep: float = 0.05):
        if max_substep <= 0:
            raise ValueError(f"max_substep must be positive, got {max_substep}")
        self.start = start
        self.rates = tuple(rates)
        self.max_substep = max_substep
        self.reset()

    def reset(self) -> None:
        """Back to the start operating point (state, valve positions, no disturbance)."""
        self.x = self.start.state.copy()
        self.actuators = [Actuator(p, r) for p, r in zip(self.start.valves, self.rates)]
        self.fuel_disturbance = 0.0

    @property
    def valves(self) -> tuple[float, float, float]:
        return tuple(a.position for a in self.actuators)

    @property
    def level(self) -> float:
        return drum_level(self.x, self.valves, self.fuel_disturbance)

    def advance(self, t: float, h: float, u: Sequence[float], d: float = 0.0) -> np.ndarray:
        """Integrate [t, t + h] with the valve commands u = (fuel, governor, feedwater) [%] and the fuel
        disturbance d [%] held; returns the outputs y = (P, E, L) at t + h (the unit is time-invariant:
        t only follows the ``Plant`` contract)."""
        fuel_disturbance = d
        paths = [a.trajectory(c, h) for a, c in zip(self.actuators, u)]

        def f(s: float, state: np.ndarray) -> np.ndarray:
            return derivatives(state, [Actuator.at(p, s) for p in paths], fuel_disturbance)

        self.x = rk4(f, self.x, h, self.max_substep)
        for a, p in zip(self.actuators, paths):
            a.position = Actuator.at(p, h)
        self.fuel_disturbance = fuel_disturbance
        return np.array([self.x[0], self.x[1], self.level])
