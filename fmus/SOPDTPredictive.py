"""Predictive controller FMU of Cîrtoaje et al.: a thin wrapper around greyfmu.control.SOPDTPredictive."""

import math
from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability
from pythonfmu.enums import Fmi2Status

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.control import ControlLaw, SOPDTPredictive as SOPDTPredictiveController
from greyfmu.signals import SampleClock


class SOPDTPredictive(GreyfmuSlave):
    description = (
        "Practical predictive controller (Cirtoaje, Francu, Radulescu) on the model K exp(-tau s)/((T1 s+1)(T2 s+1)), "
        "T1 = (1-xi/2) X_t T0, T2 = xi/2 X_t T0 (2): off-line design (3)-(6) with m = [X_d tau/Ts], "
        "N = [(tau+3 T0)/Ts]; on-line free response (9)-(10) and control law (7), (12) or (15), optional "
        "first-order reference trajectory, output and rate limits with the free response computed from the "
        "applied input. K, T0, tau, xi, X_k, X_t, X_d, X_p are tunable: setting one during the run re-runs the "
        "off-line design from the next sample on (an invalid value is refused: logged as a warning, the old value stays). Sampled at "
        "Ts with zero-order hold: do_step(t, h) computes every sample instant t0 + k*Ts in [t, t+h) from the "
        "inputs set at t; no direct feedthrough. A NaN measurement holds u and is logged as a warning. Defaults: "
        "the paper's starting data. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=4000.0, step_size=1.0)
    output_dependencies = {"u": [], "e": [], "m": [], "N": []}
    sample_time = "Ts"
    wiring = {"r": "setpoint", "y": "measurement", "u": "manipulated"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.tunable("K", 1.2, "Process steady-state gain K (> 0)")
        self.tunable("T0", 200.0, "Process dominant time constant T0 (> 0)", unit="s")
        self.tunable("tau", 90.0, "Process dead time tau (>= 0)", unit="s")
        self.tunable("xi", 0.6, "Time-constant allocation coefficient xi in (0, 1], (2)", unit="1")
        self.tunable("X_k", 1.5, "Adjustment coefficient of K, (3); > 1 for stability", unit="1")
        self.tunable("X_t", 1.0, "Adjustment coefficient of T0, (2)", unit="1")
        self.tunable("X_d", 1.0, "Adjustment coefficient of tau: m = [X_d tau/Ts]", unit="1")
        self.tunable("X_p", 0.6, "Control weighting coefficient X_p in (0, 1], (7)", unit="1")
        self.parameter("Ts", 40.0, "Sampling period T of the paper: N = [(tau + 3 T0)/Ts] should lie in 15..20", unit="s")
        self.parameter("law", ControlLaw.ONE_MOVE, "Control law: ONE_MOVE (7), TWO_MOVES (12) or TWO_MOVES_HELD (15) of the paper")
        self.parameter("T_ref", 0.0, "Reference-trajectory time constant (0 = setpoint step, Fig. 5)", unit="s", minimum=0.0)
        self.output_limit_parameters()
        self.parameter("u0", 0.0, "Initial output; the controller starts bumplessly from it")
        self.input("r", 0.0, "Setpoint w")
        self.input("y", 0.0, "Measured process output Y")
        self.output("u", "Controller output u_t, held between samples", lambda: self.controller.u, variability=Fmi2Variability.discrete)
        self.output("e", "Control error r - Y at the last sample", lambda: self.controller.e, variability=Fmi2Variability.discrete)
        self.output("m", "Integer dead time of the current design", lambda: float(self.controller.design.m), unit="1", variability=Fmi2Variability.discrete)
        self.output("N", "Prediction horizon of the current design", lambda: float(self.controller.design.N), unit="1", variability=Fmi2Variability.discrete)
        self._measurement_missing = False

    def tunable(self, name: str, start: float, description: str, unit: str | None = None) -> None:
        """Declare a tunable Real parameter; set during the run, it re-runs the off-line design (paper §2)."""
        self.parameter(name, start, description, unit=unit, retune=self._retune)

    def _retune(self, name: str, value: float) -> None:
        """An N > 20 HorizonWarning of the new design reaches the FMU log (the slave base forwards it)."""
        self.controller.retune(**{name: value})

    def build(self) -> None:
        self.controller = SOPDTPredictiveController(
            self.K,
            self.T0,
            self.tau,
            self.Ts,
            xi=self.xi,
            X_k=self.X_k,
            X_t=self.X_t,
            X_d=self.X_d,
            X_p=self.X_p,
            law=self.law,
            T_ref=self.T_ref,
            **self.output_limits(),
            u0=self.u0,
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def do_step(self, current_time: float, step_size: float) -> bool:
        """A NaN measurement is the controller's documented case (hold u, log), not an input error."""
        measurement = self.y
        self._measurement_missing = math.isnan(measurement)
        if self._measurement_missing:
            self.log(f"{self.instance_name}: measurement y is NaN at t = {current_time} s; u held", Fmi2Status.warning)
            self.y = 0.0  # a finite stand-in for the base class's input check; advance ignores it
        try:
            return super().do_step(current_time, step_size)
        finally:
            self.y = measurement

    def advance(self, t: float, h: float) -> None:
        y = math.nan if self._measurement_missing else self.y
        for _ in self.clock.samples_in(t, h):
            self.controller.step(self.r, y)
