"""Static blocks: weighted sum and gain (no state, direct feedthrough)."""

from __future__ import annotations


class Sum:
    """``y = k1·u1 + k2·u2 + k3·u3``; signs in the weights make it a difference (k2 = −1: u1 − u2)."""

    def __init__(self, k1: float = 1.0, k2: float = 1.0, k3: float = 1.0) -> None:
        self.k1 = k1
        self.k2 = k2
        self.k3 = k3

    def output(self, u1: float, u2: float, u3: float) -> float:
        return self.k1 * u1 + self.k2 * u2 + self.k3 * u3


class Gain:
    """``y = k·u``."""

    def __init__(self, k: float = 1.0) -> None:
        self.k = k

    def output(self, u: float) -> float:
        return self.k * u
