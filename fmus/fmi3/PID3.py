"""PID controller as an FMI 3.0 FMU (pythonfmu3): the PID FMU of fmus/PID.py, same variables
and behaviour, a thin wrapper around greyfmu.control.PID."""

from typing import Any

from pythonfmu3 import DefaultExperiment, Fmi3Slave, Fmi3Variability

from _slave3 import REQUIREMENTS, GreyfmuSlave3
from greyfmu.control import PID as PIDController
from greyfmu.control.pid import IntegralMode
from greyfmu.signals import SampleClock


class PID3(GreyfmuSlave3, Fmi3Slave):  # pythonfmu3 finds the slave class by a textual Fmi3Slave base
    output_dependencies = {"u": [], "e": []}
    sample_time = "Ts"
    wiring = {"r": "setpoint", "y": "measurement", "u": "manipulated"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = (
            "FMI 3.0 build of the PID FMU: sampled ideal (ISA) PID u = Kc[e + (1/Ti)∫e dt + Td de/dt], e = r - y, "
            "derivative on the measurement filtered by Td/N, output and rate limits, anti-windup and the integral "
            "modes (2.10)-(2.12) of the thesis; sampled at Ts from the first step's time, output held, no direct "
            "feedthrough. " + REQUIREMENTS
        )
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
        self.parameter("Kc", 8.0345, "Controller gain (1.6069/Kp with Kp = 0.2)")
        self.parameter("Ti", 7.1713, "Integral time", unit="s")
        self.parameter("Td", 1.5363, "Derivative time (0 disables the derivative term)", unit="s")
        self.parameter("N", 10.0, "Derivative filter factor: filter time constant Td/N")
        self.parameter("Ts", 0.1, "Sample time", unit="s")
        self.parameter("u_min", -1e10, "Lower output limit")
        self.parameter("u_max", 1e10, "Upper output limit")
        self.parameter("du_max", 0.0, "Output rate limit in units of u per second (0 = none)")
        self.parameter("integral_mode", IntegralMode.METHOD3,
                       "Integral mode: METHOD1 = (2.10), METHOD2 = (2.11), METHOD3 = (2.12) of the thesis")
        self.parameter("u0", 0.0, "Initial output (bias): the integral starts here, so u = u0 while e = 0")
        self.input("r", 0.0, "Set-point")
        self.input("y", 0.0, "Measured process output")
        self.output("u", "Controller output, held between samples", lambda: self.pid.u, Fmi3Variability.discrete)
        self.output("e", "Control error r - y at the last sample", lambda: self.pid.e, Fmi3Variability.discrete)

    def build(self) -> None:
        self.pid = PIDController(self.Kc, self.Ti, self.Td, self.Ts, N=self.N, u_min=self.u_min, u_max=self.u_max,
                                 du_max=self.du_max, integral_mode=self.integral_mode, u0=self.u0)
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.pid.step(self.r, self.y)
