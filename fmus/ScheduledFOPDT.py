"""FOPDT plant whose gain, lag and dead time move with its output: a thin wrapper around greyfmu.plants.ScheduledFOPDT."""

from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants import PiecewiseParameter, ScheduledFOPDT as Plant

# Simulation 2.1 of the thesis: Kp(y) = 0.2 (y <= 0.76), sqrt(y - 0.72), 2.5 (y >= 7); T = 20 s; tau = 4 s.
# Each entry: (lo, hi, y_lo, y_hi, a, b, c, n) of p(y) = lo / a(b y + c)^n / hi.
DEFAULTS = {
    "Kp": ((0.2, 2.5, 0.76, 7.0, 1.0, 1.0, -0.72, 0.5), None, "Process gain"),
    "T": ((20.0, 20.0, 0.76, 7.0, 20.0, 0.0, 1.0, 1.0), "s", "Time constant"),
    "tau": ((4.0, 4.0, 0.76, 7.0, 4.0, 0.0, 1.0, 1.0), "s", "Dead time"),
}


class ScheduledFOPDT(GreyfmuSlave):
    description = (
        "Process (2.13) of the thesis: T(y) dx/dt + x = Kp(y) (u + d), y(t) = x(t - tau(y(t - D))), with d a load "
        "disturbance at the plant input. Each of Kp, T, tau is a piecewise function of the output: P_lo for "
        "y <= P_y_lo, P_hi for y >= P_y_hi, P_a (P_b y + P_c)^P_n in between (Situations 1-6 of §2.3.3: linear, "
        "above- or below-linear, increasing, decreasing, constant). The inputs are held from each communication "
        "point; x is integrated in sub-steps of at most dt with Kp, T frozen at the output at each sub-step's "
        "start and solved exactly, and the output reads the exact history of x (constant parameters: exact "
        "whatever the step). Starts in equilibrium at y0 (x = y = y0 in the past). No direct feedthrough. "
        "Outputs the current Kp, T, tau too, so an ITAE-tuned controller can use them. Defaults: "
        "Simulation 2.1 (gain varies). " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": [], "Kp": [], "T": [], "tau": []}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        for name, (values, unit, label) in DEFAULTS.items():
            lo, hi, y_lo, y_hi, a, b, c, n = values
            self.parameter(f"{name}_lo", lo, f"{label} for y <= {name}_y_lo", unit=unit)
            self.parameter(f"{name}_hi", hi, f"{label} for y >= {name}_y_hi", unit=unit)
            self.parameter(f"{name}_y_lo", y_lo, f"Output below which the {label.lower()} is {name}_lo")
            self.parameter(f"{name}_y_hi", y_hi, f"Output above which the {label.lower()} is {name}_hi")
            middle = f"{name}_a ({name}_b y + {name}_c)^{name}_n between {name}_y_lo and {name}_y_hi"
            self.parameter(f"{name}_a", a, f"{label} {middle}: factor a", unit=unit)
            self.parameter(f"{name}_b", b, f"{label} {middle}: slope b")
            self.parameter(f"{name}_c", c, f"{label} {middle}: offset c")
            self.parameter(f"{name}_n", n, f"{label} {middle}: power n")
        self.parameter("y0", 0.0, "Initial output (the plant starts in equilibrium)")
        self.parameter("D", 0.01, "Small delay of the output that sets the dead time, tau(y(t - D))", unit="s", minimum=0.0)
        self.parameter("dt", 0.01, "Longest internal integration sub-step", unit="s")
        self.input("u", 0.0, "Manipulated variable")
        self.input("d", 0.0, "Load disturbance, added to u at the plant input")
        self.output("y", "Process output", lambda: self.plant.y)
        self.output("Kp", "Process gain Kp(y) at the current output", lambda: self.plant.Kp)
        self.output("T", "Time constant T(y) at the current output", lambda: self.plant.T, unit="s")
        self.output("tau", "Dead time tau(y(t - D)) in effect", lambda: self.plant.tau, unit="s")

    def _function(self, name: str) -> PiecewiseParameter:
        keys = ("lo", "hi", "y_lo", "y_hi", "a", "b", "c", "n")
        return PiecewiseParameter(*(getattr(self, f"{name}_{key}") for key in keys))

    def build(self) -> None:
        self.plant = Plant(self._function("Kp"), self._function("T"), self._function("tau"), self.y0, self.D, self.dt)

    def advance(self, t: float, h: float) -> None:
        self.plant.advance(t, h, self.u, self.d)
