"""First-order plus dead-time plant FMU: a thin wrapper around greyfmu.plants.FOPDT."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import FOPDT as FOPDTPlant


class FOPDT(GreyfmuSlave):
    description = (
        "First-order plus dead-time plant T dx/dt + x = K (u + d)(t - tau), y = x, with d a load disturbance "
        "at the plant input (thesis (2.13a)). The inputs are held from each communication point (zero-order "
        "hold) and the response is integrated exactly, splitting the step where the delayed input switches, so "
        "y does not depend on the master's step. Before the start u + d is the equilibrium y0/K. No direct "
        "feedthrough (y is the state). Defaults: Simulation 2.1 at its low operating point. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("K", 0.2, "Process gain (nonzero)")
        self.parameter("T", 20.0, "Time constant (> 0)", unit="s")
        self.parameter("tau", 4.0, "Dead time", unit="s", minimum=0.0)
        self.parameter("y0", 0.0, "Initial output (the plant starts in equilibrium)")
        self.input("u", 0.0, "Manipulated variable")
        self.input("d", 0.0, "Load disturbance, added to u at the plant input")
        self.output("y", "Process output", lambda: self.plant.y)

    def build(self) -> None:
        self.plant = FOPDTPlant(self.K, self.T, self.tau, self.y0)

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, self.u, self.d)
