"""The tube around a reference signal, in time and value, and the FMI cross-check band.

`envelope` is the tube of csv-compare (github:modelica-tools/csv-compare,
CurveCompare/Algorithms/Rectangle.cs) as LBNL's funnel computes it (github:lbl-srg/funnel,
src/algorithmRectangle.c, the same rectangle algorithm in C): a rectangle of half-width δt and
half-height δy_i around each reference point (t_i, y_i); the tube is the union, over each pair
of neighbouring points, of the convex hull of their two rectangles.  For constant δt, δy this
is the reference polyline swept by the rectangle (its Minkowski sum), so the upper bound at t
is max{y_ref(s) : |s − t| <= δt} + δy: a step that moves by up to δt stays inside.  The funnel
builds the same boundary from the rectangles' corners (top-left on rising segments, top-right
on falling ones, intersections where they cross back) and interpolates it linearly at the
checked times; here the hull's upper boundary is evaluated at the checked times directly.
Where δy differs between neighbours (a relative tolerance) and the reference rises while y+δy
falls, the hull is the wider of the two by second-order terms; tests/cosim/test_regression_funnel.py
compares both against pyfunnel 2.1.1 on the funnel's own kinds of cases.

`cross_check_band` is the epsilon band of the FMI Cross-Check rules 4.0, §9.2.5
(github:modelica/fmi-cross-check, FMI-CROSS-CHECK-RULES.md) as FMPy's validation script
computes it (``fmpy.cross_check.validate_signal``): the reference resampled linearly at 1000
equally spaced points over its time span, the maximum (minimum) of 21 neighbouring samples
(10 to either side) plus (minus) 10 % of the resampled reference's range (10 % of |value| for
a constant signal, 0.5 for an all-zero one).  The rules' text says "10% of the absolute maximum
of all values"; FMPy, which the repository's validation runs, takes the range: we follow FMPy.
"""
from __future__ import annotations

import numpy as np

#: FMI Cross-Check rules 4.0 §9.2.5: resampled points, neighbouring samples, band height
CROSS_CHECK_POINTS = 1000
CROSS_CHECK_NEIGHBOURS = 21
CROSS_CHECK_HEIGHT = 0.1
#: ... and the share of a result's samples that may lie outside the band
CROSS_CHECK_OUTSIDE = 0.1


def _hull_top(x: np.ndarray, ta: np.ndarray, tb: np.ndarray, a: np.ndarray, c: np.ndarray,
              dt: float) -> np.ndarray:
    """The upper boundary, at x in [ta − dt, tb + dt], of the convex hull of two rectangles'
    top edges: [ta − dt, ta + dt] at height a and [tb − dt, tb + dt] at height c (ta <= tb)."""
    span = tb - ta
    safe = np.where(span > 0, span, 1.0)
    with np.errstate(invalid="ignore"):
        falling = np.where(x <= ta + dt, a, a + (c - a) * (x - ta - dt) / safe)     # a >= c: hull A, B, D
        rising = np.where(x >= tb - dt, c, a + (c - a) * (x - ta + dt) / safe)      # a < c: hull A, C, D
    return np.where(a >= c, falling, rising)


def envelope(t: np.ndarray, y: np.ndarray, half_height: np.ndarray, half_width: float,
             at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of the tube around the reference (t, y) evaluated at the sorted times
    ``at`` (module docstring); NaN where no rectangle's hull reaches (outside [t0 − δt, tN + δt])."""
    t, y, at = (np.asarray(v, dtype=float) for v in (t, y, at))
    dy = np.broadcast_to(np.asarray(half_height, dtype=float), t.shape)
    if len(t) == 1:   # one point: its rectangle
        inside = np.abs(at - t[0]) <= half_width
        return np.where(inside, y[0] - dy[0], np.nan), np.where(inside, y[0] + dy[0], np.nan)
    segment = np.arange(len(t) - 1)
    first = np.searchsorted(at, t[:-1] - half_width, "left")
    last = np.searchsorted(at, t[1:] + half_width, "right")
    counts = np.maximum(last - first, 0)
    seg = np.repeat(segment, counts)
    point = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(first, counts)
    x, ta, tb = at[point], t[seg], t[seg + 1]
    top = _hull_top(x, ta, tb, y[seg] + dy[seg], y[seg + 1] + dy[seg + 1], half_width)
    bottom = -_hull_top(x, ta, tb, -(y[seg] - dy[seg]), -(y[seg + 1] - dy[seg + 1]), half_width)
    upper = np.full(len(at), -np.inf)
    lower = np.full(len(at), np.inf)
    with np.errstate(invalid="ignore"):       # a NaN reference makes a NaN bound
        np.maximum.at(upper, point, top)
        np.minimum.at(lower, point, bottom)
    reached = np.zeros(len(at), dtype=bool)
    reached[point] = True
    return np.where(reached, lower, np.nan), np.where(reached, upper, np.nan)


def sample_at(t: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """y(t) at the sorted times ``at``, linear between samples.  At an event (a time repeated in
    ``t``) the first of equal times in ``at`` takes the value before it (the first sample at
    that time) and later ones the value after it (the last), so a reference's event rows meet
    the run's left and right limits; NaN outside [t0, tN]."""
    t, y, at = (np.asarray(v, dtype=float) for v in (t, y, at))
    repeated = np.zeros(len(at), dtype=bool)
    repeated[1:] = at[1:] == at[:-1]
    left = np.searchsorted(t, at, "left")                    # first sample at or after
    right = np.searchsorted(t, at, "right") - 1              # last sample at or before
    hit = np.where(repeated, right, left)
    hit = np.clip(hit, 0, len(t) - 1)
    exact = t[hit] == at
    hi = np.clip(np.where(repeated, right + 1, left), 1, len(t) - 1)
    lo = hi - 1
    span = t[hi] - t[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        between = y[lo] + (y[hi] - y[lo]) * (at - t[lo]) / np.where(span > 0, span, 1.0)
    value = np.where(exact, y[hit], between)
    return np.where((at < t[0]) | (at > t[-1]), np.nan, value)


def cross_check_band(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_band, y_min, y_max) of the FMI cross-check epsilon band (module docstring)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    t_band = np.linspace(t[0], t[-1], CROSS_CHECK_POINTS)
    first = np.concatenate(([True], np.diff(t) > 0))       # an event's first sample, as FMPy keeps it
    y_band = np.interp(t_band, t[first], y[first])
    low, high = float(np.min(y_band)), float(np.max(y_band))
    width = (high - low) * CROSS_CHECK_HEIGHT if high != low else \
        (0.5 if low == 0 else abs(low) * CROSS_CHECK_HEIGHT)
    return (t_band, minimum_filter1d(y_band, size=CROSS_CHECK_NEIGHBOURS) - width,
            maximum_filter1d(y_band, size=CROSS_CHECK_NEIGHBOURS) + width)
