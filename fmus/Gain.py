"""Gain FMU: a thin wrapper around greyfmu.signals.Gain."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.signals import Gain as StaticGain


class Gain(GreyfmuSlave):
    description = (
        "Gain y = k*u. Direct feedthrough: y is computed from the current input whenever it is read. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": ["u"]}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("k", 1.0, "Gain")
        self.input("u", 0.0, "Input")
        self.output("y", "k times the input", lambda: self.block.output(self.u))

    def build(self) -> None:
        self.block = StaticGain(self.k)

    def advance(self, t: float, h: float) -> None:
        """Stateless: the output follows the input when read."""
