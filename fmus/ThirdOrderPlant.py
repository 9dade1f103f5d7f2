"""Third-order plant with a zero and dead time (the test process of Cîrtoaje et al.): wraps greyfmu.plants.ThirdOrderPlant."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import ThirdOrderPlant as ThirdOrderModel


class ThirdOrderPlant(GreyfmuSlave):
    description = (
        "Plant H(s) = K (1 - T4 s) exp(-tau s) / ((T1 s + 1)(T2 s + 1)(T3 s + 1)) with input u + d, d a load "
        "disturbance. The inputs are held from each communication point (zero-order hold); the response is "
        "the exact ZOH solution (matrix exponential), the step split where the delayed input switches, so y "
        "does not depend on the master's step. Before the start u + d is the equilibrium y0/K. No direct "
        "feedthrough. Defaults: the test process of Cirtoaje et al. (paper section 3), minimum phase (T4 = 0); "
        "T4 = 60 s is the non-minimum-phase case of Fig. 11. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1000.0, step_size=1.0)
    output_dependencies = {"y": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("K", 1.2, "Process gain (nonzero)")
        self.parameter("T1", 90.0, "First time constant (> 0)", unit="s")
        self.parameter("T2", 60.0, "Second time constant (> 0)", unit="s")
        self.parameter("T3", 50.0, "Third time constant (> 0)", unit="s")
        self.parameter("T4", 0.0, "Zero time constant: numerator 1 - T4 s (> 0 is non-minimum phase)", unit="s")
        self.parameter("tau", 90.0, "Dead time", unit="s", minimum=0.0)
        self.parameter("y0", 0.0, "Initial output (the plant starts in equilibrium)")
        self.input("u", 0.0, "Manipulated variable")
        self.input("d", 0.0, "Load disturbance, added to u at the plant input")
        self.output("y", "Process output", lambda: self.plant.y)

    def build(self) -> None:
        self.plant = ThirdOrderModel(self.K, self.T1, self.T2, self.T3, self.T4, self.tau, self.y0)

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, self.u, self.d)
