"""Gain-scheduled PID FMU: a thin wrapper around greyfmu.control.GainScheduledPID (thesis §2.3)."""

from typing import Any

from pythonfmu import DefaultExperiment, Fmi2Variability

from enum import IntEnum

from _slave import REQUIREMENTS, AntiWindup, GreyfmuSlave
from greyfmu.control import ITAE, DerivativeOn, GainSchedule, GainScheduledPID as Controller, Gains, Interpolation, OperatingPoint
from greyfmu.signals import SampleClock

MAX_POINTS = 8
"""FMI 2.0 has no array parameters: the table is n_points rows of the numbered scalars W_i, Kc_i, Ti_i, Td_i."""



class SchedulingLaw(IntEnum):
    """How the gains follow the scheduling variable (thesis §2.3.1): greyfmu.control.Interpolation or ITAE."""

    THRESHOLD = Interpolation.THRESHOLD
    """Switch from the gains of W_i to those of W_{i+1} at the midpoint W*_i."""
    FGS1 = Interpolation.FGS1
    """(2.6): Kc, Kc/Ti and Kc·Td linear in W."""
    FGS2 = Interpolation.FGS2
    """(2.7): Kc, Ti and Td linear in W."""
    MFGS = Interpolation.MFGS
    """(2.9): 1/Kc, Ti and Td linear in W."""
    ITAE = 4
    """(2.8): the ITAE rule on the process-parameter inputs Kp, T, tau (the table is unused)."""

# Simulation 2.5 of the thesis (dead time varies): the MFGS table at y = 0.76 and y = 7.
DEFAULT_TABLE = [(0.76, 8.0346, 7.1713, 1.5363), (7.0, 1.75, 23.52, 7.62)]


