"""First-order filter FMU: a thin wrapper around greyfmu.signals.FirstOrderFilter."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.signals import FirstOrderFilter as Lag


class FirstOrderFilter(GreyfmuSlave):
    description = (
        "First-order filter T dy/dt + y = K u, integrated exactly with the input held over each "
        "communication step (zero-order hold). No direct feedthrough (y is the state). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("K", 1.0, "Static gain")
        self.parameter("T", 1.0, "Time constant (> 0)", unit="s")
        self.parameter("y0", 0.0, "Initial output")
        self.input("u", 0.0, "Filter input")
        self.output("y", "Filtered output", lambda: self.lag.y)

    def build(self) -> None:
        self.lag = Lag(self.T, self.K, self.y0)

    def advance(self, t: float, h: float) -> None:
        self.lag.advance(h, self.u)
