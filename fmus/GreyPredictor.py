"""Grey predictor FMU: a thin wrapper around greyfmu.grey.GreyPredictor."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.grey import GreyPredictor as Predictor
from greyfmu.grey import Threshold
from greyfmu.signals import SampleClock


class GreyPredictor(GreyfmuSlave):
    description = (
        "Moving-window GM(1,1) grey predictor (thesis 000_*, §3.1.5-3.1.6, (3.5e)-(3.7b), (3.29)): samples x every "
        "Ts, fits GM(1,1) to n samples spaced m samples apart (LDISPI; m = 1: plain window) after adding the bias B, "
        "and outputs the prediction ph seconds ahead minus B when |a| > a_min (threshold MAGNITUDE) or a > a_min (SIGNED), else "
        "the model's estimate of the "
        "current sample; the current sample itself until the window is full or when no valid model exists "
        "(biased sample <= 0, singular fit, |a| >= 2). Zero-order hold between samples, no direct feedthrough. "
        "Defaults: Simulation 3.3 CASE 1 (Ts = 1 s, n = 4, ph = 20 s). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=1.0)
    output_dependencies = {"x_hat": [], "a": [], "b": [], "mode": []}
    sample_time = "Ts"
    wiring = {"x": "measurement"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("Ts", 1.0, "Sample interval of the predictor", unit="s")
        self.parameter("n", 4, "Window length: samples per GM(1,1) fit (>= 3; the thesis uses 4-6)", minimum=3)
        self.parameter("m", 1, "Data interval (LDISPI): every m-th sample enters the window", minimum=1)
        self.parameter("ph", 20.0, "Prediction horizon", unit="s", minimum=0.0)
        self.parameter("B", 0.0, "Bias added before the fit, removed after it (3.29b)", minimum=0.0)
        self.parameter("a_min", 0.0, "Predict only when a passes a_min (see threshold), else estimate the current value", unit="1",
                       minimum=0.0)
        self.parameter("threshold", Threshold.MAGNITUDE, "Predict/estimate rule: SIGNED a > a_min (§4.2 as printed) or "
                       "MAGNITUDE |a| > a_min (with a_min = 0: always, chapter 3)")
        self.input("x", 0.0, "Signal to predict")
        self.output("x_hat", "Prediction ph ahead (held between samples)", lambda: self.predictor.prediction,
                    variability=Fmi2Variability.discrete)
        self.output("a", "GM(1,1) development coefficient a(i) of the last fit", lambda: self.predictor.a, unit="1",
                    variability=Fmi2Variability.discrete)
        self.output("b", "GM(1,1) grey input b(i) of the last fit", lambda: self.predictor.b,
                    variability=Fmi2Variability.discrete)
        self.output("mode", "0 filling, 1 estimated, 2 predicted, 3 fallback (no valid model)",
                    lambda: float(self.predictor.mode), unit="1", variability=Fmi2Variability.discrete)

    def build(self) -> None:
        self.predictor = Predictor(n=self.n, m=self.m, horizon=self.ph / self.Ts, bias=self.B, a_min=self.a_min,
                               threshold=self.threshold)
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.predictor.update(self.x)
