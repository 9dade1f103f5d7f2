"""GM(3/t,1) step-response identifier FMU: a thin wrapper around greyfmu.grey.StepIdentifier."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability
from pythonfmu.enums import Fmi2Status

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.grey import StepIdentifier
from greyfmu.signals import SampleClock


class GM3t1Identifier(GreyfmuSlave):
    description = (
        "GM(3/t,1) identification of a second-order process (Jukic & Bozicevic 2005, Eqs. (4), (8)-(16)): samples "
        "the process output y every Ts from t_step on (the first sample, taken at rest at the step instant, is the "
        "baseline), and after N samples fits GM(3/t,1) to y - baseline with x(0) = 0 and outputs the static "
        "sensitivity ks = b/(a a2), the natural frequency wn = sqrt(a2)/Ts and the damping ratio zeta = a1/(2 "
        "sqrt(a2)) for a step of height a. valid = 1 once a stable model (a1 > 0, a2 > 0) came out; 0 before that "
        "or when the fit failed (the reason is logged), with ks = wn = zeta = 0. Sampled, no direct feedthrough. "
        + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=400.0, step_size=0.5)
    output_dependencies = {"ks": [], "wn": [], "zeta": [], "valid": []}
    sample_time = "Ts"
    sample_offset = "t_step"
    wiring = {"y": "measurement"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("t_step", 10.0, "Instant of the input step; the first sample is taken there", unit="s")
        self.parameter("a", 1.0, "Height of the input step (nonzero)")
        self.parameter("Ts", 0.5, "Sample interval", unit="s")
        self.parameter("N", 600, "Samples to collect before identifying (>= 4)", minimum=4)
        self.input("y", 0.0, "Process output")
        discrete = Fmi2Variability.discrete
        self.output("ks", "Identified static sensitivity (0 until valid)", lambda: self._value("ks"), variability=discrete)
        self.output("wn", "Identified natural frequency (0 until valid)", lambda: self._value("wn"), unit="rad/s",
                    variability=discrete)
        self.output("zeta", "Identified damping ratio (0 until valid)", lambda: self._value("zeta"), unit="1", variability=discrete)
        self.output("valid", "1 when a stable model was identified, else 0",
                    lambda: float(self.identifier.result is not None), unit="1", variability=discrete)

    def build(self) -> None:
        self.identifier = StepIdentifier(self.a, self.N, self.Ts)
        self.clock = SampleClock(self.Ts, self.t_step)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            if self.identifier.done:
                return
            self.identifier.add(self.y)
            if self.identifier.error:
                self.log(f"{self.instance_name}: {self.identifier.error}", Fmi2Status.warning)

    def _value(self, name: str) -> float:
        result = self.identifier.result
        return 0.0 if result is None else float(getattr(result, name))
