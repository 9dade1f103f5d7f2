"""Steam header (PUUH) FMU: 3 boilers, 2 turbines, 2 header segments; wraps greyfmu.plants.SteamHeader."""

from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import HeaderParameters
from greyfmu.plants import SteamHeader as SteamHeaderPlant


class SteamHeader(GreyfmuSlave):
    description = (
        "Parallel-coursing utility units with a header (Pan, Shen & Luh 2012, §2 and §5.2): 3 boilers with firing "
        "lag, steam-generation lag, storage and load-dependent efficiency, 2 turbines with valves, 2 header "
        "segments with pressures P_m2 (y1) and P_m4 (y2). OUR lumped model (recovered-models.md §8 with "
        "per-boiler efficiency curves, linear outlet/tie conductances and B2 between the segments; see "
        "greyfmu.plants.steam_header). Fixed-step RK4 with sub-steps of at most 0.25 s over each "
        "communication step, inputs held; starts at the equilibrium of u0 and 50 % valves; no direct "
        "feedthrough. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=4500.0, step_size=1.0)
    output_dependencies = {"y1": [], "y2": [], "fuel": [], "F1": [], "F2": [], "F3": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("u0", 0.75, "Initial firing of every boiler (p.u. of rated firing)", unit="1")
        self.parameter("tau_f", 15.0, "Firing lag", unit="s", minimum=0.0)
        self.parameter("tau_g", 60.0, "Steam generation lag", unit="s", minimum=0.0)
        self.parameter("F_N", 7.2, "Fuel at rated firing", unit="kg/s", minimum=0.0)
        self.parameter("max_substep", 0.25, "Largest RK4 sub-step", unit="s", minimum=0.0)
        for i in (1, 2, 3):
            self.input(f"u{i}", 0.75, f"Firing demand of boiler {i} (p.u. of rated firing)", unit="1")
        self.input("v1", 50.0, "Valve opening of turbine 1", unit="%")
        self.input("v2", 50.0, "Valve opening of turbine 2", unit="%")
        self.output("y1", "Header pressure P_m2 (segment of turbine 1)", lambda: float(self.plant.x[9]), unit="MPa")
        self.output("y2", "Header pressure P_m4 (segment of turbine 2)", lambda: float(self.plant.x[10]), unit="MPa")
        self.output("fuel", "Total fuel consumption of the three boilers", lambda: float(self.plant.fuel.sum()), unit="kg/s")
        for i in (1, 2, 3):
            self.output(f"F{i}", f"Fuel consumption of boiler {i}", lambda i=i: float(self.plant.fuel[i - 1]), unit="kg/s")

    def build(self) -> None:
        for name in ("tau_f", "tau_g", "max_substep"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"SteamHeader: {name} must be > 0, got {getattr(self, name)}")
        params = HeaderParameters(tau_f=self.tau_f, tau_g=self.tau_g, F_N=self.F_N)
        self.plant = SteamHeaderPlant(params, np.full(3, self.u0), (0.5, 0.5), self.max_substep)

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, [self.u1, self.u2, self.u3], [self.v1 / 100.0, self.v2 / 100.0])
