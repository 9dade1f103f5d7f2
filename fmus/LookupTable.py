"""One-dimensional lookup table FMU ("Fcn Gen"): a thin wrapper around greyfmu.signals.LookupTable."""

from enum import IntEnum
from typing import Any

from pythonfmu import DefaultExperiment

from _slave import REQUIREMENTS, GreyfmuSlave
from greyfmu.plants.boiler_turbine import PRESSURE_SCHEDULE
from greyfmu.signals import LookupTable as Table

MAX_POINTS = 8


class Extrapolation(IntEnum):
    """The table's output outside its breakpoints."""

    HOLD = 0
    """Hold the end values."""
    LINEAR = 1
    """Extend the end segments."""


class LookupTable(GreyfmuSlave):
    description = (
        f"Lookup table y = f(u), linear between n_points breakpoints (x_i, y_i), i = 1..n_points <= {MAX_POINTS}, "
        "x strictly increasing; outside the table the end segments are extended (extrapolate = LINEAR) or the end "
        "values held (HOLD). Defaults: the thesis's ch. 4 'Fcn Gen', load [MW] -> pressure setpoint [kgf/cm2]: "
        "58/76/101 MW -> 86/109/140. Direct feedthrough. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=100.0, step_size=0.1)
    output_dependencies = {"y": ["u"]}

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("n_points", len(PRESSURE_SCHEDULE), f"Number of breakpoints used (2..{MAX_POINTS})",
                       minimum=2, maximum=MAX_POINTS)
        self.parameter("extrapolate", Extrapolation.LINEAR, "Outside the table: LINEAR extends the end segments, HOLD holds the end values")
        for i in range(1, MAX_POINTS + 1):
            x, y = PRESSURE_SCHEDULE[i - 1] if i <= len(PRESSURE_SCHEDULE) else (float(i * 1000), 0.0)
            self.parameter(f"x_{i}", x, f"Breakpoint {i}: input value (used when i <= n_points)")
            self.parameter(f"y_{i}", y, f"Breakpoint {i}: output value (used when i <= n_points)")
        self.input("u", PRESSURE_SCHEDULE[1][0], "Input")
        self.output("y", "Table value at the input", lambda: self.table.output(self.u))

    def build(self) -> None:
        n = self.n_points
        self.table = Table([getattr(self, f"x_{i}") for i in range(1, n + 1)],
                           [getattr(self, f"y_{i}") for i in range(1, n + 1)], bool(self.extrapolate))

    def advance(self, t: float, h: float) -> None:
        """Stateless: the output follows the input when read."""
