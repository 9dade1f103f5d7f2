"""Event-based metrics (cosim.present.metrics.find_events / event_metrics, ``cosim metrics
--disturbance``) and the reasons given for undefined metrics, on responses with closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from cosim.present.metrics import event_metrics, find_events, step_metrics, step_response
import json
from cosim.cli import main

T, TAU, A = 5.0, 3.0, 0.5          # set-point response time constant; load response shape


def loop(dt=1e-3, stop=80.0):
    """r: 0 → 1 at 2 s; d: 0 → 1 at 40 s.  y = 1 − exp(−(t−2)/T) after the set-point step, minus
    A·(x/τ)·exp(−x/τ), x = t − 40, after the load step (a typical load response of a PI loop)."""
    t = np.arange(0, stop + dt / 2, dt)
    r = np.where(t >= 2, 1.0, 0.0)
    d = np.where(t >= 40, 1.0, 0.0)
    x = np.clip(t - 40, 0, None)
    y = np.where(t >= 2, 1 - np.exp(-(t - 2) / T), 0.0) - A * (x / TAU) * np.exp(-x / TAU)
    return t, y, r, d


def test_events_are_the_set_point_and_disturbance_steps_with_windows_up_to_the_next():
    t, y, r, d = loop()
    events = find_events(t, ("sp.y", r), {"load.y": d})
    assert [(e.kind, e.signal, e.t0, e.t1, e.before, e.after) for e in events] == [
        ("set-point", "sp.y", pytest.approx(2.0), pytest.approx(40.0), 0.0, 1.0),
        ("disturbance", "load.y", pytest.approx(40.0), pytest.approx(80.0), 0.0, 1.0)]


def test_each_event_is_measured_in_its_own_window():
    t, y, r, d = loop()
    sp, load = event_metrics(t, y, r, find_events(t, ("sp.y", r), {"load.y": d}))
    # set-point step: the first-order textbook values (the load does not leak into them)
    assert sp.values["IAE"] == pytest.approx(T, rel=1e-3)
    assert sp.values["settling_time"] == pytest.approx(T * math.log(50), abs=2e-3)
    assert sp.values["rise_time"] == pytest.approx(T * math.log(9), abs=2e-3)
    assert sp.values["overshoot"] == 0.0 and not sp.undefined
    # over the whole run, as one window, the load step spoils the settling time
    assert step_metrics(t, y, r)["settling_time"] > 40
    # load step, e(x) = A (x/τ) e^(−x/τ) + e^(−(x+38)/T), x = t − 40 (the set-point response's tail):
    # IAE = A τ + T e^(−38/T) (to 1e-7 over the 40 s window), the peak and the recovery into ±2 %
    e = lambda x: A * x / TAU * math.exp(-x / TAU) + math.exp(-(x + 38) / T)  # noqa: E731
    assert load.values["IAE"] == pytest.approx(A * TAU + T * math.exp(-38 / T), rel=1e-4)
    peak = minimize_scalar(lambda x: -e(x), bounds=(0, 10), method="bounded", options={"xatol": 1e-9})
    assert load.values["peak_error"] == pytest.approx(e(peak.x), rel=1e-6)
    assert load.values["settling_time"] == pytest.approx(brentq(lambda x: e(x) - 0.02, TAU, 60), abs=2e-3)
    assert math.isnan(load.values["overshoot"]) and math.isnan(load.values["rise_time"])
    assert "disturbance event (load.y at 40 s) has no set-point step" in load.undefined["rise_time"]


def test_a_ramp_is_one_event_and_a_constant_set_point_one_event_from_the_start():
    t = np.linspace(0, 10, 101)
    ramp = np.clip(t - 2, 0, 3)
    events = find_events(t, ("sp.y", ramp))
    assert len(events) == 1 and events[0].t0 == pytest.approx(2.1) and events[0].after == 3.0
    flat = find_events(t, ("sp.y", np.ones_like(t)))
    assert [(e.t0, e.t1) for e in flat] == [(0.0, 10.0)]


def test_undefined_metrics_say_why():
    t, y, r, _ = loop(stop=40.0)
    never = step_response(t, 0.5 * y, r)
    assert math.isnan(never.values["rise_time"]) and math.isnan(never.values["settling_time"])
    assert "never reached 90 % of the step (at most 50 %)" in never.undefined["rise_time"]
    assert "still outside ±2 % of the step" in never.undefined["settling_time"]
    short = step_response(t, y, r, t1=14.0)            # 12 s after the step: risen, not settled
    assert not math.isnan(short.values["rise_time"]) and "settling_time" in short.undefined
    flat = step_response(t, y, r, t0=30.0)             # no set-point change at 30 s
    assert set(flat.undefined) == {"overshoot", "rise_time", "settling_time"}
    assert "does not change at 30 s" in flat.undefined["overshoot"]


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


@pytest.mark.pythonfmu
def test_cosim_metrics_prints_one_row_per_event_of_a_real_run(tmp_path, capsys):
    csv = tmp_path / "r.csv"
    assert main(["run", "ssp/pid_fopdt", "-q", "-o", str(csv), "--stop", "250"]) == 0
    capsys.readouterr()
    args = ["metrics", str(csv), "--signal", "plant.y", "--setpoint", "setpoint.y", "--disturbance", "load.y"]
    assert main(args + ["--json"]) == 0
    sp, load = json.loads(capsys.readouterr().out)
    assert (sp["event"], sp["t0"], sp["t1"]) == ("set-point", 10.0, 150.0)
    assert (load["event"], load["signal"], load["t0"]) == ("disturbance", "load.y", 150.0)
    assert main(["metrics", str(csv), "--signal", "plant.y", "--setpoint", "setpoint.y", "--t1", "150",
                 "--json"]) == 0
    window, = json.loads(capsys.readouterr().out)
    assert sp["settling_time"] == pytest.approx(window["settling_time"])   # --t1 still overrides
    assert 30 < sp["overshoot"] < 37 and load["overshoot"] is None and 0 < load["settling_time"] < 100
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "2 disturbance load.y 0 → -1" in out and "event 2: overshoot, rise_time undefined" in out


@pytest.mark.pythonfmu
def test_a_sweep_row_says_why_a_metric_is_undefined(built_fmus, tmp_path, capsys):
    # the FMUs by --fmu-dir: the worker process then needs no FMU provider (in the whole suite, a
    # spawned worker inherits a sys.path on which earlier in-process runs may have left an FMU's
    # embedded greyfmu, whose provider has no fmus/ to build from)
    fmus = built_fmus["PID"].parent
    # 40 s: the loop (rise 8.8 s, settling 72 s after the step at 10 s) has risen but not settled
    assert main(["sweep", "ssp/pid_fopdt", "--set", "controller.Kc=8", "--stop", "40", "--metrics",
                 "plant.y:setpoint.y", "--workers", "1", "--fmu-dir", str(fmus), "--output", str(tmp_path),
                 "--quiet"]) == 0
    assert "plant.y:settling_time undefined in 1 of 1 runs" in capsys.readouterr().err
    import pyarrow.parquet as pq
    row, = pq.read_table(tmp_path / "sweep.parquet").to_pylist()
    assert math.isnan(row["plant.y:settling_time"]) and not math.isnan(row["plant.y:rise_time"])
    assert row["undefined(plant.y)"].startswith("settling_time: the response is still outside ±2 % of the step")
