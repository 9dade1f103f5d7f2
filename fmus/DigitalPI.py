"""Centralised digital PI with Kalman innovation observer: a thin wrapper around greyfmu.control.digital_pi.DigitalPI."""

from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.control.digital_pi import MAX_CHANNELS, MAX_ORDER, DigitalPI as DigitalPIController, design_digital_pi
from greyfmu.control.digital_pi.examples import ch47
from greyfmu.signals import SampleClock

_EXAMPLE = ch47()
_DEFAULT = design_digital_pi(_EXAMPLE.plant, _EXAMPLE.Ts, _EXAMPLE.tau, _EXAMPLE.alpha, _EXAMPLE.beta,
                             _EXAMPLE.q, _EXAMPLE.r)


class DigitalPI(GreyfmuSlave):
    description = (
        "Zhou et al. (2006) centralised digital PI, law (18)/(36): u = -F xhat - K2 z + K1 e, z(k+1) = z + Hc e, "
        "e = r - y, with the Kalman innovation observer xhat(k+1) = Gp xhat + Hp u + Gammap (y - Cp xhat) on the "
        "delay-augmented plant (9)/(10). The design comes as numbered scalar parameters (M_i_j, 1-based, entries beyond na, m ignored; "
        f"augmented order na <= {MAX_ORDER}, m = p <= {MAX_CHANNELS} channels) written into an .ssv by "
        "greyfmu.control.digital_pi.write_design_ssv. Sampled at Ts with zero-order hold: do_step(t, h) computes "
        "every sample instant in [t, t+h) from the inputs set at t; no direct feedthrough. Defaults: the CH-47 "
        "design of Example 2 (T = 0.01 s, tau = T/2, Q = 10 I, R = I, alpha = 1, beta = 0). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=4.0, step_size=0.01)
    output_dependencies = {**{f"u{i}": [] for i in range(1, MAX_CHANNELS + 1)},
                           **{f"e{i}": [] for i in range(1, MAX_CHANNELS + 1)}}
    sample_time = "Ts"
    wiring = {**{f"r{i}": "setpoint" + (f" if m >= {i}" if i > 1 else "") for i in range(1, MAX_CHANNELS + 1)},
              **{f"y{i}": "measurement" + (f" if m >= {i}" if i > 1 else "") for i in range(1, MAX_CHANNELS + 1)},
              **{f"u{i}": "manipulated" for i in range(1, MAX_CHANNELS + 1)}}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        a = _DEFAULT.augmented
        self.parameter("Ts", _DEFAULT.Ts, "Sample time T", unit="s", minimum=1e-12)
        self.parameter("na", a.order, "Order of the augmented plant (9)/(10): n + D m", minimum=1, maximum=MAX_ORDER)
        self.parameter("m", a.Hp.shape[1], "Number of inputs = outputs", minimum=1, maximum=MAX_CHANNELS)
        self._shapes = {
            "Gp": (a.Gp, MAX_ORDER, MAX_ORDER, "Augmented plant matrix Gp (9)/(10)"),
            "Hp": (a.Hp, MAX_ORDER, MAX_CHANNELS, "Augmented input matrix Hp"),
            "Gammap": (a.Gammap, MAX_ORDER, MAX_CHANNELS, "Augmented innovation gain Gammap (Kalman gain)"),
            "Cp": (a.Cp, MAX_CHANNELS, MAX_ORDER, "Augmented output matrix Cp"),
            "F": (_DEFAULT.F, MAX_CHANNELS, MAX_ORDER, "State-feedback gain F (21)"),
            "K1": (_DEFAULT.K1, MAX_CHANNELS, MAX_CHANNELS, "Static decoupling gain K1 = Gp(0)^-1"),
            "K2": (_DEFAULT.K2, MAX_CHANNELS, MAX_CHANNELS, "PI state gain K2 (21)"),
            "Hc": (_DEFAULT.Hc, MAX_CHANNELS, MAX_CHANNELS, "PI state input matrix Hc (16)"),
        }
        for name, (default, rows, columns, text) in self._shapes.items():
            for i in range(rows):
                for j in range(columns):
                    start = float(default[i, j]) if i < default.shape[0] and j < default.shape[1] else 0.0
                    self.parameter(f"{name}_{i + 1}_{j + 1}", start, f"{text}, row {i + 1}, column {j + 1}")
        for i in range(1, MAX_CHANNELS + 1):
            self.input(f"r{i}", 0.0, f"Set-point {i}")
        for i in range(1, MAX_CHANNELS + 1):
            self.input(f"y{i}", 0.0, f"Measured output {i}")
        for i in range(1, MAX_CHANNELS + 1):
            self.output(f"u{i}", f"Control input {i}, held between samples (0 when i > m)",
                        lambda i=i: self._held(self.controller.u, i), variability=Fmi2Variability.discrete)
        for i in range(1, MAX_CHANNELS + 1):
            self.output(f"e{i}", f"Control error r{i} - y{i} at the last sample (0 when i > m)",
                        lambda i=i: self._held(self.controller.e, i), variability=Fmi2Variability.discrete)

    def _matrix(self, name: str, rows: int, columns: int) -> np.ndarray:
        """The active rows x columns block of the numbered parameters name_i_j (entries outside are ignored)."""
        return np.array([[getattr(self, f"{name}_{i + 1}_{j + 1}") for j in range(columns)] for i in range(rows)],
                        dtype=float)

    def build(self) -> None:
        na, m = self.na, self.m
        self.controller = DigitalPIController(
            self._matrix("Gp", na, na), self._matrix("Hp", na, m), self._matrix("Gammap", na, m),
            self._matrix("Cp", m, na), self._matrix("F", m, na), self._matrix("K1", m, m),
            self._matrix("K2", m, m), self._matrix("Hc", m, m))
        self.clock = SampleClock(self.Ts, self.experiment_start)

    @staticmethod
    def _held(values: np.ndarray, i: int) -> float:
        return float(values[i - 1]) if i <= len(values) else 0.0

    def advance(self, t: float, h: float) -> None:
        m = self.m
        for _ in self.clock.samples_in(t, h):
            r = np.array([getattr(self, f"r{i}") for i in range(1, m + 1)])
            y = np.array([getattr(self, f"y{i}") for i in range(1, m + 1)])
            self.controller.step(r, y)
