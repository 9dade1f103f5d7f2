"""Second-order plant with dead time FMU: a thin wrapper around greyfmu.plants.SecondOrder."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import SecondOrder as SecondOrderPlant


class SecondOrder(GreyfmuSlave):
    description = (
        "Second-order plant with dead time y''/wn^2 + 2 zeta y'/wn + y = K (u + d)(t - tau) (Jukic & Bozicevic "
        "2005, Eq. (1)); K/(c2 s^2 + c1 s + 1) has wn = 1/sqrt(c2), zeta = c1/(2 sqrt(c2)). Inputs held from each "
        "communication point (zero-order hold), integrated exactly (matrix exponential), split where the delayed "
        "input switches, so y does not depend on the master's step. Starts at rest at y0. No direct feedthrough. "
        "Defaults: thesis Simulation 3.4 CASE 2, 1/(1400 s^2 + 30 s + 1). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=600.0, step_size=1.0)
    output_dependencies = {"y": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("K", 1.0, "Static gain (nonzero)")
        self.parameter("wn", 0.026726124191242, "Natural frequency (> 0)", unit="rad/s")
        self.parameter("zeta", 0.400891862868637, "Damping ratio (> 0)", unit="1")
        self.parameter("tau", 0.0, "Dead time", unit="s", minimum=0.0)
        self.parameter("y0", 0.0, "Initial output (the plant starts at rest)")
        self.input("u", 0.0, "Manipulated variable")
        self.input("d", 0.0, "Load disturbance, added to u at the plant input")
        self.output("y", "Process output", lambda: self.plant.y)

    def build(self) -> None:
        self.plant = SecondOrderPlant(self.K, self.wn, self.zeta, self.tau, self.y0)

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, self.u, self.d)
