"""Plant models following `greyfmu.contract.Plant`, integrated exactly or accurately over a caller's step."""

from greyfmu.plants.delay import DelayLine
from greyfmu.plants.fopdt import FOPDT

__all__ = ["DelayLine", "FOPDT"]

from greyfmu.plants.third_order import ThirdOrderPlant

__all__ += ["ThirdOrderPlant"]

from greyfmu.plants.boiler_turbine import BoilerTurbine, OperatingPoint, equilibrium, scheduled_pressure

__all__ += ["BoilerTurbine", "OperatingPoint", "equilibrium", "scheduled_pressure"]

from greyfmu.plants.scheduled_fopdt import PiecewiseParameter, ScheduledFOPDT

__all__ += ["PiecewiseParameter", "ScheduledFOPDT"]

from greyfmu.plants.second_order import SecondOrder  # noqa: E402

__all__ += ["SecondOrder"]

from greyfmu.plants.stochastic_lti import StochasticLTI  # noqa: E402

__all__ += ["StochasticLTI"]

from greyfmu.plants.four_tank import FourTank, equilibrium_levels
from greyfmu.plants.steam_header import (
    HeaderParameters,
    SteamHeader,
    excitation_run,
    least_fuel_firing,
    segment_demands,
    steady_firing,
)

__all__ += ["FourTank", "equilibrium_levels", "HeaderParameters", "SteamHeader", "excitation_run", "least_fuel_firing",
            "segment_demands", "steady_firing"]
