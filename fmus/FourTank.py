"""Four-tank benchmark FMU: a thin wrapper around greyfmu.plants.FourTank."""

from enum import IntEnum
from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import FourTank as FourTankPlant
from greyfmu.plants import equilibrium_levels
from greyfmu.signals import SampleClock


class FourTankModel(IntEnum):
    """Which model of the paper the map follows."""

    TIME_INVARIANT = 0
    """The time-invariant model (40)."""
    TIME_VARYING = 1
    """(41)-(42): after k_change the input coefficients ramp and the delay grows."""


class FourTank(GreyfmuSlave):
    description = (
        "Two-input four-tank benchmark of Pan, Shen & Luh (2012), (40), as the discrete map (41)-(42) the paper "
        "prints (forward Euler of (40) at the sample period Ts): after step k_change the input coefficients ramp "
        "as 1 - ramp (k - ramp_origin) and the delay of h3, h4 on h1, h2 steps from 1 to 'delay' samples "
        "(DelayLine). The map advances at every sample instant t0 + k Ts in [t, t+h) with u1, u2 read at t "
        "(zero-order hold); levels are held between samples; no direct feedthrough. Levels and flows are "
        "dimensionless, as in the paper (unit 1). Initial levels: the equilibrium of (40) for u1 = u2 = u0. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1500.0, step_size=1.0)
    output_dependencies = {"h1": [], "h2": [], "h3": [], "h4": []}
    sample_time = "Ts"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("Ts", 1.0, "Sample period of the map (41)-(42)", unit="s")
        self.parameter("k_change", 500, "Step at which the ramp and the delay change start ((41)-(42))", minimum=0)
        self.parameter("ramp", 0.0005, "Slope of the input-coefficient ramp per step ((41)-(42))", unit="1")
        self.parameter("ramp_origin", 500, "Step at which the coefficient ramp 1 - ramp (k - ramp_origin) equals 1 "
                       "(500: continuous at k_change; 0: the literal 1 - 0.0005 k of (41))", minimum=0)
        self.parameter("delay", 450, "Input delay after k_change, in steps ((41)-(42))", minimum=1)
        self.parameter("time_varying", FourTankModel.TIME_VARYING, "Model: TIME_VARYING (41)-(42) or TIME_INVARIANT (40)")
        self.parameter("u0", 0.7, "Inputs whose equilibrium sets the initial levels", unit="1")
        self.input("u1", 0.7, "Input flow 1 (into tank 3)", unit="1")
        self.input("u2", 0.7, "Input flow 2 (into tank 4)", unit="1")
        for i in range(1, 5):
            self.output(f"h{i}", f"Level of tank {i}", lambda i=i: float(self.plant.h[i - 1]), unit="1", variability=Fmi2Variability.discrete)

    def build(self) -> None:
        self.plant = FourTankPlant(
            equilibrium_levels(self.u0, self.u0), self.Ts, self.k_change, self.ramp, self.delay, bool(self.time_varying),
            self.ramp_origin,
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.plant.step(self.u1, self.u2)
