"""Band-limited white noise with the semantics of the Simulink block of the same name."""

from __future__ import annotations

import math

import numpy as np

from greyfmu.signals.clock import SampleClock

_BLOCK = 1024
"""Samples drawn per call to the generator; fixed so the sequence never depends on access order."""


class BandLimitedWhiteNoise:
    """Held Gaussian samples approximating white noise of power spectral density ``power``.

    Sample j is drawn from N(0, power/Ts) and held on
    ``[t0 + j·Ts, t0 + (j+1)·Ts)``, as Simulink's Band-Limited White
    Noise block does (its "noise power" is the PSD height; dividing by the sample time Ts
    keeps the integrated power independent of it).  The sequence is that of
    ``numpy.random.default_rng(seed).standard_normal()``, so ``value(t)`` depends only on
    the parameters and ``t``, not on how often or in which order it is asked.
    Times before ``t0`` return sample 0.
    """

    def __init__(self, power: float, Ts: float, seed: int = 0, t0: float = 0.0) -> None:
        if not (math.isfinite(power) and power >= 0.0):
            raise ValueError(f"BandLimitedWhiteNoise: power must be a finite number >= 0, got {power}")
        self.power = power
        self.seed = seed
        self.clock = SampleClock(Ts, t0)
        self._scale = math.sqrt(power / Ts)
        self._rng = np.random.default_rng(seed)
        self._block_index = -1
        self._block = np.empty(0)

    def value(self, t: float) -> float:
        return self._scale * self._sample(max(0, self.clock.index_at(t)))

    def _sample(self, j: int) -> float:
        block_index, offset = divmod(j, _BLOCK)
        if block_index < self._block_index:
            self._rng = np.random.default_rng(self.seed)
            self._block_index = -1
        while self._block_index < block_index:
            self._block = self._rng.standard_normal(_BLOCK)
            self._block_index += 1
        return float(self._block[offset])
