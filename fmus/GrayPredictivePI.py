"""Grey predictive PI FMU: a thin wrapper around greyfmu.control.GrayPredictivePI."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, AntiWindup, GreyfmuSlave
from greyfmu.control import GrayPredictivePI as Controller
from greyfmu.control.pid import PIForm
from greyfmu.grey import Threshold
from greyfmu.signals import SampleClock


class GrayPredictivePI(GreyfmuSlave):
    description = (
        "Error-prediction-based grey predictive PI (thesis 000_*, §3.2, Fig. 3.14, (3.29)): the error e = r - y plus "
        "the bias B goes through a moving-window GM(1,1) predictor (n samples every m-th sample, LDISPI §3.1.6); the "
        "PI of the PID FMU (integral modes (2.10)-(2.12), limits, optional anti-windup) acts on the predicted error "
        "e_hat, ph seconds ahead when a > a_min (threshold SIGNED, §4.2 as printed) or |a| > a_min (MAGNITUDE), the estimated "
        "current error otherwise. Sampled at Ts with zero-order "
        "hold, no direct feedthrough. Defaults: ph = 25 s, B = 50, a_min = 0.035 of §4.2; Kc, Ti for "
        "1/((1+30s)(1+5s)). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=300.0, step_size=1.0)
    output_dependencies = {"u": [], "e": [], "e_hat": [], "a": [], "mode": []}
    sample_time = "Ts"
    wiring = {"r": "setpoint", "y": "measurement", "u": "manipulated"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("Kc", 2.0, "Controller gain")
        self.parameter("Ti", 20.0, "Integral time", unit="s")
        self.parameter("Ts", 1.0, "Sample time", unit="s")
        self.parameter("n", 4, "Grey window length (>= 3; the thesis uses 4-6)", minimum=3)
        self.parameter("m", 5, "LDISPI data interval: every m-th error sample enters the window", minimum=1)
        self.parameter("ph", 25.0, "Prediction horizon", unit="s", minimum=0.0)
        self.parameter("B", 50.0, "Bias keeping e + B positive (3.29b)", minimum=0.0)
        self.parameter("a_min", 0.035, "Predict only when a passes a_min (see threshold), else estimate the current error", unit="1",
                       minimum=0.0)
        self.parameter("threshold", Threshold.SIGNED,
                       "Predict/estimate rule: SIGNED a > a_min (§4.2 as printed) or MAGNITUDE |a| > a_min")
        self.parameter("anti_windup", AntiWindup.CONDITIONAL_INTEGRATION,
                       "Anti-windup: CONDITIONAL_INTEGRATION at the output limits (ours) or NONE (the thesis's PI)")
        self.parameter("form", PIForm.ISA, "Where Kc enters the PI: ISA Kc[e + (1/Ti)∫e] (ours, (2.6a)) or PARALLEL "
                       "Kc·e + (1/Ti)∫e (§4.2 of the thesis as printed)")
        self.output_limit_parameters()
        self.integral_parameters()
        self.input("r", 0.0, "Set-point")
        self.input("y", 0.0, "Measured process output")
        discrete = Fmi2Variability.discrete
        self.output("u", "Controller output, held between samples", lambda: self.controller.u, variability=discrete)
        self.output("e", "Control error r - y at the last sample", lambda: self.controller.e, variability=discrete)
        self.output("e_hat", "Predicted error the PI acted on at the last sample", lambda: self.controller.e_hat,
                    variability=discrete)
        self.output("a", "GM(1,1) development coefficient a(i) of the last fit", lambda: self.controller.predictor.a, unit="1",
                    variability=discrete)
        self.output("mode", "0 filling, 1 estimated, 2 predicted, 3 fallback (no valid model)",
                    lambda: float(self.controller.mode), unit="1", variability=discrete)

    def build(self) -> None:
        self.controller = Controller(
            self.Kc, self.Ti, self.Ts, n=self.n, m=self.m, ph=self.ph, B=self.B, a_min=self.a_min,
            threshold=self.threshold, anti_windup=bool(self.anti_windup), form=self.form, **self.output_limits(), **self.integral_options(),
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.controller.step(self.r, self.y)
