"""The comparison engine (cosim.regression) and ``cosim compare``: tube in value and time, event
shifts, the reference's grid, verdicts with first and worst violation, the named modes."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from cosim.cli import main
from cosim.errors import SetupError
from cosim.regression.engine import compare
from cosim.regression.tolerances import Tolerance, tolerance_for
from cosim.regression.tube import envelope, sample_at
from cosim.record.results import write

H = 0.01   # the step of the runs below


def result(t, **signals) -> np.ndarray:
    out = np.zeros(len(t), dtype=[("time", float)] + [(n, float) for n in signals])
    out["time"] = t
    for name, values in signals.items():
        out[name] = values
    return out


def valve(shift_steps: int = 0, stop: float = 2.0) -> np.ndarray:
    """A valve opening at 1 s (+ shift_steps steps) and a first-order response to it, on the grid of H."""
    t = np.round(np.arange(0, stop + H / 2, H), 12)
    t_open = 1.0 + shift_steps * H
    opened = (t >= t_open - 1e-12).astype(float)
    flow = np.where(t >= t_open - 1e-12, 1 - np.exp(-(t - t_open) / 0.2), 0.0)
    return result(t, **{"valve.y": opened, "pipe.q": flow})


def test_an_event_shifted_by_one_step_passes_with_the_time_tolerance_and_fails_without():
    reference, shifted = valve(), valve(shift_steps=1)
    strict = compare(reference, shifted)
    assert [v.passed for v in strict] == [False, False]
    opened = strict[0]
    assert opened.first.time == pytest.approx(1.0) and opened.first.value == 0.0 and opened.first.reference == 1.0
    assert (opened.first.lower, opened.first.upper) == pytest.approx((1 - 1e-6, 1 + 1e-6))
    tolerant = compare(reference, shifted, time=H)
    assert [v.passed for v in tolerant] == [True, True]
    assert tolerant[0].max_abs == 1.0                           # the samples differ; the tube holds them
    # two steps late is outside a one-step tube
    assert [v.passed for v in compare(reference, valve(shift_steps=2), time=H)] == [False, False]


def test_a_value_error_inside_the_time_tolerance_window_fails():
    """Within ±time of the event the tube spans both levels, not more: an overshoot of the valve at
    the event, and a flow error next to it, fail although they are inside the window."""
    reference = valve()
    wrong = valve(shift_steps=1)
    at = np.flatnonzero(np.isclose(wrong["time"], 1.01))[0]
    wrong["valve.y"][at] = 1.05                                   # the event's sample, 5 % too high
    wrong["pipe.q"][at + 1] -= 0.05                               # next to the event
    opened, flow = compare(reference, wrong, time=H, rtol=1e-3, atol=1e-3)
    assert not opened.passed and opened.out == 1
    assert opened.first.time == pytest.approx(1.01) and opened.first.value == 1.05
    assert opened.first.upper == pytest.approx(1.001)            # the upper level + atol, not the spike
    assert not flow.passed and flow.out == 1 and flow.first == flow.worst and flow.first.time == pytest.approx(1.02)
    # the tube there reaches down to the reference one step earlier (the run is one step late), less atol
    assert flow.first.lower == pytest.approx(reference["pipe.q"][at] - 1e-3)
    fixed = valve(shift_steps=1)
    assert all(v.passed for v in compare(reference, fixed, time=H, rtol=1e-3, atol=1e-3))


def test_a_run_on_another_grid_is_checked_at_the_references_points():
    t_ref = np.round(np.arange(0, 2 + 0.05, 0.1), 12)                   # a coarse reference (another tool)
    t_run = np.round(np.arange(0, 2 + 0.005, 0.01), 12)                 # a fine run
    reference = result(t_ref, y=np.sin(t_ref))
    run = result(t_run, y=np.sin(t_run))
    verdict, = compare(reference, run, rtol=0, atol=1e-12)
    assert verdict.passed and verdict.checked == len(t_ref)
    assert np.array_equal(verdict.trace.time, t_ref)
    # an error between the reference's points is not seen on them; checking the run's own samples
    # (as csv-compare and the funnel do) sees it against the reference's linear interpolation
    run["y"][np.flatnonzero(np.isclose(t_run, 1.05))] += 0.5
    assert compare(reference, run, rtol=0, atol=1e-12)[0].passed
    own, = compare(reference, run, atol=0.01, on="candidate")
    assert not own.passed and own.checked == len(t_run) and own.first.time == pytest.approx(1.05)
    # a run that stops early fails every signal, saying so
    short, = compare(reference, run[t_run <= 1.5])
    assert not short.passed and "the run covers t = 0..1.5 s, the reference t = 0..2 s" in short.describe()


def test_the_worst_violation_is_the_largest_excess_and_nan_matches_nan_only():
    t = np.arange(0, 1.0001, 0.1)
    reference = result(t, y=np.ones_like(t), z=np.full_like(t, np.nan))
    run = reference.copy()
    run["y"][[3, 6]] = [1.5, 3.0]
    y, z = compare(reference, run, atol=0.1, rtol=0)
    assert (y.first.time, y.worst.time, y.out) == (pytest.approx(0.3), pytest.approx(0.6), 2)
    assert y.worst.excess == pytest.approx(1.9) and z.passed
    run["z"][2] = 0.0
    assert not compare(reference, run, signals=["z"])[0].passed


def test_tolerances_by_glob_absolute_floor_relative_band():
    default = Tolerance(1e-6, 1e-9)
    tolerances = {"*": (1e-1, 0.0), "plant.*": (1e-2, 0.0), "plant.y?": {"rtol": 1e-3}, "plant.y": (1e-4, 1e-5, 0.5)}
    assert tolerance_for("plant.y", tolerances, default) == Tolerance(1e-4, 1e-5, 0.5)   # exact name
    assert tolerance_for("plant.y2", tolerances, default) == Tolerance(1e-3, 1e-9)       # missing atol: default's
    assert tolerance_for("controller.u", tolerances, default) == Tolerance(1e-1, 0.0)
    for bad in [{"plant.y": (1e-3,)}, {"plant.y": {"rtol": 1e-3, "atl": 0}}, {"plant.y": (-1.0, 0.0)},
                {"plant.y": (1.0, 0.0, float("inf"))}]:
        with pytest.raises(SetupError, match="plant.y"):
            tolerance_for("plant.y", bad, default)
    # the band is the wider of the absolute floor and the relative band (the funnel's atoly and ltoly)
    assert list(Tolerance(0.1, 0.05).half_height(np.array([0.0, 0.4, 2.0]))) == pytest.approx([0.05, 0.05, 0.2])
    t = np.arange(0, 1.0001, 0.5)
    reference = result(t, y=np.array([0.0, 1.0, 10.0]))
    with pytest.raises(SetupError, match="'y.'.*matches no compared signal.*Did you mean 'y'"):
        compare(reference, reference, tolerances={"y.": (1.0, 1.0)})
    with pytest.raises(SetupError, match="the run has no signal 'x'"):
        compare(result(t, x=t), result(t, y=t))
    with pytest.raises(SetupError, match="tube mode"):
        compare(reference, reference, mode="fmi-cross-check", tolerances={"y": (1, 1)})


def test_the_tube_equals_the_sweep_of_the_rectangle_along_the_reference():
    """For constant δt, δy the upper bound is max{y_ref(s): |s − t| <= δt} + δy, the lower the min − δy."""
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0, 10, 40))
    y = np.cumsum(rng.normal(size=40))
    at = np.linspace(t[0], t[-1], 501)
    lower, upper = envelope(t, y, 0.05, 0.3, at)
    for k in range(501):
        ends = np.clip([at[k] - 0.3, at[k] + 0.3], t[0], t[-1])
        values = np.concatenate((np.interp(ends, t, y), y[(t >= ends[0]) & (t <= ends[1])]))   # the polyline's extremes
        assert upper[k] == pytest.approx(values.max() + 0.05, abs=1e-12)
        assert lower[k] == pytest.approx(values.min() - 0.05, abs=1e-12)


def test_sampling_at_an_event_takes_the_left_then_the_right_limit():
    t = np.array([0.0, 1.0, 1.0, 2.0])
    y = np.array([0.0, 0.0, 1.0, 1.0])
    assert list(sample_at(t, y, np.array([0.5, 1.0, 1.0, 1.5]))) == [0.0, 0.0, 1.0, 1.0]
    assert list(sample_at(t, y, np.array([1.0]))) == [0.0]
    assert np.isnan(sample_at(t, y, np.array([2.5]))).all()


def test_the_cross_check_mode_marks_the_samples_fmpys_cross_check_validation_marks():
    """FMI Cross-Check rules 4.0 §9.2.5 as FMPy's validation script computes them
    (fmpy.cross_check.validate_signal): the same samples out, and the 10 % rule."""
    from fmpy.cross_check import validate_signal

    rng = np.random.default_rng(3)
    t_ref = np.linspace(0, 10, 301)
    reference = result(t_ref, y=np.sin(t_ref) + (t_ref > 4), z=np.zeros_like(t_ref))
    for noise in (0.0, 0.05, 0.15, 0.4):
        t = np.linspace(-0.5, 10.5, 173)
        run = result(t, y=np.sin(t + 0.02) + (t > 4.2) + rng.normal(scale=noise, size=len(t)),
                     z=rng.normal(scale=noise, size=len(t)))
        for name in ("y", "z"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)    # its scipy.ndimage.filters import
                _, _, _, out = validate_signal(run["time"], run[name], t_ref, reference[name].copy(), 0.0, 10.0)
            verdict, = compare(reference, run, signals=[name], mode="fmi-cross-check")
            inside = (run["time"] >= 0) & (run["time"] <= 10)
            assert np.array_equal(verdict.trace.out, out[inside]) and verdict.out == out.sum()
            assert verdict.passed == (out.sum() / len(out) <= 0.1)
    assert not compare(reference, run, mode="fmi-cross-check")[0].passed     # the noisiest run fails


def test_compare_cli_exit_codes_modes_and_report(tmp_path, capsys):
    reference, shifted = valve(), valve(shift_steps=1)
    a, b = write(reference, tmp_path / "ref.csv"), write(shifted, tmp_path / "run.csv")
    assert main(["compare", str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "DIFF valve.y: FAILED (rtol 1e-06, atol 1e-09; on the reference's points); 1 of 201 points outside; " \
           "first at t = 1 s: run 0, reference 1, tube [0.999999, 1.000001]" in out
    assert "0 of 2 signals within tolerance (tube)" in out
    assert main(["compare", str(a), str(b), "--time-tolerance", str(H)]) == 0
    assert main(["compare", str(a), str(b), "--tolerance", "valve.*=0,0,0.01", "--signals", "valve.y"]) == 0
    assert main(["compare", str(a), str(b), "--mode", "fmi-cross-check"]) == 0
    assert main(["compare", str(a), str(b), "--tolerance", "valve.y=1e-3"]) == 2
    assert "not GLOB=RTOL,ATOL[,TIME]" in capsys.readouterr().err
    page = tmp_path / "diff.html"
    assert main(["compare", str(a), str(b), "--report", str(page)]) == 1
    assert f"difference report: {page} (plot {page.with_suffix('.png')})" in capsys.readouterr().out
    text = page.read_text()
    assert "valve.y" in text and "FAILED" in text and page.with_suffix(".png").stat().st_size > 10_000
    assert main(["compare", str(a), str(b), "--report", str(a)]) == 2         # never over an input
    assert main(["compare", str(a), str(b), "--report", str(tmp_path / "x.txt")]) == 2
