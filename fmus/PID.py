"""PID controller FMU: a thin wrapper around greyfmu.control.PID."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, AntiWindup, GreyfmuSlave
from greyfmu.control import PID as PIDController
from greyfmu.control.pid import DerivativeOn, PIForm
from greyfmu.signals import SampleClock


class PID(GreyfmuSlave):
    description = (
        "Sampled ideal (ISA) PID u = Kc[e + (1/Ti)∫e dt + Td de/dt] (or the parallel form, parameter form), e = r - y, with the derivative on the "
        "measurement (default) or on the error (the thesis's form) filtered by Td/N (backward Euler), output and rate "
        "limits, conditional-integration anti-windup (switchable off) and the integral modes (2.10)-(2.12) of the "
        "thesis. Sampled at Ts with zero-order hold: "
        "do_step(t, h) computes every sample instant t0 + k*Ts in [t, t+h) from the inputs set at t, and u is "
        "the last sample's output (u0 before the first sample); no direct feedthrough. Defaults: Simulation 2.1 "
        "at its low operating point (Kc = 1.6069/0.2). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"u": [], "e": []}
    sample_time = "Ts"
    wiring = {"r": "setpoint", "y": "measurement", "u": "manipulated"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("Kc", 8.0345, "Controller gain (1.6069/Kp with Kp = 0.2)")
        self.parameter("Ti", 7.1713, "Integral time", unit="s")
        self.parameter("Td", 1.5363, "Derivative time (0 disables the derivative term)", unit="s", minimum=0.0)
        self.parameter("N", 10.0, "Derivative filter factor: filter time constant Td/N", unit="1")
        self.parameter("Ts", 0.1, "Sample time", unit="s")
        self.parameter("anti_windup", AntiWindup.CONDITIONAL_INTEGRATION,
                       "Anti-windup: CONDITIONAL_INTEGRATION at the output limits (ours) or NONE (the thesis's PI)")
        self.parameter("derivative_on", DerivativeOn.MEASUREMENT, "Signal the D term differentiates: MEASUREMENT -y "
                       "(ours, no set-point kick) or ERROR e (the thesis's Td de/dt, (2.6a))")
        self.parameter("form", PIForm.ISA, "Where Kc enters: ISA Kc[e + (1/Ti)∫e + Td de/dt] (ours, (2.6a)) or "
                       "PARALLEL Kc·e + (1/Ti)∫e + Td de/dt (§4.2 of the thesis as printed)")
        self.output_limit_parameters()
        self.integral_parameters()
        self.input("r", 0.0, "Set-point")
        self.input("y", 0.0, "Measured process output")
        self.output("u", "Controller output, held between samples", lambda: self.pid.u, variability=Fmi2Variability.discrete)
        self.output("e", "Control error r - y at the last sample", lambda: self.pid.e, variability=Fmi2Variability.discrete)

    def build(self) -> None:
        self.pid = PIDController(
            self.Kc,
            self.Ti,
            self.Td,
            self.Ts,
            N=self.N,
            anti_windup=bool(self.anti_windup),
            derivative_on=self.derivative_on,
            form=self.form,
            **self.output_limits(),
            **self.integral_options(),
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.pid.step(self.r, self.y)