class GainScheduledPID(GreyfmuSlave):
    description = (
        "Gain-scheduled sampled PID u = Kc(W)[e + (1/Ti(W))∫e dt + Td(W) de/dt] (thesis (2.6a)/(2.7a)/(2.9a)). "
        "The gains come from a table of n_points operating points (W_i, Kc_i, Ti_i, Td_i), i = 1..n_points <= 8, "
        "W strictly increasing, interpolated by law: 0 = threshold switching at the midpoints, 1 = FGS1 (2.6), "
        "2 = FGS2 (2.7), 3 = MFGS (2.9), with W clamped to [W_1, W_n]; or 4 = the ITAE rule (2.8) with constants "
        "A..F computed from the process-parameter inputs Kp, T, tau (the table is then unused). The gains are "
        "scheduled at every sample from the inputs of that sample and handed to the PID of the PID FMU (same "
        "integral modes (2.10)-(2.12), derivative on the measurement or the error filtered by Td/N, limits, "
        "optional anti-windup). "
        "An unsorted table, a non-positive Ti_i or n_points outside 1..8 is refused at initialisation with a "
        "message naming the parameter; a non-finite input is refused by do_step (error status naming it). "
        "Sampled at Ts with zero-order hold, no direct feedthrough; Kc, Ti, Td are the gains of the last sample "
        "(before the first: the schedule at the current inputs). Defaults: Simulation 2.5's MFGS. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"u": [], "e": [], "Kc": [], "Ti": [], "Td": []}
    sample_time = "Ts"
    wiring = {"r": "setpoint", "y": "measurement", "W": "scheduling if law in 0 1 2 3",
              "Kp": "process if law in 4", "T": "process if law in 4", "tau": "process if law in 4", "u": "manipulated"}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter(
            "law", SchedulingLaw.MFGS, "Scheduling law: THRESHOLD, FGS1 (2.6), FGS2 (2.7), MFGS (2.9) or ITAE (2.8)"
        )
        self.parameter("n_points", 2, f"Number of operating points used, 1..{MAX_POINTS}", minimum=1, maximum=MAX_POINTS)
        for i in range(1, MAX_POINTS + 1):
            W, Kc, Ti, Td = DEFAULT_TABLE[i - 1] if i <= len(DEFAULT_TABLE) else (float(i), 1.0, 1.0, 0.0)
            used = f"operating point {i} (used if n_points >= {i})"
            self.parameter(f"W_{i}", W, f"Scheduling value of {used}; W_1 < W_2 < ...")
            self.parameter(f"Kc_{i}", Kc, f"Controller gain at {used}")
            self.parameter(f"Ti_{i}", Ti, f"Integral time at {used}, > 0", unit="s")
            self.parameter(f"Td_{i}", Td, f"Derivative time at {used}, >= 0", unit="s")
        for name, value in zip("ABCDEF", (1.357, 0.947, 1.176, 0.738, 0.381, 0.995)):
            self.parameter(name, value, f"ITAE constant {name} of (2.8) (law = ITAE only)", unit="1")
        self.parameter("N", 10.0, "Derivative filter factor: filter time constant Td/N", unit="1")
        self.parameter("Ts", 0.1, "Sample time", unit="s")
        self.parameter("anti_windup", AntiWindup.CONDITIONAL_INTEGRATION,
                       "Anti-windup: CONDITIONAL_INTEGRATION at the output limits (ours) or NONE (the thesis's PI)")
        self.parameter("derivative_on", DerivativeOn.MEASUREMENT, "Signal the D term differentiates: MEASUREMENT -y "
                       "(ours, no set-point kick) or ERROR e (the thesis's Td de/dt, (2.6a))")
        self.output_limit_parameters()
        self.integral_parameters()
        self.input("r", 0.0, "Set-point")
        self.input("y", 0.0, "Measured process output")
        self.input("W", 0.0, "Scheduling variable (process output, set-point or exogenous signal; laws 0-3)")
        self.input("Kp", 0.2, "Process gain (law = 4 only)")
        self.input("T", 20.0, "Process time constant (law = 4 only)", unit="s")
        self.input("tau", 4.0, "Process dead time (law = 4 only)", unit="s")
        discrete = Fmi2Variability.discrete
        self.output("u", "Controller output, held between samples", lambda: self.controller.u, variability=discrete)
        self.output("e", "Control error r - y at the last sample", lambda: self.controller.e, variability=discrete)
        self.output("Kc", "Scheduled controller gain", lambda: self._gains().Kc, variability=discrete)
        self.output("Ti", "Scheduled integral time", lambda: self._gains().Ti, unit="s", variability=discrete)
        self.output("Td", "Scheduled derivative time", lambda: self._gains().Td, unit="s", variability=discrete)

    def build(self) -> None:
        if self.law == SchedulingLaw.ITAE:
            itae = ITAE(self.A, self.B, self.C, self.D, self.E, self.F)
            schedule = lambda process: itae(*process)  # noqa: E731
        else:
            if not 1 <= self.n_points <= MAX_POINTS:
                raise ValueError(f"n_points = {self.n_points}: the table needs 1 to {MAX_POINTS} operating points")
            rows = range(1, self.n_points + 1)
            points = [
                OperatingPoint(getattr(self, f"W_{i}"), getattr(self, f"Kc_{i}"), getattr(self, f"Ti_{i}"), getattr(self, f"Td_{i}"))
                for i in rows
            ]
            schedule = GainSchedule(points, Interpolation(self.law))
        self.controller = Controller(
            schedule,
            self.Ts,
            N=self.N,
            anti_windup=bool(self.anti_windup),
            derivative_on=self.derivative_on,
            **self.output_limits(),
            **self.integral_options(),
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def _scheduling_variable(self) -> float | tuple[float, float, float]:
        return (self.Kp, self.T, self.tau) if self.law == SchedulingLaw.ITAE else self.W

    def _gains(self) -> Gains:
        gains = self.controller.gains
        return gains if gains is not None else self.controller.schedule(self._scheduling_variable())

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.controller.step(self.r, self.y, W=self._scheduling_variable())
