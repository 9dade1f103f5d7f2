"""Control-loop metrics on results, and result comparison for regression use.

`step_response` measures a response to the setpoint's last change (or from a given t0):
IAE = ∫|e| dt, ISE = ∫e² dt, ITAE = ∫(t − t0)|e| dt with e = r − y (trapezoidal rule on the
recorded samples), overshoot in % of the step, 10–90 % rise time and the settling time into
a band of ±2 % of the step (by default).  The step is the setpoint's change at t0; measured
from the first sample, it is the distance from the initial output to the setpoint.  A metric
that cannot be measured (no setpoint change after t0, a response that never gets there) is
NaN, and `Response.undefined` says why in one sentence; `step_metrics` gives the values alone.

`find_events` splits a run into events, each a change of the setpoint or of a named
disturbance signal, with the window up to the next event; `event_metrics` measures each in
its own window (one row per event, as ``cosim metrics`` prints them): a setpoint event by
`step_response`, a disturbance event by its peak error and its recovery time into ±2 % of
the last setpoint step.

`compare` checks a candidate result against a reference signal by signal within
rtol/atol, with per-signal tolerances chosen by glob (`tolerance_for`), and says where each
failing signal first leaves its band (the regression fixture `cosim.pytest_plugin` and
``cosim compare`` report that).
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError, did_you_mean
from ..record.results import matches

METRICS = ("IAE", "ISE", "ITAE", "overshoot", "rise_time", "settling_time")
#: an event's row: the step metrics and the largest error in its window (signed, r − y)
EVENT_METRICS = METRICS + ("peak_error",)
UNITS = {"overshoot": "%", "rise_time": "s", "settling_time": "s"}


def metric_unit(metric: str, unit: str | None) -> str:
    """The unit of ``metric`` of a signal in ``unit`` (None: no unit, taken as 1): IAE in
    unit·s, ISE in unit²·s, ITAE in unit·s², the peak error in unit; the others as `UNITS`."""
    if metric in UNITS:
        return UNITS[metric]
    time = {"IAE": "s", "ISE": "s", "ITAE": "s²"}.get(metric, "")
    signal = (f"({unit})²" if "/" in unit or "·" in unit else f"{unit}²") if unit and metric == "ISE" else (unit or "")
    return "·".join(p for p in (signal, time) if p)


def _trapezoid(values: np.ndarray, time: np.ndarray) -> float:
    return float(np.sum((values[1:] + values[:-1]) * np.diff(time)) / 2) if len(time) > 1 else 0.0


def last_change(time: np.ndarray, r: np.ndarray) -> float:
    """The time of the setpoint's last change (the first sample if it never changes)."""
    changed = np.nonzero(np.diff(r))[0]
    return float(time[changed[-1] + 1]) if len(changed) else float(time[0])


@dataclass(frozen=True)
class Response:
    """Metric values (NaN where undefined) and, for each undefined one, the reason."""
    values: dict[str, float]
    undefined: dict[str, str] = field(default_factory=dict)

    def reasons(self) -> str:
        """The reasons in one line (empty when every metric is defined), as a sweep table's
        ``undefined(SIGNAL)`` column holds them; `reasons_of` reads them back."""
        return "; ".join(f"{k}: {v}" for k, v in self.undefined.items())

    def grouped(self) -> list[tuple[list[str], str]]:
        """(metrics, reason) for each distinct reason, in the order of the metrics."""
        groups: dict[str, list[str]] = {}
        for key, why in self.undefined.items():
            groups.setdefault(why, []).append(key)
        return [(keys, why) for why, keys in groups.items()]


_REASON_KEY = re.compile(rf"(?:^|; )({'|'.join(EVENT_METRICS)}): ")


def reasons_of(line: str | None) -> dict[str, str]:
    """The mapping metric -> reason that `Response.reasons` wrote as ``line``: split only before
    a metric's name, so a reason that contains "; " or ": " stays whole."""
    keys = list(_REASON_KEY.finditer(line or ""))
    return {key.group(1): line[key.end():after.start() if after else len(line)]
            for key, after in zip(keys, keys[1:] + [None])}


def _window(time: np.ndarray, arrays: Sequence[np.ndarray], t1: float | None):
    if t1 is None:
        return time, arrays
    keep = time <= t1 + 1e-12 * max(1.0, abs(t1))
    return time[keep], [a[keep] for a in arrays]


