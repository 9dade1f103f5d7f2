"""Sources and blocks a wiring needs: step, ramp, pulse, band-limited white noise, first-order filter, sum, gain."""

from greyfmu.signals.arithmetic import Gain, Sum
from greyfmu.signals.clock import SampleClock, time_reached
from greyfmu.signals.filters import FirstOrderFilter
from greyfmu.signals.noise import BandLimitedWhiteNoise
from greyfmu.signals.sources import Pulse, Ramp, Step

__all__ = [
    "BandLimitedWhiteNoise",
    "FirstOrderFilter",
    "Gain",
    "Pulse",
    "Ramp",
    "SampleClock",
    "Step",
    "Sum",
    "time_reached",
]

from greyfmu.signals.lookup import LookupTable

__all__ += ["LookupTable"]

from greyfmu.signals.prbs import PRBS

__all__ += ["PRBS"]
