"""PRBS source FMU: a thin wrapper around greyfmu.signals.PRBS."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, SourceSlave
from greyfmu.signals import PRBS as PRBSSignal


class PRBS(SourceSlave):
    description = (
        "Binary pseudo-random sequence: y = low or high, each level held for 'hold' seconds, bits from "
        "numpy.random.default_rng(seed) (the four-tank excitation of Pan, Shen & Luh 2012, Fig. 3). Evaluated "
        "at the FMU's current time. No inputs. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1500.0, step_size=1.0)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("low", 0.45, "Lower level")
        self.parameter("high", 1.0, "Upper level")
        self.parameter("hold", 100.0, "Time each level is held", unit="s")
        self.parameter("seed", 1, "Seed of the bit generator", minimum=0)
        self.source_output("PRBS output", Fmi2Variability.discrete)

    def build(self) -> None:
        if not self.hold > 0.0:
            raise ValueError(f"PRBS: hold must be > 0, got {self.hold}")
        self.signal = PRBSSignal(self.low, self.high, self.hold, self.seed, self.experiment_start)
