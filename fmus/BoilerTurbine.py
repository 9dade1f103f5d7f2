"""Bell–Åström 160 MW boiler-turbine-generator FMU: a thin wrapper around greyfmu.plants.BoilerTurbine."""

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants.boiler_turbine import THESIS_RATES, BoilerTurbine as Unit, equilibrium

START = equilibrium(76.0, level=-100.0)


class BoilerTurbine(GreyfmuSlave):
    description = (
        "Bell-Astrom 160 MW boiler-turbine-generator unit (canonical 3-state model of "
        "shared/models/recovered-models.md section 1, valves scaled 0-100 %) with rate-limited valve actuators "
        "(thesis (4.2b)). Starts at the equilibrium of load0 on the thesis's variant-pressure line "
        "(58/76/101 MW at 86/109/140 kgf/cm2) with drum level L0. Fixed-step RK4 with sub-steps of at most "
        "max_substep inside each communication step. No direct feedthrough. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=600.0, step_size=0.5)
    output_dependencies = {name: [] for name in ("P", "E", "L", "fuel_pos", "governor_pos", "feedwater_pos")}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("load0", 76.0, "Initial load: the unit starts at its equilibrium", unit="MW")
        self.parameter("L0", -100.0, "Initial drum level (fixes the fluid density of the equilibrium)", unit="mm")
        self.parameter("rate_fuel", THESIS_RATES[0], "Fuel valve rate limit (4.2b)", unit="%/s", minimum=0.0)
        self.parameter("rate_governor", THESIS_RATES[1], "Governor valve rate limit (4.2b)", unit="%/s", minimum=0.0)
        self.parameter("rate_feedwater", THESIS_RATES[2], "Feedwater valve rate limit (4.2b)", unit="%/s",
                       minimum=0.0)
        self.parameter("max_substep", 0.05, "Longest RK4 sub-step", unit="s", minimum=0.0)
        self.input("fuel", START.fuel, "Fuel valve command", unit="%")
        self.input("governor", START.governor, "Governor (steam) valve command", unit="%")
        self.input("feedwater", START.feedwater, "Feedwater valve command", unit="%")
        self.input("fuel_disturbance", 0.0, "Fuel disturbance added after the fuel actuator", unit="%")
        self.output("P", "Drum (throttle) pressure", lambda: self.unit.x[0], unit="kgf/cm2")
        self.output("E", "Electric output", lambda: self.unit.x[1], unit="MW")
        self.output("L", "Drum level", lambda: self.unit.level, unit="mm")
        self.output("fuel_pos", "Fuel valve position", lambda: self.unit.valves[0], unit="%")
        self.output("governor_pos", "Governor valve position", lambda: self.unit.valves[1], unit="%")
        self.output("feedwater_pos", "Feedwater valve position", lambda: self.unit.valves[2], unit="%")

    def build(self) -> None:
        start = equilibrium(self.load0, level=self.L0)
        self.unit = Unit(start, (self.rate_fuel, self.rate_governor, self.rate_feedwater), self.max_substep)

    def advance(self, t: float, h: float) -> None:
        self.unit.advance(t, h, (self.fuel, self.governor, self.feedwater), self.fuel_disturbance)
