"""The comparison engine: a run against a reference, signal by signal, with a verdict each.

Three rules (``mode``):

- ``"tube"`` (default): per-signal tolerances (`cosim.regression.tolerances`, by glob) make a
  tube around the reference (`cosim.regression.tube.envelope`, csv-compare's rectangles as LBNL's
  funnel builds them): |run − reference| <= max(atol, rtol·|reference|), the reference taken
  anywhere within ±time s.  With time = 0 it is the plain band at each point.  The run is
  checked at the reference's time points, linearly interpolated where the grids differ (a
  reference from another tool, step or output interval); ``on="candidate"`` checks the run's
  own samples against the tube instead, as csv-compare and the funnel do.
- ``"csv-compare"``: csv-compare's tube as the Modelica Standard Library's regression tests run
  it (CsvFile.cs: one relative ``tolerance``, default 0.002, legacy base and ratio, nominal
  0.001): δt = tolerance·max(t range, |t_min|), δy = tolerance·max(y range, |y_min|, 0.001);
  the run's samples checked.
- ``"fmi-cross-check"``: the FMI Cross-Check rules' epsilon band (`cosim.regression.tube.cross_check_band`);
  the run's samples within the reference's time span checked; a signal passes with at most 10 %
  of the run's samples outside the band.

Each signal's `Verdict` gives the points checked and out, the largest |run − reference|, the
first and the worst violation (time, run value, reference value, tube bounds) and the checked
points themselves (`Trace`) for the difference report (`cosim.regression.report`).
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError, did_you_mean
from . import CSV_COMPARE_TOLERANCE, MODES
from .tolerances import Tolerance, ToleranceSpec, as_tolerance, check_tolerance_keys, tolerance_for
from .tube import CROSS_CHECK_HEIGHT, CROSS_CHECK_NEIGHBOURS, CROSS_CHECK_OUTSIDE, CROSS_CHECK_POINTS, \
    cross_check_band, envelope, sample_at

#: the nominal value csv-compare's CsvFile.cs floors the y base with
CSV_COMPARE_NOMINAL = 0.001


@dataclass(frozen=True)
class Violation:
    """A checked point outside the tube: the run's value, the reference's there, the bounds."""
    time: float
    value: float
    reference: float
    lower: float
    upper: float

    @property
    def excess(self) -> float:
        """How far the value lies outside [lower, upper] (inf for a NaN on one side only)."""
        outside = max(self.value - self.upper, self.lower - self.value)
        return float(outside) if outside == outside else float("inf")

    def describe(self) -> str:
        return (f"t = {self.time:.10g} s: run {self.value:.12g}, reference {self.reference:.12g}, "
                f"tube [{self.lower:.12g}, {self.upper:.12g}] (outside by {self.excess:.3g})")


@dataclass(frozen=True)
class Trace:
    """The points a signal was checked at: time, run, reference and tube bounds there, and
    which were outside."""
    time: np.ndarray
    value: np.ndarray
    reference: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    out: np.ndarray


@dataclass(frozen=True)
class Verdict:
    """One signal's comparison."""
    signal: str
    passed: bool
    rule: str
    checked: int
    out: int
    max_abs: float
    first: Violation | None = None
    worst: Violation | None = None
    problem: str = ""
    trace: Trace | None = field(default=None, repr=False, compare=False)

    def describe(self) -> str:
        """One line for a log: the verdict, and where a failing signal first and worst leaves its tube."""
        head = f"{self.signal}: {'passed' if self.passed else 'FAILED'} ({self.rule})"
        if self.problem:
            head += f"; {self.problem}"
        if self.first is None:
            return f"{head}; max |run − reference| {self.max_abs:.3g}"
        return (f"{head}; {self.out} of {self.checked} points outside; first at {self.first.describe()}; "
                f"worst at {self.worst.describe()}")