def step_response(time: np.ndarray, y: np.ndarray, r: np.ndarray, *, t0: float | None = None,
                  t1: float | None = None, band: float = 0.02) -> Response:
    """IAE, ISE, ITAE, overshoot [%], rise time and settling time [s after t0] of y following r,
    over the window [t0, t1] (t0 default: the setpoint's last change; t1: the end of the run),
    with the reason for each metric that cannot be measured."""
    time, y, r = (np.asarray(a, dtype=float) for a in (time, y, r))
    time, (y, r) = _window(time, (y, r), t1)
    if t0 is None:
        t0 = last_change(time, r)
    start = int(np.searchsorted(time, t0 - 1e-12 * max(1.0, abs(t0))))
    before = max(start - 1, 0)
    t, yy, rr = time[start:], y[start:], r[start:]
    e = rr - yy
    values = {"IAE": _trapezoid(np.abs(e), t), "ISE": _trapezoid(e * e, t),
              "ITAE": _trapezoid((t - t0) * np.abs(e), t),
              "overshoot": float("nan"), "rise_time": float("nan"), "settling_time": float("nan")}
    end = f"{t[-1]:g} s" if len(t) else f"{t0:g} s"
    if len(t) < 2:
        return Response(values, dict.fromkeys(METRICS[3:], f"the window from {t0:g} s holds fewer than two samples"))
    target = rr[-1]
    step = target - (r[start - 1] if start > 0 else y[0])   # from t = t_first: the step is from y(0)
    if step == 0:
        why = (f"the set-point does not change at {t0:g} s (it stays {target:g} up to {end}), so there is "
               "no step to measure against (a disturbance's effect: name the disturbance signal, cosim metrics "
               "--disturbance)")
        return Response(values, dict.fromkeys(METRICS[3:], why))
    undefined = {}
    sign = np.sign(step)
    values["overshoot"] = max(0.0, float(np.max((yy - target) * sign)) / abs(step) * 100)
    y_start = y[before]
    progress = (yy - y_start) / (target - y_start) if target != y_start else np.ones_like(yy)
    reached10 = np.nonzero(progress >= 0.1)[0]
    reached90 = np.nonzero(progress >= 0.9)[0]
    if len(reached10) and len(reached90):
        values["rise_time"] = float(t[reached90[0]] - t[reached10[0]])
    else:
        undefined["rise_time"] = (f"the response never reached {10 if not len(reached10) else 90} % of the step "
                                  f"(at most {100 * float(np.max(progress)):.3g} %) between {t0:g} s and {end}")
    values["settling_time"], why = _settling(t, np.abs(yy - target), band * abs(step), t0, band, "the step")
    if why:
        undefined["settling_time"] = why
    return Response(values, undefined)


def _settling(t: np.ndarray, error: np.ndarray, limit: float, t0: float, band: float,
              of: str) -> tuple[float, str]:
    """Time after t0 from which |error| stays within limit, or NaN and why not."""
    outside = np.nonzero(error > limit)[0]
    if not len(outside):
        return 0.0, ""
    if outside[-1] + 1 < len(t):
        return float(t[outside[-1] + 1] - t0), ""
    return float("nan"), (f"the response is still outside ±{100 * band:g} % of {of} (±{limit:.3g}) at "
                          f"{t[-1]:g} s, the end of the window (error {error[-1]:.3g})")


def step_metrics(time: np.ndarray, y: np.ndarray, r: np.ndarray, *, t0: float | None = None,
                 t1: float | None = None, band: float = 0.02) -> dict[str, float]:
    """The values of `step_response` (NaN where a metric cannot be measured)."""
    return step_response(time, y, r, t0=t0, t1=t1, band=band).values


@dataclass(frozen=True)
class Event:
    """A change of the setpoint (kind "set-point") or of a disturbance signal, from ``before``
    to ``after``, starting at t0; its window ends at t1, the next event or the end of the run."""
    kind: str
    signal: str
    t0: float
    t1: float
    before: float
    after: float

    def describe(self) -> str:
        return f"{self.kind} {self.signal} {self.before:g} → {self.after:g}"


def _changes(time: np.ndarray, x: np.ndarray) -> list[tuple[float, float, float]]:
    """(t, before, after) of each run of consecutive changing samples (a ramp is one change)."""
    idx = np.nonzero(np.diff(x))[0]
    if not len(idx):
        return []
    breaks = np.nonzero(np.diff(idx) > 1)[0]
    firsts = np.concatenate(([idx[0]], idx[breaks + 1]))
    lasts = np.concatenate((idx[breaks], [idx[-1]]))
    return [(float(time[f + 1]), float(x[f]), float(x[l + 1])) for f, l in zip(firsts, lasts)]


def find_events(time: np.ndarray, setpoint: tuple[str, np.ndarray],
                disturbances: Mapping[str, np.ndarray] | None = None) -> list[Event]:
    """The setpoint's changes and the named disturbances' changes, in time order (a setpoint
    change first when both happen at one sample), each window ending at the next later event.
    A run whose setpoint never changes is one setpoint event from the first sample."""
    time = np.asarray(time, dtype=float)
    name, r = setpoint
    found = [("set-point", name, *c) for c in _changes(time, np.asarray(r, dtype=float))]
    if not found:
        found = [("set-point", name, float(time[0]), float(r[0]), float(r[0]))]
    for signal, d in (disturbances or {}).items():
        found += [("disturbance", signal, *c) for c in _changes(time, np.asarray(d, dtype=float))]
    found.sort(key=lambda e: (e[2], e[0] != "set-point"))
    starts = sorted({e[2] for e in found})
    events = []
    for kind, signal, t0, before, after in found:
        later = [s for s in starts if s > t0]
        events.append(Event(kind, signal, t0, later[0] if later else float(time[-1]), before, after))
    return events


