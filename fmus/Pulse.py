"""Pulse source FMU: a thin wrapper around greyfmu.signals.Pulse."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, SourceSlave
from greyfmu.signals import Pulse as PulseSignal


class Pulse(SourceSlave):
    description = (
        "Pulse source: y = offset + amplitude on [start_time + n*period, start_time + n*period + width), "
        "offset elsewhere; period = 0 gives a single pulse. Evaluated at the FMU's current time (after "
        "do_step(t, h): y(t + h); after initialisation: y(t0)). No inputs. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("amplitude", 1.0, "Pulse height above the offset")
        self.parameter("start_time", 10.0, "Rising edge of the first pulse", unit="s")
        self.parameter("width", 5.0, "Pulse duration", unit="s", minimum=0.0)
        self.parameter("period", 20.0, "Pulse period, >= width (0 = single pulse)", unit="s", minimum=0.0)
        self.parameter("offset", 0.0, "Output between pulses")
        self.source_output("Pulse output", Fmi2Variability.discrete)

    def build(self) -> None:
        self.signal = PulseSignal(self.amplitude, self.start_time, self.width, self.period, self.offset)