def _violation(trace: Trace, i: int) -> Violation:
    return Violation(float(trace.time[i]), float(trace.value[i]), float(trace.reference[i]),
                     float(trace.lower[i]), float(trace.upper[i]))


def _verdict(signal: str, rule: str, trace: Trace, passed: bool | None = None, problem: str = "") -> Verdict:
    out = np.flatnonzero(trace.out)
    with np.errstate(invalid="ignore"):
        diff = np.abs(trace.value - trace.reference)
    finite = diff[np.isfinite(diff)]
    first = worst = None
    if len(out):
        first = _violation(trace, int(out[0]))
        excess = np.maximum(trace.value[out] - trace.upper[out], trace.lower[out] - trace.value[out])
        worst = _violation(trace, int(out[np.argmax(np.where(np.isnan(excess), np.inf, excess))]))
    ok = not len(out) if passed is None else passed
    return Verdict(signal, ok and not problem, rule, len(trace.time), len(out), float(finite.max(initial=0.0)),
                   first, worst, problem, trace)


def _outside(value: np.ndarray, reference: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Outside the tube; NaN matches NaN only, an infinity the same infinity only."""
    both_nan = np.isnan(value) & np.isnan(reference)
    with np.errstate(invalid="ignore"):
        inside = (lower <= value) & (value <= upper)
    return ~(inside | both_nan | (value == reference))


def _span(t: np.ndarray) -> str:
    return f"t = {t[0]:g}..{t[-1]:g} s" if len(t) else "no samples"


def _coverage(t_ref: np.ndarray, t_run: np.ndarray) -> str:
    """Why the run does not cover the reference's time span, or ""."""
    slack = 1e-9 * max(1.0, abs(t_ref[-1]))
    if len(t_run) and t_run[0] <= t_ref[0] + slack and t_run[-1] >= t_ref[-1] - slack:
        return ""
    return f"the run covers {_span(t_run)}, the reference {_span(t_ref)}"


def _tube(name: str, t_ref, y_ref, t_run, y_run, tol: Tolerance, on: str, rule: str) -> Verdict:
    if on == "reference":
        at, reference = t_ref, y_ref
        value = sample_at(t_run, y_run, at)
    else:
        keep = (t_run >= t_ref[0]) & (t_run <= t_ref[-1])
        at, value = t_run[keep], y_run[keep]
        reference = sample_at(t_ref, y_ref, at)
    lower, upper = envelope(t_ref, y_ref, tol.half_height(y_ref), tol.time, at)
    trace = Trace(at, value, reference, lower, upper, _outside(value, reference, lower, upper))
    return _verdict(name, rule, trace, problem=_coverage(t_ref, t_run))


def _cross_check(name: str, t_ref, y_ref, t_run, y_run) -> Verdict:
    t_band, y_min, y_max = cross_check_band(t_ref, y_ref)
    keep = (t_run >= t_ref[0]) & (t_run <= t_ref[-1])       # samples outside the reference's span are ignored
    at, value = t_run[keep], y_run[keep]
    lower, upper = np.interp(at, t_band, y_min), np.interp(at, t_band, y_max)
    with np.errstate(invalid="ignore"):
        out = ~((lower <= value) & (value <= upper))          # NaN is out, as FMPy counts it
    trace = Trace(at, value, sample_at(t_ref, y_ref, at), lower, upper, out)
    share = trace.out.sum() / max(len(t_run), 1)              # FMPy divides by all of the run's samples
    rule = (f"FMI cross-check: ±{CROSS_CHECK_HEIGHT:.0%} of range, max/min of {CROSS_CHECK_NEIGHBOURS} of "
            f"{CROSS_CHECK_POINTS} resampled points; {share:.1%} of samples out, at most {CROSS_CHECK_OUTSIDE:.0%}")
    return _verdict(name, rule, trace, passed=share <= CROSS_CHECK_OUTSIDE, problem=_coverage(t_ref, t_run))


def _column(result: np.ndarray, name: str, label: str) -> np.ndarray:
    if name not in result.dtype.names:
        raise SetupError(f"{label} has no signal '{name}'.", variable=name, hint=did_you_mean(name, result.dtype.names))
    column = result[name]
    if column.ndim != 1:
        raise SetupError(f"'{name}' is a vector of {column.shape[1]} values a sample; compare its elements "
                         "as scalar columns.", variable=name)
    return np.asarray(column, dtype=float)


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


def compare(reference: np.ndarray, candidate: np.ndarray, *, signals: Sequence[str] | None = None,
            tolerances: Mapping[str, ToleranceSpec] | None = None, rtol: float = 1e-6, atol: float = 1e-9,
            time: float = 0.0, mode: str = "tube", on: str | None = None,
            tolerance: float = CSV_COMPARE_TOLERANCE) -> list[Verdict]:
    """A `Verdict` per signal (default: every signal of the reference) of ``candidate`` against
    ``reference``, both structured arrays with a ``time`` field (`cosim.record.results.read`), by
    ``mode`` (module docstring).  ``tolerances``: per-signal `ToleranceSpec` by glob, the others
    get (``rtol``, ``atol``, ``time``) (tube mode; a key matching no compared signal is an
    error); ``on``: the points checked in tube mode, "reference" (default) or "candidate";
    ``tolerance``: csv-compare's relative tolerance.  A signal missing from either result is an
    error naming the closest names; a run not covering the reference's span fails each signal."""
    if mode not in MODES:
        raise SetupError(f"unknown comparison mode '{mode}'; one of {', '.join(MODES)}.", element="mode")
    if on not in (None, "reference", "candidate") or (on is not None and mode != "tube"):
        raise SetupError(f"on={on!r}: the tube mode checks on 'reference' or 'candidate' points; the "
                         f"{mode} rule checks the run's own samples.", element="on")
    if tolerances and mode != "tube":
        raise SetupError(f"per-signal tolerances apply to the tube mode; the {mode} rule sets its own.",
                         element="tolerances")
    names = list(signals) if signals is not None else [n for n in reference.dtype.names if n != "time"]
    tolerances = tolerances or {}
    check_tolerance_keys(tolerances, names)
    default = as_tolerance((rtol, atol, time), Tolerance())
    t_ref, t_run = np.asarray(reference["time"], dtype=float), np.asarray(candidate["time"], dtype=float)
    if not len(t_ref):
        raise SetupError("the reference has no samples.", element="time")
    counterpart = _by_position(reference.dtype.names, candidate.dtype.names)
    verdicts = []
    for name in names:
        y_ref, y_run = _column(reference, name, "the reference"), _column(candidate, counterpart.get(name, name), "the run")
        if mode == "fmi-cross-check":
            verdicts.append(_cross_check(name, t_ref, y_ref, t_run, y_run))
            continue
        if mode == "csv-compare":
            finite = y_ref[np.isfinite(y_ref)]
            base_t = max(float(np.ptp(t_ref)), abs(float(t_ref.min())), 1e-12)
            base_y = max(float(np.ptp(finite)) if len(finite) else 0.0, abs(float(finite.min())) if len(finite)
                         else 0.0, CSV_COMPARE_NOMINAL)
            tol = Tolerance(0.0, tolerance * base_y, tolerance * base_t)
            rule = f"csv-compare tube, tolerance {tolerance:g}: ±{tol.time:.3g} s, ±{tol.atol:.3g}"
            verdicts.append(_tube(name, t_ref, y_ref, t_run, y_run, tol, "candidate", rule))
            continue
        tol = tolerance_for(name, tolerances, default)
        where = on or "reference"
        rule = f"{tol}; on the {where}'s {'points' if where == 'reference' else 'samples'}"
        verdicts.append(_tube(name, t_ref, y_ref, t_run, y_run, tol, where, rule))
    return verdicts
