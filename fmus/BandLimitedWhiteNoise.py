"""Band-limited white noise FMU: a thin wrapper around greyfmu.signals.BandLimitedWhiteNoise."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, SourceSlave
from greyfmu.signals import BandLimitedWhiteNoise as Noise


class BandLimitedWhiteNoise(SourceSlave):
    description = (
        "Band-limited white noise with Simulink semantics: sample j ~ N(0, power/Ts), held on "
        "[t0 + j*Ts, t0 + (j+1)*Ts), reproducible from seed (numpy.random.default_rng). Evaluated at the "
        "FMU's current time, independent of the master's step (after do_step(t, h): y(t + h); after "
        "initialisation: y(t0)). No inputs. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("power", 0.1, "Noise power: height of the power spectral density", minimum=0.0)
        self.parameter("Ts", 0.1, "Sample time: each sample is held this long", unit="s")
        self.parameter("seed", 23341, "Seed of the random number generator")
        self.source_output("Noise output", Fmi2Variability.discrete)

    def build(self) -> None:
        self.signal = Noise(self.power, self.Ts, self.seed, self.experiment_start)
