"""The tube of cosim.regression against LBNL's funnel itself: pyfunnel 2.1.1 (its C library, the
rectangle algorithm of csv-compare) installed from the registry (pyproject's test extra), on the
kinds of cases the funnel's own tests hold (tests/fail*, success*: steps, time-event offsets,
different time arrays, absolute and local tolerances)."""
from __future__ import annotations

import numpy as np
import pytest
import pyfunnel

from cosim.regression.engine import compare
from cosim.regression.tube import envelope


def funnel(t_ref, y_ref, t_test, y_test, tmp_path, **tolerances):
    """pyfunnel's lower and upper bound (its own vertices) and errors (one per test point)."""
    out = tmp_path / f"funnel{len(list(tmp_path.iterdir()))}"
    pyfunnel.compareAndReport(xReference=list(t_ref), yReference=list(y_ref), xTest=list(t_test),
                              yTest=list(y_test), outputDirectory=str(out), **tolerances)
    read = lambda name: np.loadtxt(out / name, delimiter=",", skiprows=1, ndmin=2)   # noqa: E731
    return read("lowerBound.csv"), read("upperBound.csv"), read("errors.csv")


def cases():
    rng = np.random.default_rng(11)
    t = np.sort(np.concatenate(([0.0, 10.0], rng.uniform(0, 10, 60))))
    walk = np.cumsum(rng.normal(size=len(t)))
    step = np.where(t >= 5.0, 1.0, 0.0)
    t_test = np.linspace(0, 10, 301)
    yield "random walk, another grid", t, walk, t_test, np.interp(t_test + 0.05, t, walk) + rng.normal(0, .05, 301)
    yield "step at 5 s, the test's 0.08 s later", t, step, t_test, np.where(t_test >= 5.08, 1.0, 0.0)
    tt = np.array([0.0, 1.0, 1.0, 2.0])                                             # a time event (repeated time)
    yield "time event offset", tt, np.array([0.0, 0.0, 1.0, 1.0]), np.array([0.0, 0.99, 0.99, 2.0]), \
        np.array([0.0, 0.0, 1.01, 1.0])
    ts = np.linspace(0, 10, 41)
    yield "sine, local tolerance", ts, 3 + np.sin(ts), t_test, 3 + np.sin(t_test - 0.03) + rng.normal(0, .004, 301)


def vertical(bound: np.ndarray, t_test: np.ndarray) -> np.ndarray:
    """Test points at a time where the funnel's bound is vertical (an event's edge ± δt)."""
    x = bound[:, 0]
    return np.isin(t_test, x[1:][np.diff(x) == 0])


@pytest.mark.parametrize("tolerance", [{"atolx": 0.1, "atoly": 0.05}, {"atolx": 0.01, "atoly": 0.01},
                                       {"ltoly": 0.002, "atolx": 0.05}])
def test_the_tube_and_its_violations_are_the_funnels(tmp_path, tolerance):
    """At every test point the tube's bounds equal pyfunnel's bounds (linearly interpolated, as the
    funnel checks them) to 1e-12, and the same points are outside with the same error; except where
    the funnel's bound is vertical (exactly δt before or after an event): the funnel takes the first
    end of that segment (its case should_succeed1, "atolx is strict"), the tube here is closed, so a
    point on its edge is inside."""
    edges = 0
    for what, t, y, t_test, y_test in cases():
        lower_f, upper_f, errors = funnel(t, y, t_test, y_test, tmp_path, **tolerance)
        half_height = np.maximum(tolerance.get("atoly", 0.0), tolerance.get("ltoly", 0.0) * np.abs(y))
        half_height[half_height < 1e-10] = 1e-10                   # tubeSize.c: a zero tube size is 1e-10
        lower, upper = envelope(t, y, half_height, tolerance.get("atolx", 0.0), t_test)
        excess = np.maximum(0, np.maximum(y_test - upper, lower - y_test))
        edge = vertical(lower_f, t_test) | vertical(upper_f, t_test)
        edges += edge.sum()
        same = ~edge
        assert np.abs(lower - np.interp(t_test, *lower_f.T))[same].max() < 1e-12, what
        assert np.abs(upper - np.interp(t_test, *upper_f.T))[same].max() < 1e-12, what
        assert np.abs(excess - errors[:, 1])[same].max() < 1e-12, what
        assert (excess <= errors[:, 1])[edge].all(), what
        reference = np.rec.fromarrays([t, y], names="time,y")
        run = np.rec.fromarrays([t_test, y_test], names="time,y")
        verdict, = compare(reference, run, on="candidate", rtol=tolerance.get("ltoly", 0.0),
                           atol=max(tolerance.get("atoly", 0.0), 1e-10), time=tolerance.get("atolx", 0.0))
        assert verdict.out == (excess > 0).sum() and verdict.checked == len(t_test), what
    assert edges == (2 if tolerance == {"atolx": 0.01, "atoly": 0.01} else 0)   # should_succeed1's points


def test_csv_compare_mode_is_the_funnels_relative_tube_where_the_range_is_the_base(tmp_path):
    """csv-compare's tube (δ = tolerance·range in t and y, range >= |min| and >= 0.001 here) is the
    funnel's rtolx/rtoly tube, which the funnel keeps "for compatibility with csv-compare"."""
    for what, t, y, t_test, y_test in cases():
        if np.ptp(y) < abs(y.min()):
            continue                      # csv-compare's legacy base takes |min| there; the funnel does not
        _, _, errors = funnel(t, y, t_test, y_test, tmp_path, rtolx=0.002, rtoly=0.002)
        verdict, = compare(np.rec.fromarrays([t, y], names="time,y"), np.rec.fromarrays([t_test, y_test],
                           names="time,y"), mode="csv-compare")
        assert verdict.out == (errors[:, 1] > 0).sum() and verdict.checked == len(t_test), what
