"""Control-loop metrics on results, and result comparison for regression use.

`step_metrics` measures a response to the setpoint's last change (or from a given t0):
IAE = ∫|e| dt, ISE = ∫e² dt, ITAE = ∫(t − t0)|e| dt with e = r − y (trapezoidal rule on the
recorded samples), overshoot in % of the step, 10–90 % rise time and the settling time into
a band of ±2 % of the step (by default).  The step is the setpoint's change at t0; measured
from the first sample, it is the distance from the initial output to the setpoint.  Overshoot, rise and settling time are NaN when the
setpoint does not change after t0 (a pure disturbance run) or when the response never gets
there.  `compare` checks two results signal by signal within rtol/atol.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .errors import SetupError, did_you_mean

METRICS = ("IAE", "ISE", "ITAE", "overshoot", "rise_time", "settling_time")


def _trapezoid(values: np.ndarray, time: np.ndarray) -> float:
    return float(np.sum((values[1:] + values[:-1]) * np.diff(time)) / 2) if len(time) > 1 else 0.0


def last_change(time: np.ndarray, r: np.ndarray) -> float:
    """The time of the setpoint's last change (the first sample if it never changes)."""
    changed = np.nonzero(np.diff(r))[0]
    return float(time[changed[-1] + 1]) if len(changed) else float(time[0])


def step_metrics(time: np.ndarray, y: np.ndarray, r: np.ndarray, *, t0: float | None = None,
                 t1: float | None = None, band: float = 0.02) -> dict[str, float]:
    """IAE, ISE, ITAE, overshoot [%], rise time and settling time [s after t0] of y following r,
    over the window [t0, t1] (t1 default: the end of the run)."""
    time, y, r = (np.asarray(a, dtype=float) for a in (time, y, r))
    if t1 is not None:
        keep = time <= t1 + 1e-12 * max(1.0, abs(t1))
        time, y, r = time[keep], y[keep], r[keep]
    if t0 is None:
        t0 = last_change(time, r)
    start = int(np.searchsorted(time, t0 - 1e-12 * max(1.0, abs(t0))))
    before = max(start - 1, 0)
    t, yy, rr = time[start:], y[start:], r[start:]
    e = rr - yy
    result = {"IAE": _trapezoid(np.abs(e), t), "ISE": _trapezoid(e * e, t),
              "ITAE": _trapezoid((t - t0) * np.abs(e), t),
              "overshoot": float("nan"), "rise_time": float("nan"), "settling_time": float("nan")}
    target = rr[-1]
    step = target - (r[start - 1] if start > 0 else y[0])   # from t = t_first: the step is from y(0)
    if step == 0 or len(t) < 2:
        return result
    sign = np.sign(step)
    result["overshoot"] = max(0.0, float(np.max((yy - target) * sign)) / abs(step) * 100)
    y_start = y[before]
    progress = (yy - y_start) / (target - y_start) if target != y_start else np.ones_like(yy)
    reached10 = np.nonzero(progress >= 0.1)[0]
    reached90 = np.nonzero(progress >= 0.9)[0]
    if len(reached10) and len(reached90):
        result["rise_time"] = float(t[reached90[0]] - t[reached10[0]])
    outside = np.nonzero(np.abs(yy - target) > band * abs(step))[0]
    if not len(outside):
        result["settling_time"] = 0.0
    elif outside[-1] + 1 < len(t):
        result["settling_time"] = float(t[outside[-1] + 1] - t0)
    return result


@dataclass
class Difference:
    signal: str
    max_abs: float
    max_rel: float
    ok: bool


def compare(a: np.ndarray, b: np.ndarray, *, signals: Sequence[str] | None = None, rtol: float = 1e-6,
            atol: float = 1e-9) -> list[Difference]:
    """Signal-by-signal check that ``b`` matches ``a``: |a − b| <= atol + rtol·|a| at every sample.

    Both must have the same time grid (same length, times equal to 1e-9 s); a signal missing
    from either is an error naming the closest names.
    """
    if len(a) != len(b) or not np.allclose(a["time"], b["time"], rtol=0, atol=1e-9):
        raise SetupError(f"the time grids differ ({len(a)} samples from {a['time'][0]:g} to {a['time'][-1]:g} s "
                         f"vs {len(b)} from {b['time'][0]:g} to {b['time'][-1]:g} s); compare runs made on the "
                         "same grid.", element="time")
    names = list(signals) if signals else [n for n in a.dtype.names if n != "time"]
    out = []
    for name in names:
        for result, label in ((a, "the first result"), (b, "the second result")):
            if name not in result.dtype.names:
                raise SetupError(f"{label} has no signal '{name}'.", variable=name,
                                 hint=did_you_mean(name, result.dtype.names))
        diff = np.abs(a[name] - b[name])
        scale = np.abs(a[name])
        rel = np.divide(diff, scale, out=np.zeros_like(diff), where=scale > 0)
        out.append(Difference(name, float(diff.max(initial=0)), float(rel.max(initial=0)),
                              bool(np.all(diff <= atol + rtol * scale))))
    return out
