"""Step source FMU: a thin wrapper around greyfmu.signals.Step."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, SourceSlave
from greyfmu.signals import Step as StepSignal


class Step(SourceSlave):
    description = (
        "Step source: y = initial before t_step, final from t_step on, evaluated at the FMU's current time "
        "(after do_step(t, h): y(t + h); after initialisation: y(t0)). No inputs. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("t_step", 1.0, "Step time", unit="s")
        self.parameter("initial", 0.0, "Output before the step")
        self.parameter("final", 1.0, "Output from the step time on")
        self.source_output("Step output", Fmi2Variability.discrete)

    def build(self) -> None:
        self.signal = StepSignal(self.t_step, self.initial, self.final)
