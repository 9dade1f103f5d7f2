"""Ramp source FMU: a thin wrapper around greyfmu.signals.Ramp."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, SourceSlave
from greyfmu.signals import Ramp as RampSignal


class Ramp(SourceSlave):
    description = (
        "Rate-limited ramp source: y = initial until start_time, then moves toward final at |slope| per "
        "second and stays at final (use a distant final for an unbounded ramp). Evaluated at the FMU's "
        "current time (after do_step(t, h): y(t + h); after initialisation: y(t0)). No inputs. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("start_time", 10.0, "Time the ramp starts", unit="s")
        self.parameter("slope", 0.1, "Rate of change in units of y per second (its magnitude is used)")
        self.parameter("initial", 0.0, "Output before the ramp")
        self.parameter("final", 1.0, "Output the ramp stops at")
        self.source_output("Ramp output", Fmi2Variability.continuous)

    def build(self) -> None:
        self.signal = RampSignal(self.start_time, self.slope, self.initial, self.final)
