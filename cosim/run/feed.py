"""An input table's values set into the exchange during a run (`cosim.plan.inputs` bound the table to
the plan's inputs): `InputFeed` is the operation OP_FEED of the step's program (`cosim.run.program`).

Values follow FMI and fmpy (``fmpy.simulation.Input``):

* a continuous Real input is interpolated linearly between samples; a discrete one (Integer,
  Boolean, Enumeration, or a Real of variability discrete) holds the value of the last sample
  at or before the time;
* at an event time (a repeated time) the value from the right (the last row at that time) is
  taken, except while the FMU initialises, where it is the value from the left (the first row);
* before the first sample the first value holds, after the last the last.

A Co-Simulation master on a fixed grid sees the table at its communication points only: an
event between two of them takes effect at the next one (fmpy adds a communication point there
when the FMU can handle variable step sizes; `warn_off_grid` says which), and a Model Exchange FMU
gets its inputs held over each communication step (fmpy interpolates them within the step).
"""
from __future__ import annotations

import warnings
from math import isclose

import numpy as np

from ..model.grid import Grid
from ..model.structure import BoundTable


def warn_off_grid(bound: BoundTable, grid: Grid) -> None:
    """A `RuntimeWarning` naming the table's events that fall between the run's communication points."""
    off = [t for t in bound.event_times() if grid.start < t < grid.stop and not _on_grid(t, grid)]
    if off:
        shown = ", ".join(f"{t:g}" for t in off[:8]) + (f" and {len(off) - 8} more" if len(off) > 8 else "")
        warnings.warn(f"{bound.file}: input events at t = {shown} s fall between communication points "
                      f"(step {grid.step:g} s); each takes effect at the next one (fmpy adds a communication "
                      "point there for an FMU that can vary its step).", RuntimeWarning, stacklevel=3)


def _on_grid(t: float, grid: Grid) -> bool:
    k = round((t - grid.start) / grid.step)
    return isclose(t, grid.time(k), rel_tol=1e-9, abs_tol=1e-12 * max(1.0, abs(t)))


class InputFeed:
    """Writes the table's values at a time into the exchange's input buffers (``TypedBuffers.U``),
    by the buffers' input names; the first call (initialisation) takes left values at events."""

    def __init__(self, bound: BoundTable, typed: list):
        self.time = np.array(bound.time)
        self.initialising = True
        self.groups = []
        for ty in typed:
            if ty.strings:
                continue
            index = {n: i for i, n in enumerate(ty.in_names)}
            for discrete in (False, True):
                chosen = [t for t in bound.targets if t.name in index and t.discrete == discrete]
                if chosen:
                    self.groups.append((ty.U, np.array([index[t.name] for t in chosen], dtype=np.intp),
                                        np.array([t.values for t in chosen]), discrete))

    def __call__(self, t: float) -> None:
        after_event = not self.initialising
        self.initialising = False
        for buffer, positions, values, discrete in self.groups:
            buffer[positions] = interpolate(t, self.time, values, discrete, after_event)


def interpolate(time: float, t: np.ndarray, table: np.ndarray, discrete: bool, after_event: bool) -> np.ndarray:
    """The values of ``table`` (one row per signal, one column per sample at times ``t``) at
    ``time``, as ``fmpy.simulation.Input.interpolate`` computes them (times compared with
    `math.isclose`)."""
    n = len(t)
    if n < 2:
        return table[:, 0]
    i0 = int(np.searchsorted(t, time))
    if i0 == 0:
        return table[:, 0]
    if i0 == n:
        return table[:, -1]
    if discrete:
        i = i0 - 1
        if after_event:
            while i + 1 < n and (t[i + 1] < time or isclose(time, t[i + 1])):
                i += 1
        return table[:, i]
    if isclose(time, t[i0]) and i0 < n - 1 and isclose(t[i0], t[i0 + 1]):  # an event at time
        if after_event:
            while i0 < n - 1 and isclose(t[i0], t[i0 + 1]):
                i0 += 1
        return table[:, i0]
    t0, t1 = t[i0 - 1], t[i0]
    w0 = (t1 - time) / (t1 - t0)
    return w0 * table[:, i0 - 1] + (1 - w0) * table[:, i0]
