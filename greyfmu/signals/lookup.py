"""One-dimensional lookup table: the "Fcn Gen" of the thesis's boiler-following scheme (ch. 4).

y = f(u) by linear interpolation between breakpoints (x_i, y_i), x strictly increasing; outside
the table either the end values are held (``extrapolate=False``) or the end segments are
extended (``extrapolate=True``, Simulink's 1-D Lookup Table default).  No state, direct
feedthrough.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class LookupTable:
    def __init__(self, x: Sequence[float], y: Sequence[float], extrapolate: bool = True) -> None:
        self.x = np.asarray(x, dtype=float)
        self.y = np.asarray(y, dtype=float)
        if self.x.ndim != 1 or self.x.shape != self.y.shape or len(self.x) < 2:
            raise ValueError(f"a lookup table needs at least two (x, y) breakpoints of equal count; got "
                             f"{len(self.x)} x and {len(self.y)} y")
        if not np.all(np.isfinite(self.x)) or not np.all(np.isfinite(self.y)):
            raise ValueError("lookup table breakpoints must be finite numbers")
        if np.any(np.diff(self.x) <= 0):
            bad = int(np.nonzero(np.diff(self.x) <= 0)[0][0])
            raise ValueError(f"lookup table x must be strictly increasing: x_{bad + 1} = {self.x[bad]:g} is not "
                             f"below x_{bad + 2} = {self.x[bad + 1]:g}")
        self.extrapolate = extrapolate

    def output(self, u: float) -> float:
        x, y = self.x, self.y
        if self.extrapolate and (u < x[0] or u > x[-1]):
            i = 0 if u < x[0] else len(x) - 2
            return float(y[i] + (y[i + 1] - y[i]) / (x[i + 1] - x[i]) * (u - x[i]))
        return float(np.interp(u, x, y))
