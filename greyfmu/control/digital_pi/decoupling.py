"""Static decoupling: the proportional gain K1 = G_p(0)^{-1} of Zhou et al. (2006) (15)."""

from __future__ import annotations

import numpy as np

from greyfmu.control.digital_pi.discretize import ContinuousPlant
from greyfmu.control.digital_pi.errors import DesignError

CONDITION_LIMIT = 1e12
"""Condition number above which A or G_p(0) counts as singular."""


def static_gain(plant: ContinuousPlant) -> np.ndarray:
    """``G_p(0) = −C A^{-1} B`` (delays do not change it); refused when A is singular (a pole at s = 0)."""
    if np.linalg.cond(plant.A) > CONDITION_LIMIT:
        raise DesignError("A is singular: the plant has a pole at s = 0 and no static gain G_p(0)")
    return -plant.C @ np.linalg.solve(plant.A, plant.B)


def static_decoupling(plant: ContinuousPlant) -> np.ndarray:
    """``K1 = G_p(0)^{-1}`` (15).  The plant must be square with a nonsingular static gain; no pseudo-inverse."""
    if plant.m != plant.p:
        raise DesignError(f"static decoupling needs a square plant, got {plant.p} outputs and {plant.m} inputs")
    gain = static_gain(plant)
    if np.linalg.cond(gain) > CONDITION_LIMIT:
        raise DesignError(f"the static gain G_p(0) = {np.round(gain, 6).tolist()} is singular; K1 = G_p(0)^-1 "
                          "does not exist")
    return np.linalg.inv(gain)
