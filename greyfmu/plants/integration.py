"""Classical fourth-order Runge–Kutta over a communication step in equal sub-steps (design.md §3:
plants integrate exactly or with RK4 sub-steps); shared by ``BoilerTurbine`` and ``SteamHeader``."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

Derivative = Callable[[float, NDArray[np.float64]], NDArray[np.float64]]
"""dx/ds at the time s ∈ [0, h] since the start of the step and the state x."""


def substeps(h: float, max_substep: float) -> int:
    """Fewest equal sub-steps of [0, h] none longer than ``max_substep`` (at least one)."""
    return max(1, math.ceil(h / max_substep - 1e-9))


def rk4(f: Derivative, x: NDArray[np.float64], h: float, max_substep: float) -> NDArray[np.float64]:
    """The state after integrating dx/ds = f(s, x) from x over [0, h] with RK4 in ``substeps(h, max_substep)`` steps."""
    n = substeps(h, max_substep)
    dt = h / n
    for i in range(n):
        s = i * dt
        k1 = f(s, x)
        k2 = f(s + dt / 2, x + dt / 2 * k1)
        k3 = f(s + dt / 2, x + dt / 2 * k2)
        k4 = f(s + dt, x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x
