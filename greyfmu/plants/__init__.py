"""Plant models as plain classes integrated exactly or accurately over a caller's step."""

from greyfmu.plants.delay import DelayLine
from greyfmu.plants.fopdt import FOPDT

__all__ = ["DelayLine", "FOPDT"]
