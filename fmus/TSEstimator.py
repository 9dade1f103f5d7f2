"""On-line TS model estimator FMU (global FRLS, local FRLS or MFRLS) on the four-tank levels."""

from enum import IntEnum
from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, Estimator, GreyfmuSlave
from greyfmu.control import FuzzyRLS
from greyfmu.control.four_tank_ts import regressor, table1_model
from greyfmu.signals import SampleClock



class Dominance(IntEnum):
    """The MFRLS mixing weight mu_m of a sample (greyfmu.control.ts_fuzzy.FuzzyRLS ``dominance``)."""

    MAX_FIRING = 1
    """The largest raw firing degree max tau_i of the sample (recovered-models.md §6)."""
    NORMALISED_MAX_MEMBERSHIP = 2
    """(R max lambda_i - 1)/(R - 1): 1 in one rule's core, 0 where all rules fire evenly (the paper's §3 wording)."""

    @property
    def rls_dominance(self) -> str:
        """The ``dominance`` name greyfmu.control.ts_fuzzy.FuzzyRLS takes."""
        return ("firing", "normalised")[self.value - 1]


class TSEstimator(GreyfmuSlave):
    description = (
        "On-line estimation of the consequents of Table 1's Takagi-Sugeno model of h1 and h2 (Pan, Shen & Luh "
        "2012, §5.1; antecedents reconstructed, see greyfmu.control.four_tank_ts) by global FRLS, local FRLS or "
        "MFRLS (our reconstruction of the paper's mixed FRLS, recovered-models.md §6). At every sample instant "
        "t0 + k Ts in [t, t+h) it predicts h_j(k) from the levels at k-1 with the current parameters (a-priori "
        "one-step prediction), then updates the parameters with the levels read at t. Outputs the predictions "
        "and the running mean absolute error (43); no direct feedthrough. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1500.0, step_size=1.0)
    output_dependencies = {"y_hat1": [], "y_hat2": [], "mae1": [], "mae2": []}
    sample_time = "Ts"
    wiring = {f"h{i}": "measurement" for i in range(1, 5)}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("method", Estimator.MFRLS, "On-line estimator: GLOBAL_FRLS, LOCAL_FRLS or MFRLS")
        self.parameter("forgetting", 0.99, "Forgetting factor in (0, 1]", unit="1", minimum=0.0, maximum=1.0)
        self.parameter("omega", 100.0, "Initial covariance C(0) = omega I")
        self.parameter("dominance", Dominance.NORMALISED_MAX_MEMBERSHIP, "MFRLS mixing weight: MAX_FIRING or NORMALISED_MAX_MEMBERSHIP")
        self.parameter("Ts", 1.0, "Sample period", unit="s")
        for i in range(1, 5):
            self.input(f"h{i}", 0.0, f"Measured level of tank {i}", unit="1")
        self.output("y_hat1", "A-priori prediction of h1", lambda: self.y_hat[0], unit="1", variability=Fmi2Variability.discrete)
        self.output("y_hat2", "A-priori prediction of h2", lambda: self.y_hat[1], unit="1", variability=Fmi2Variability.discrete)
        self.output("mae1", "Mean absolute error (43) of h1 so far", lambda: self.mae[0], unit="1", variability=Fmi2Variability.discrete)
        self.output("mae2", "Mean absolute error (43) of h2 so far", lambda: self.mae[1], unit="1", variability=Fmi2Variability.discrete)

    def build(self) -> None:
        self.estimators = [
            FuzzyRLS(table1_model(j), Estimator(self.method).rls_method, self.forgetting, self.omega, Dominance(self.dominance).rls_dominance)
            for j in (1, 2)
        ]
        self.clock = SampleClock(self.Ts, self.experiment_start)
        self.previous: np.ndarray | None = None
        self.y_hat = [0.0, 0.0]
        self.mae = [0.0, 0.0]
        self.count = 0
        self.error_sum = np.zeros(2)

    def advance(self, t: float, h: float) -> None:
        levels = np.array([self.h1, self.h2, self.h3, self.h4])
        for _ in self.clock.samples_in(t, h):
            if self.previous is not None:
                for j, estimator in enumerate(self.estimators):
                    error = estimator.update(self.previous, regressor(self.previous, j + 1), levels[j])
                    self.y_hat[j] = float(levels[j] - error)
                    self.error_sum[j] += abs(error)
                self.count += 1
                self.mae = list(self.error_sum / self.count)
            self.previous = levels

