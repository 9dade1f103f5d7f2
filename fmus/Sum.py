"""Weighted sum FMU: a thin wrapper around greyfmu.signals.Sum."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.signals import Sum as WeightedSum


class Sum(GreyfmuSlave):
    description = (
        "Weighted sum y = k1*u1 + k2*u2 + k3*u3 (k2 = -1 for a difference). Direct feedthrough: y is computed "
        "from the current inputs whenever it is read. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": ["u1", "u2", "u3"]}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("k1", 1.0, "Weight of u1")
        self.parameter("k2", 1.0, "Weight of u2")
        self.parameter("k3", 1.0, "Weight of u3")
        self.input("u1", 0.0, "First input")
        self.input("u2", 0.0, "Second input")
        self.input("u3", 0.0, "Third input")
        self.output("y", "Weighted sum of the inputs", lambda: self.block.output(self.u1, self.u2, self.u3))

    def build(self) -> None:
        self.block = WeightedSum(self.k1, self.k2, self.k3)

    def advance(self, t: float, h: float) -> None:
        """Stateless: the output follows the inputs when read."""
