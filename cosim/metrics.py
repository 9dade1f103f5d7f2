"""Control-loop metrics on results, and result comparison for regression use.

`step_metrics` measures a response to the setpoint's last change (or from a given t0):
IAE = ∫|e| dt, ISE = ∫e² dt, ITAE = ∫(t − t0)|e| dt with e = r − y (trapezoidal rule on the
recorded samples), overshoot in % of the step, 10–90 % rise time and the settling time into
a band of ±2 % of the step (by default).  The step is the setpoint's change at t0; measured
from the first sample, it is the distance from the initial output to the setpoint.  Overshoot, rise and settling time are NaN when the
setpoint does not change after t0 (a pure disturbance run) or when the response never gets
there.  `compare` checks a candidate result against a reference signal by signal within
rtol/atol, with per-signal tolerances chosen by glob (`tolerance_for`), and says where each
failing signal first leaves its band (the regression fixture `cosim.pytest_plugin` and
``cosim compare`` report that).
"""
from __future__ import annotations

import fnmatch
import re
from collections.abc import Mapping, Sequence
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


@dataclass(frozen=True)
class Tolerance:
    """The band a candidate sample must fall in: |candidate − reference| <= atol + rtol·|reference|."""
    rtol: float
    atol: float

    def bound(self, reference: np.ndarray) -> np.ndarray:
        return self.atol + self.rtol * np.abs(reference)

    def __str__(self) -> str:
        return f"rtol {self.rtol:g}, atol {self.atol:g}"


#: what a caller may give per signal: a Tolerance, (rtol, atol), or {"rtol": ..., "atol": ...}
#: (a missing key takes the default)
ToleranceSpec = Tolerance | tuple[float, float] | Mapping[str, float]


def as_tolerance(spec: ToleranceSpec, default: Tolerance, key: str = "") -> Tolerance:
    """A `Tolerance` from any `ToleranceSpec`; negative or malformed values are refused."""
    if isinstance(spec, Tolerance):
        tol = spec
    elif isinstance(spec, Mapping):
        unknown = set(spec) - {"rtol", "atol"}
        if unknown:
            raise SetupError(f"unknown tolerance field(s) {', '.join(sorted(unknown))}; use 'rtol' and 'atol'.",
                             variable=key or None)
        tol = Tolerance(float(spec.get("rtol", default.rtol)), float(spec.get("atol", default.atol)))
    elif isinstance(spec, (tuple, list)) and len(spec) == 2:
        tol = Tolerance(float(spec[0]), float(spec[1]))
    else:
        raise SetupError(f"a tolerance is (rtol, atol) or {{'rtol': .., 'atol': ..}}, not {spec!r}.",
                         variable=key or None)
    if not (tol.rtol >= 0 and tol.atol >= 0):
        raise SetupError(f"tolerances must be >= 0 ({tol}).", variable=key or None)
    return tol


def parse_tolerance(text: str) -> tuple[str, Tolerance]:
    """``"GLOB=RTOL,ATOL"`` (the ``cosim compare --tolerance`` syntax) as (glob, Tolerance)."""
    key, _, values = text.partition("=")
    parts = values.split(",")
    try:
        if not key.strip() or len(parts) != 2:
            raise ValueError
        spec = (float(parts[0]), float(parts[1]))
    except ValueError:
        raise SetupError(f"'{text}' is not GLOB=RTOL,ATOL (e.g. 'plant.y=1e-6,1e-9').",
                         element="--tolerance") from None
    return key.strip(), as_tolerance(spec, Tolerance(*spec), key.strip())


def _literal_length(pattern: str) -> int:
    """How much of a glob is fixed text: the measure of how specific a tolerance key is."""
    return len(re.sub(r"\[[^\]]*\]|[*?]", "", pattern))


def tolerance_for(signal: str, tolerances: Mapping[str, ToleranceSpec], default: Tolerance) -> Tolerance:
    """The tolerance of ``signal``: the most specific glob key that matches it wins (an exact
    name beats any pattern; among patterns, the one with the most fixed characters, then the
    first given), else ``default``."""
    if signal in tolerances:
        return as_tolerance(tolerances[signal], default, signal)
    matches = [k for k in tolerances if fnmatch.fnmatchcase(signal, k)]
    if not matches:
        return default
    best = max(matches, key=_literal_length)   # max keeps the first of equals
    return as_tolerance(tolerances[best], default, best)


def check_tolerance_keys(tolerances: Mapping[str, ToleranceSpec], names: Sequence[str]) -> None:
    """Refuse a tolerance key that matches none of ``names`` (a misspelt key must not go unnoticed)."""
    for key in tolerances:
        if not any(key == n or fnmatch.fnmatchcase(n, key) for n in names):
            raise SetupError("this tolerance key matches no compared signal.", variable=key,
                             hint=did_you_mean(key, names))


