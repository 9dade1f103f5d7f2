"""Continuous MIMO LTI plant in innovation form with input delays: a thin wrapper around greyfmu.plants.StochasticLTI."""

from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.control.digital_pi.examples import ch47
from greyfmu.plants import StochasticLTI as StochasticLTIPlant

MAX_STATES = 8
MAX_CHANNELS = 3
_DEFAULT = ch47()


class StochasticLTI(GreyfmuSlave):
    description = (
        "Zhou et al. (2006) plant (1)-(2): dx/dt = A x + B u(t - tau) + V eta, y = C x + eta + d, with up to "
        f"{MAX_STATES} states and {MAX_CHANNELS} inputs/outputs (matrices as numbered scalars M_i_j, 1-based; "
        "entries beyond n, m, p are ignored). tau_i_j delays u_j in row i of B. eta: white innovations of "
        "covariance Qeta held over noise_period (seeded), so at noise_period = T the sampled plant is exactly "
        "the discrete model (4)-(8). d: step disturbances on the outputs (direct feedthrough to y). Integrated "
        "exactly (matrix exponential per piece, split where a delayed input switches or a noise sample starts), "
        "independent of the master's step; u = 0 before the start. Defaults: the CH-47 helicopter of "
        "Example 2 (recovered-models.md section 2), tau = T/2 = 0.005 s, reconstructed noise. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=4.0, step_size=0.005)
    output_dependencies = {f"y{i}": [f"d{i}"] for i in range(1, MAX_CHANNELS + 1)}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        plant = _DEFAULT.plant
        self.parameter("n", plant.n, "Number of states", minimum=1, maximum=MAX_STATES)
        self.parameter("m", plant.m, "Number of inputs", minimum=1, maximum=MAX_CHANNELS)
        self.parameter("p", plant.p, "Number of outputs", minimum=1, maximum=MAX_CHANNELS)
        tau = np.where(plant.B != 0.0, _DEFAULT.tau, 0.0)
        self._matrices = {
            "A": (plant.A, MAX_STATES, MAX_STATES, "State matrix A"),
            "B": (plant.B, MAX_STATES, MAX_CHANNELS, "Input matrix B"),
            "tau": (tau, MAX_STATES, MAX_CHANNELS, "Input delay of entry B"),
            "C": (plant.C, MAX_CHANNELS, MAX_STATES, "Output matrix C"),
            "V": (plant.V, MAX_STATES, MAX_CHANNELS, "Innovation gain V"),
            "Qeta": (_DEFAULT.Q_eta, MAX_CHANNELS, MAX_CHANNELS, "Innovation covariance Q_eta"),
        }
        for name, (default, rows, columns, text) in self._matrices.items():
            for i in range(rows):
                for j in range(columns):
                    start = float(default[i, j]) if i < default.shape[0] and j < default.shape[1] else 0.0
                    unit = "s" if name == "tau" else None
                    self.parameter(f"{name}_{i + 1}_{j + 1}", start, f"{text}, row {i + 1}, column {j + 1}",
                                   unit=unit, minimum=0.0 if name == "tau" else None)
        self.parameter("noise_period", _DEFAULT.Ts, "Hold time of each innovation sample (the controller's T)",
                       unit="s", minimum=1e-12)
        self.parameter("seed", 0, "Seed of the innovation sequence")
        for i in range(1, MAX_CHANNELS + 1):
            self.input(f"u{i}", 0.0, f"Input {i} (ignored when i > m)")
        for i in range(1, MAX_CHANNELS + 1):
            self.input(f"d{i}", 0.0, f"Step disturbance added to output {i}")
        for i in range(1, MAX_CHANNELS + 1):
            self.output(f"y{i}", f"Output {i}: C x + eta + d (0 when i > p)", lambda i=i: self._y(i))

    def _matrix(self, name: str, rows: int, columns: int) -> np.ndarray:
        """The active rows x columns block of the numbered parameters name_i_j (entries outside are ignored)."""
        return np.array([[getattr(self, f"{name}_{i + 1}_{j + 1}") for j in range(columns)] for i in range(rows)],
                        dtype=float)

    def build(self) -> None:
        n, m, p = self.n, self.m, self.p
        self.plant = StochasticLTIPlant(
            self._matrix("A", n, n), self._matrix("B", n, m), self._matrix("C", p, n), self._matrix("V", n, p),
            self._matrix("tau", n, m), self._matrix("Qeta", p, p), self.noise_period, self.seed,
            self.experiment_start)

    def _y(self, i: int) -> float:
        if i > self.p:
            return 0.0
        return float(self.plant.output()[i - 1]) + getattr(self, f"d{i}")

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, np.array([getattr(self, f"u{j}") for j in range(1, self.m + 1)]))
