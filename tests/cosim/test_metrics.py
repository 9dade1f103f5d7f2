"""cosim metrics, checked on responses with known closed forms (cosim compare: test_regression_engine.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.cli import main
from cosim.present.metrics import step_metrics


def first_order(T=5.0, t0=2.0, dt=1e-3, stop=80.0):
    t = np.arange(0, stop + dt / 2, dt)
    r = np.where(t >= t0, 1.0, 0.0)
    y = np.where(t >= t0, 1 - np.exp(-(t - t0) / T), 0.0)
    return t, y, r


def test_first_order_step_has_the_textbook_values():
    """e = exp(-s/T): IAE = T, ISE = T/2, ITAE = T^2; rise 10-90 % = T ln 9; 2 % settling = T ln 50."""
    t, y, r = first_order()
    m = step_metrics(t, y, r)
    assert m["IAE"] == pytest.approx(5.0, rel=1e-4)
    assert m["ISE"] == pytest.approx(2.5, rel=1e-4)
    assert m["ITAE"] == pytest.approx(25.0, rel=1e-4)
    assert m["overshoot"] == 0.0
    assert m["rise_time"] == pytest.approx(5 * math.log(9), abs=2e-3)
    assert m["settling_time"] == pytest.approx(5 * math.log(50), abs=2e-3)


def test_underdamped_overshoot_matches_the_second_order_formula():
    zeta, wn, dt = 0.3, 2.0, 1e-3
    t = np.arange(0, 30, dt)
    wd = wn * math.sqrt(1 - zeta ** 2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    r = np.ones_like(t)
    m = step_metrics(t, y, r, t0=0.0)
    assert m["overshoot"] == pytest.approx(100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2)), rel=1e-4)


def test_window_and_disturbance_only_runs():
    t, y, r = first_order()
    windowed = step_metrics(t, y, r, t1=12.0)
    assert windowed["IAE"] == pytest.approx(5 * (1 - math.exp(-2)), rel=1e-4)
    assert math.isnan(windowed["settling_time"])          # not settled by t1
    flat = step_metrics(t, y, np.ones_like(t), t0=10.0)   # setpoint unchanged: a disturbance run
    assert math.isnan(flat["overshoot"]) and math.isnan(flat["rise_time"])


def test_the_reasons_line_reads_back_as_the_mapping_it_was_written_from():
    """A sweep table's undefined(SIGNAL) column (`Response.reasons`) reads back as the mapping
    (`reasons_of`), also when a reason holds "; " or ": " or a line break, as the CLI's summary
    of undefined metrics needs (it split the line at every "; " before)."""
    from cosim.present.metrics import Response, reasons_of

    undefined = {"overshoot": "the response never passes the set-point; it stays below: 0.4",
                 "settling_time": "the response is still outside ±2 %\nof the step at 140 s",
                 "rise_time": "it never reaches 90 %"}
    line = Response(values={}, undefined=undefined).reasons()
    assert reasons_of(line) == undefined
    assert reasons_of("") == {} and reasons_of(None) == {}


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


@pytest.mark.pythonfmu
def test_metrics_cli_on_a_real_run(tmp_path, capsys):
    csv = tmp_path / "r.csv"
    assert main(["run", "ssp/pid_fopdt", "-q", "-o", str(csv), "--stop", "150"]) == 0
    capsys.readouterr()
    assert main(["metrics", str(csv), "--signal", "plant.y", "--setpoint", "setpoint.y", "--json"]) == 0
    import json
    m, = json.loads(capsys.readouterr().out)       # one event: the set-point step at 10 s
    assert 30 < m["overshoot"] < 37 and 0 < m["settling_time"] < 140
    assert main(["metrics", str(csv), "--signal", "plant.yy", "--setpoint", "setpoint.y"]) == 2
    assert "no signal matches 'plant.yy'" in capsys.readouterr().err
