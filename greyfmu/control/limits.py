"""Output limits of a sampled controller: a rate limit per second and a range, checked once, applied once.

Shared by ``PID`` (thesis (2.6a) with practical limits) and ``SOPDTPredictive`` (Cîrtoaje et
al., the limits under which the free response (9)-(10) uses the applied input).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class OutputLimits:
    """``u(k)`` limited to ``u(k−1) ± du_max·Ts`` (``du_max`` per second, 0 or inf = none), then to
    ``[u_min, u_max]`` (the range wins).  ``owner`` names the controller in error messages."""

    owner: str
    Ts: float
    u_min: float = -math.inf
    u_max: float = math.inf
    du_max: float = 0.0

    def __post_init__(self) -> None:
        if not self.u_min <= self.u_max:
            raise ValueError(f"{self.owner}: output limits need u_min <= u_max, got u_min = {self.u_min}, u_max = {self.u_max}")
        if not self.du_max >= 0.0:
            raise ValueError(f"{self.owner}: rate limit du_max must be >= 0 (0 = none), got {self.du_max}")

    def check_start(self, u0: float) -> None:
        """Refuse an initial output outside the range (a bumpless start needs a reachable u0)."""
        if not (math.isfinite(u0) and self.u_min <= u0 <= self.u_max):
            raise ValueError(f"{self.owner}: initial output u0 must lie in [u_min, u_max] = [{self.u_min}, {self.u_max}], got {u0}")

    @property
    def du_per_sample(self) -> float:
        """Largest move in one sample, ``du_max·Ts`` (inf without a rate limit)."""
        return self.du_max * self.Ts if self.du_max > 0.0 else math.inf

    def apply(self, v: float, u_prev: float) -> float:
        """The unlimited output v limited by rate (around u_prev) and then by range."""
        rate = self.du_per_sample
        v = min(max(v, u_prev - rate), u_prev + rate)
        return min(max(v, self.u_min), self.u_max)