def grid_mismatch(reference: np.ndarray, candidate: np.ndarray) -> str | None:
    """None when both time vectors are the same grid (equal to 1e-9 s), else how they differ:
    sample counts, spans, steps and the first sample where they part."""
    if len(reference) == len(candidate) and np.allclose(reference, candidate, rtol=0, atol=1e-9):
        return None

    def span(t: np.ndarray) -> str:
        if not len(t):
            return "0 samples"
        step = f", step {float(np.median(np.diff(t))):g} s" if len(t) > 1 else ""
        return f"{len(t)} samples from {t[0]:g} to {t[-1]:g} s{step}"

    text = f"the time grids differ ({span(reference)} vs {span(candidate)}"
    n = min(len(reference), len(candidate))
    parted = np.nonzero(np.abs(reference[:n] - candidate[:n]) > 1e-9)[0]
    if len(parted):
        i = int(parted[0])
        text += f"; sample {i} is at {reference[i]:.12g} s vs {candidate[i]:.12g} s"
    return text + ")"


@dataclass
class Difference:
    """One signal's comparison; when it fails, the first sample out of its band."""
    signal: str
    max_abs: float
    max_rel: float
    ok: bool
    tolerance: Tolerance
    samples_out: int = 0
    first_time: float = float("nan")
    first_value: float = float("nan")        # the candidate's sample
    first_reference: float = float("nan")
    first_bound: float = float("nan")        # atol + rtol·|reference| there

    def describe(self) -> str:
        """One line for a report: where the signal first leaves its band and by how much."""
        if self.ok:
            return f"{self.signal}: within {self.tolerance} (max |diff| {self.max_abs:.3g})"
        diff = abs(self.first_value - self.first_reference)
        return (f"{self.signal}: first at t = {self.first_time:.10g} s: value {self.first_value:.12g}, "
                f"reference {self.first_reference:.12g}, |diff| {diff:.3g} > {self.first_bound:.3g} "
                f"({self.tolerance}); {self.samples_out} sample(s) out, max |diff| {self.max_abs:.3g}")


def compare(a: np.ndarray, b: np.ndarray, *, signals: Sequence[str] | None = None, rtol: float = 1e-6,
            atol: float = 1e-9, tolerances: Mapping[str, ToleranceSpec] | None = None) -> list[Difference]:
    """Signal-by-signal check that ``b`` (candidate) matches ``a`` (reference):
    |a − b| <= atol + rtol·|a| at every sample (NaN matches NaN only).

    ``tolerances`` gives per-signal (rtol, atol) by glob key (see `tolerance_for`); a key that
    matches no compared signal is an error (`check_tolerance_keys`).
    Both results must have the same time grid (`grid_mismatch`); a signal missing from either
    is an error naming the closest names.
    """
    mismatch = grid_mismatch(a["time"], b["time"])
    if mismatch:
        raise SetupError(mismatch + "; compare runs made on the same grid.", element="time")
    names = list(signals) if signals else [n for n in a.dtype.names if n != "time"]
    tolerances = tolerances or {}
    check_tolerance_keys(tolerances, names)
    default = as_tolerance((rtol, atol), Tolerance(rtol, atol))
    out = []
    for name in names:
        for result, label in ((a, "the first result"), (b, "the second result")):
            if name not in result.dtype.names:
                raise SetupError(f"{label} has no signal '{name}'.", variable=name,
                                 hint=did_you_mean(name, result.dtype.names))
        tol = tolerance_for(name, tolerances, default)
        ref, cand = a[name], b[name]
        with np.errstate(invalid="ignore"):
            diff = np.abs(ref - cand)
        scale = np.abs(ref)
        bound = tol.bound(ref)
        both_nan = np.isnan(ref) & np.isnan(cand)
        same = both_nan | (ref == cand)  # equal infinities too: inf - inf is NaN
        diff = np.where(same, 0.0, diff)
        # an infinite difference is out of any band (the bound of an infinite reference is infinite too)
        out_of_band = ~(((diff <= bound) & np.isfinite(diff)) | same)
        finite = np.where(both_nan, 0.0, diff)
        with np.errstate(invalid="ignore"):
            rel = np.divide(finite, scale, out=np.zeros_like(finite), where=scale > 0)
        d = Difference(name, float(finite.max(initial=0)), float(rel.max(initial=0)), not out_of_band.any(), tol, int(out_of_band.sum()))
        if not d.ok:
            i = int(np.argmax(out_of_band))
            d.first_time, d.first_value = float(a["time"][i]), float(cand[i])
            d.first_reference, d.first_bound = float(ref[i]), float(bound[i])
        out.append(d)
    return out
