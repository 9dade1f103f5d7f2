"""Moving-window grey predictor with LDISPI data spacing and bias (thesis 000_*, §3.1.5, §3.1.6, §3.2).

Each ``update(x)`` is one sample of the signal.  The predictor keeps the last (n − 1)·m + 1
samples and fits the dynamic GM(1,1) (3.5e)/(3.6) to every m-th of them, oldest first, the
current sample last: the "large data interval and small predictive interval" method
(LDISPI, Method 3 of §3.1.6; m = 1 is the plain moving window).  The fit runs on the
biased samples x + B (3.29b) so that a signal of either sign is positive, as Theorem 3.1
needs; B is subtracted from the result again (3.29d).

The result, ``horizon`` samples ahead (a GM step is m samples, so the exponent of (3.29c)
becomes n − 1 + horizon/m), follows the rule of §4.2, "predict as the parameter a(i) of
GM(1,1) is larger than 0.035 ... if not, estimate the current output value": with
``threshold = SIGNED`` (the rule as printed; the default of `GrayPredictivePI`) predict
only when a > a_min, i.e. while the biased signal decays; ``MAGNITUDE`` (this class's
default) predicts when |a| > a_min, in either direction; with a_min = 0 it predicts always,
as the predictors of chapter 3 (Simulations 3.3-3.7, no threshold) do.  ``mode`` says which case applied:

- FILLING:   fewer than (n − 1)·m + 1 samples seen: the current sample is returned;
- ESTIMATED: the threshold not passed: ê(n) by (3.7b), the model's estimate of the current sample;
- PREDICTED: ê(n + horizon/m) by (3.29c)/(3.29d);
- FALLBACK:  no valid model — a biased sample <= 0 (B too small), C(i) = 0, or |a| >= 2
             (Remark 1): the current sample is returned.
"""

from __future__ import annotations

import math
from collections import deque
from enum import IntEnum
from itertools import islice

from greyfmu.grey.gm11 import gm11_coefficients, gm11_value


class PredictorMode(IntEnum):
    """Which rule produced the last output of `GreyPredictor` (see the module docstring)."""

    FILLING = 0
    ESTIMATED = 1
    PREDICTED = 2
    FALLBACK = 3


class Threshold(IntEnum):
    """The predict/estimate rule of §4.2 applied to the development coefficient a."""

    SIGNED = 1
    """a > a_min: "a(i) larger than 0.035", as §4.2 states it."""
    MAGNITUDE = 2
    """|a| > a_min: predict a rising as well as a decaying biased signal."""


class GreyPredictor:
    """GM(1,1) predictor on a moving window of n samples taken every m-th sample.

    ``n`` >= 3 (the thesis suggests 4 to 6), ``m`` >= 1, ``horizon`` >= 0 in samples of the
    signal (the time horizon is horizon·Ts), ``bias`` B >= 0 (3.29b), ``a_min`` >= 0 the
    threshold of the predict/estimate rule (the thesis uses 0.035 in Chapter 4) and
    ``threshold`` the form of that rule (`Threshold`).
    """

    def __init__(
        self,
        n: int = 4,
        m: int = 1,
        horizon: float = 20.0,
        bias: float = 0.0,
        a_min: float = 0.0,
        threshold: Threshold | int = Threshold.MAGNITUDE,
    ) -> None:
        if not (isinstance(n, int) and n >= 3):
            raise ValueError(f"GreyPredictor: window length n must be an integer >= 3, got {n!r}")
        if not (isinstance(m, int) and m >= 1):
            raise ValueError(f"GreyPredictor: data interval m must be an integer >= 1, got {m!r}")
        if not (math.isfinite(horizon) and horizon >= 0.0):
            raise ValueError(f"GreyPredictor: horizon must be a finite number >= 0 (samples), got {horizon}")
        if not (math.isfinite(bias) and bias >= 0.0):
            raise ValueError(f"GreyPredictor: bias B must be a finite number >= 0, got {bias}")
        if not (math.isfinite(a_min) and a_min >= 0.0):
            raise ValueError(f"GreyPredictor: a_min must be a finite number >= 0, got {a_min}")
        self.n = n
        self.m = m
        self.horizon = horizon
        self.bias = bias
        self.a_min = a_min
        self.threshold = Threshold(threshold)
        self._exponent_predict = n - 1 + horizon / m
        self._exponent_estimate = float(n - 1)
        self._history: deque[float] = deque(maxlen=(n - 1) * m + 1)
        self.reset()

    def reset(self) -> None:
        """Forget all samples."""
        self._history.clear()
        self.prediction = 0.0
        self.a = 0.0
        self.b = 0.0
        self.mode = PredictorMode.FILLING

    def update(self, x: float) -> float:
        """Take the current sample ``x`` and return the prediction ``horizon`` samples ahead (see the modes)."""
        if not math.isfinite(x):
            raise ValueError(f"GreyPredictor: sample {x} is not a finite number")
        history = self._history
        history.append(x)
        self.prediction = x
        if len(history) < history.maxlen:
            self.mode = PredictorMode.FILLING
            return x
        bias = self.bias
        window = [value + bias for value in islice(history, 0, None, self.m)]
        coefficients = gm11_coefficients(window) if min(window) > 0.0 else None
        if coefficients is None:
            self.mode = PredictorMode.FALLBACK
            return x
        a, b = self.a, self.b = coefficients
        if not abs(a) < 2.0:
            self.mode = PredictorMode.FALLBACK
            return x
        if (a if self.threshold is Threshold.SIGNED else abs(a)) > self.a_min:
            self.mode = PredictorMode.PREDICTED
            exponent = self._exponent_predict
        else:
            self.mode = PredictorMode.ESTIMATED
            exponent = self._exponent_estimate
        self.prediction = gm11_value(a, b, window[0], exponent) - bias
        return self.prediction
