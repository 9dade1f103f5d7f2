"""The digital PI of Zhou et al. (2006) as a sampled controller: law (18)/(36) with the innovation observer."""

from __future__ import annotations

import numpy as np

from greyfmu.control.digital_pi.design import DigitalPIDesign


class DigitalPI:
    """One ``step(r, y) -> u`` per sample (r, y, u vectors):

        e = r − y,  u = −F x̂_a − K2 z + K1 e,  z ← z + Hc e,
        x̂_a ← Gp x̂_a + Hp u + Γp (y − Cp x̂_a)        (observer of Example 1 / (47) on (9)/(10))

    The state starts at zero (plant at rest at the origin).
    """

    def __init__(self, Gp: np.ndarray, Hp: np.ndarray, Gammap: np.ndarray, Cp: np.ndarray,
                 F: np.ndarray, K1: np.ndarray, K2: np.ndarray, Hc: np.ndarray) -> None:
        self.Gp, self.Hp, self.Gammap, self.Cp = Gp, Hp, Gammap, Cp
        self.F, self.K1, self.K2, self.Hc = F, K1, K2, Hc
        na, m = Hp.shape
        p = Cp.shape[0]
        shapes = {"Gp": (Gp, (na, na)), "Gammap": (Gammap, (na, p)), "Cp": (Cp, (p, na)), "F": (F, (m, na)),
                  "K1": (K1, (m, p)), "K2": (K2, (m, p)), "Hc": (Hc, (p, p))}
        for name, (matrix, shape) in shapes.items():
            if matrix.shape != shape:
                raise ValueError(f"DigitalPI: {name} must have shape {shape}, got {matrix.shape}")
        self.reset()

    @classmethod
    def from_design(cls, design: DigitalPIDesign) -> DigitalPI:
        """The controller of a design (its augmented observer model and gains)."""
        a = design.augmented
        return cls(a.Gp, a.Hp, a.Gammap, a.Cp, design.F, design.K1, design.K2, design.Hc)

    def reset(self) -> None:
        """Back to zero observer state, integrator, output and error."""
        self.x_hat = np.zeros(self.Gp.shape[0])
        self.z = np.zeros(self.Hc.shape[0])
        self.u = np.zeros(self.Hp.shape[1])
        self.e = np.zeros(self.Cp.shape[0])

    def step(self, r: np.ndarray, y: np.ndarray) -> np.ndarray:
        """One sample with set-points r and measurements y; returns u(k) (law (18)/(36), then the observer update)."""
        y = np.asarray(y, dtype=float)
        self.e = np.asarray(r, dtype=float) - y
        self.u = -self.F @ self.x_hat - self.K2 @ self.z + self.K1 @ self.e
        self.z = self.z + self.Hc @ self.e
        self.x_hat = self.Gp @ self.x_hat + self.Hp @ self.u + self.Gammap @ (y - self.Cp @ self.x_hat)
        return self.u
