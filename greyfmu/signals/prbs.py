"""Binary pseudo-random sequence (PRBS) source, as used to excite the four-tank model (seed 003, Fig. 3)."""

from __future__ import annotations

import math

import numpy as np

from greyfmu.signals.clock import SampleClock

_BLOCK = 1024


class PRBS:
    """Random binary signal: ``low`` or ``high``, each level held ``hold`` seconds from ``t0``.

    Level j (on ``[t0 + j·hold, t0 + (j+1)·hold)``) is bit j of
    ``numpy.random.default_rng(seed).integers(0, 2)`` drawn in blocks of 1024, so ``value(t)``
    depends only on the parameters and t.  Times before ``t0`` return level 0.
    """

    def __init__(self, low: float, high: float, hold: float, seed: int = 0, t0: float = 0.0) -> None:
        if not (math.isfinite(low) and math.isfinite(high)):
            raise ValueError(f"PRBS: levels must be finite, got low = {low}, high = {high}")
        self.low = low
        self.high = high
        self.clock = SampleClock(hold, t0)
        self._rng = np.random.default_rng(seed)
        self._bits = np.empty(0, dtype=np.int64)

    def value(self, t: float) -> float:
        index = max(0, self.clock.index_at(t))
        while index >= len(self._bits):
            self._bits = np.concatenate([self._bits, self._rng.integers(0, 2, size=_BLOCK)])
        return self.high if self._bits[index] else self.low