def event_metrics(time: np.ndarray, y: np.ndarray, r: np.ndarray, events: Sequence[Event], *,
                  band: float = 0.02) -> list[Response]:
    """One `Response` per event, measured within the event's window (`EVENT_METRICS`).

    A setpoint event is measured by `step_response`.  A disturbance event has no setpoint
    step, so no overshoot or rise time; its settling time is the recovery into ±band of the
    last setpoint step before it (of |r| when there was none)."""
    time, y, r = (np.asarray(a, dtype=float) for a in (time, y, r))
    rows = []
    scale = 0.0
    for ev in events:
        t, (yy, rr) = _window(time, (y, r), ev.t1)
        start = int(np.searchsorted(t, ev.t0 - 1e-12 * max(1.0, abs(ev.t0))))
        e = rr[start:] - yy[start:]
        peak = float(e[np.argmax(np.abs(e))]) if len(e) else float("nan")
        if ev.kind == "set-point":
            resp = step_response(time, y, r, t0=ev.t0, t1=ev.t1, band=band)
            scale = abs(ev.after - ev.before) or scale
            rows.append(Response({**resp.values, "peak_error": peak}, resp.undefined))
            continue
        tt = t[start:]
        values = {"IAE": _trapezoid(np.abs(e), tt), "ISE": _trapezoid(e * e, tt),
                  "ITAE": _trapezoid((tt - ev.t0) * np.abs(e), tt), "overshoot": float("nan"),
                  "rise_time": float("nan"), "settling_time": float("nan"), "peak_error": peak}
        why = f"a disturbance event ({ev.signal} at {ev.t0:g} s) has no set-point step"
        undefined = {"overshoot": why, "rise_time": why}
        reference = scale or (abs(float(rr[start])) if len(rr) > start else 0.0)
        if len(tt) < 2:
            undefined["settling_time"] = f"the window from {ev.t0:g} s holds fewer than two samples"
        elif reference == 0:
            undefined["settling_time"] = ("no set-point step before it and a zero set-point: no size to "
                                          f"take ±{100 * band:g} % of")
        else:
            of = "the last set-point step" if scale else "the set-point"
            values["settling_time"], reason = _settling(tt, np.abs(e), band * reference, ev.t0, band, of)
            if reason:
                undefined["settling_time"] = reason
        rows.append(Response(values, undefined))
    return rows


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
    """How much of a glob is fixed text: the measure of how specific a tolerance key is (brackets
    are literal, `cosim.record.results.matches`)."""
    return len(re.sub(r"[*?]", "", pattern))


def tolerance_for(signal: str, tolerances: Mapping[str, ToleranceSpec], default: Tolerance) -> Tolerance:
    """The tolerance of ``signal``: the most specific glob key that matches it wins (an exact
    name beats any pattern; among patterns, the one with the most fixed characters, then the
    first given), else ``default``."""
    if signal in tolerances:
        return as_tolerance(tolerances[signal], default, signal)
    keys = [k for k in tolerances if matches(signal, k)]
    if not keys:
        return default
    best = max(keys, key=_literal_length)   # max keeps the first of equals
    return as_tolerance(tolerances[best], default, best)


def check_tolerance_keys(tolerances: Mapping[str, ToleranceSpec], names: Sequence[str]) -> None:
    """Refuse a tolerance key that matches none of ``names`` (a misspelt key must not go unnoticed)."""
    for key in tolerances:
        if not any(key == n or matches(n, key) for n in names):
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


_ELEMENT = re.compile(r"(.+)\[(\d+(?:,\d+)*)\]")


def _by_position(a: Sequence[str], b: Sequence[str]) -> dict[str, str]:
    """For each name of ``a`` that ``b`` lacks, ``b``'s name of the same element of an array where
    one result names its elements by position (``A[1]`` .. ``A[6]``: fmusim writes an array's values
    without its shape, `cosim.record.results.read` numbers them) and the other by index (``A[1,1]``
    .. ``A[2,3]``, row-major, as a run records them) and both have as many."""
    def arrays(names: Sequence[str]) -> dict[str, list[str]]:
        found: dict[str, list[str]] = {}
        for name in names:
            match = _ELEMENT.fullmatch(name)
            if match is not None:
                found.setdefault(match.group(1), []).append(name)
        return found
    theirs = arrays(b)
    return {x: y for base, ours in arrays(a).items()
            if len(theirs.get(base, ())) == len(ours) and any("," not in n for n in (ours[0], theirs[base][0]))
            for x, y in zip(ours, theirs[base]) if x not in b}


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
    counterpart = _by_position(a.dtype.names, b.dtype.names)
    out = []
    for name in names:
        theirs = counterpart.get(name, name)
        for result, label, own in ((a, "the first result", name), (b, "the second result", theirs)):
            if own not in result.dtype.names:
                raise SetupError(f"{label} has no signal '{own}'.", variable=own,
                                 hint=did_you_mean(own, result.dtype.names))
        tol = tolerance_for(name, tolerances, default)
        ref, cand = a[name], b[theirs]
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
