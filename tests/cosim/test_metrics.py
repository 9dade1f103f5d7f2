"""cosim metrics and cosim compare, checked on responses with known closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.cli import main
from cosim.errors import SetupError
from cosim.present.metrics import Tolerance, compare, step_metrics, tolerance_for


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


def _csv(path, t, **signals):
    names = ["time", *signals]
    rows = np.column_stack([t, *signals.values()])
    with open(path, "w") as f:
        f.write(",".join(f'"{n}"' for n in names) + "\n")
        np.savetxt(f, rows, fmt="%.17g", delimiter=",")
    return str(path)


def test_compare_cli_exit_codes(tmp_path, capsys):
    t, y, r = first_order(stop=10.0)
    a = _csv(tmp_path / "a.csv", t, **{"plant.y": y, "setpoint.y": r})
    b = _csv(tmp_path / "b.csv", t, **{"plant.y": y * (1 + 1e-9), "setpoint.y": r})
    c = _csv(tmp_path / "c.csv", t, **{"plant.y": y + 1e-3, "setpoint.y": r})
    assert main(["compare", a, b]) == 0
    assert main(["compare", a, c]) == 1
    out = capsys.readouterr().out
    assert "DIFF plant.y: max |diff| 0.001" in out and "1 of 2 signals agree" in out
    assert main(["compare", a, c, "--atol", "2e-3"]) == 0
    assert main(["compare", a, c, "--signals", "setpoint.*"]) == 0
    d = _csv(tmp_path / "d.csv", t[:-1], **{"plant.y": y[:-1], "setpoint.y": r[:-1]})
    assert main(["compare", a, d]) == 2
    assert "time grids differ" in capsys.readouterr().err


def test_compare_function_names_missing_signals():
    t, y, r = first_order(stop=1.0)
    a = np.empty(len(t), dtype=[("time", float), ("plant.y", float)])
    a["time"], a["plant.y"] = t, y
    with pytest.raises(Exception) as err:
        compare(a, a, signals=["plant.z"])
    assert "plant.y" in str(err.value)


def test_the_most_specific_tolerance_key_wins():
    default = Tolerance(1e-6, 1e-9)
    tolerances = {"*": (1e-1, 0.0), "plant.*": (1e-2, 0.0), "plant.y?": {"rtol": 1e-3}, "plant.y": (1e-4, 1e-5)}
    assert tolerance_for("plant.y", tolerances, default) == Tolerance(1e-4, 1e-5)       # exact name
    assert tolerance_for("plant.y2", tolerances, default) == Tolerance(1e-3, 1e-9)      # missing atol: default's
    assert tolerance_for("plant.u", tolerances, default) == Tolerance(1e-2, 0.0)
    assert tolerance_for("controller.u", tolerances, default) == Tolerance(1e-1, 0.0)
    assert tolerance_for("controller.u", {}, default) == default
    for bad in [{"plant.y": (1e-3,)}, {"plant.y": {"rtol": 1e-3, "atl": 0}}, {"plant.y": (-1.0, 0.0)}]:
        with pytest.raises(SetupError, match="plant.y"):
            tolerance_for("plant.y", bad, default)


def test_compare_reports_the_first_sample_out_of_band_per_signal():
    t, y, r = first_order(stop=10.0)
    a = np.empty(len(t), dtype=[("time", float), ("plant.y", float), ("setpoint.y", float)])
    a["time"], a["plant.y"], a["setpoint.y"] = t, y, r
    b = a.copy()
    b["plant.y"][(t >= 5.0) & (t < 5.0105)] += 1e-4     # 11 samples out from t = 5 s
    loose, tight = compare(a, b, tolerances={"plant.*": (0.0, 2e-4)}), compare(a, b)
    assert all(d.ok for d in loose)
    y_diff = tight[0]
    assert not y_diff.ok and tight[1].ok and y_diff.samples_out == 11
    assert y_diff.first_time == pytest.approx(5.0) and y_diff.first_reference == a["plant.y"][5000]
    assert y_diff.first_value == b["plant.y"][5000] and y_diff.first_bound == pytest.approx(1e-9 + 1e-6 * y[5000])
    assert "plant.y: first at t = 5 s" in y_diff.describe() and "(rtol 1e-06, atol 1e-09)" in y_diff.describe()
    with pytest.raises(SetupError, match="'plant.yy'.*matches no compared signal.*Did you mean 'plant.y'"):
        compare(a, b, tolerances={"plant.yy": (1.0, 1.0)})
    with pytest.raises(SetupError, match=r"the time grids differ \(10001 samples from 0 to 10 s, step 0.001 s vs "
                                         r"10001 samples .*; sample 1 is at 0.001 s vs 0.002 s\)"):
        shifted = a.copy()
        shifted["time"][1:] += 1e-3
        compare(a, shifted)


def test_compare_cli_per_signal_tolerances(tmp_path, capsys):
    t, y, r = first_order(stop=10.0)
    a = _csv(tmp_path / "a.csv", t, **{"plant.y": y, "setpoint.y": r})
    c = _csv(tmp_path / "c.csv", t, **{"plant.y": y + 1e-3, "setpoint.y": r})
    assert main(["compare", a, c, "--tolerance", "plant.*=0,2e-3"]) == 0
    assert main(["compare", a, c, "--tolerance", "plant.*=0,2e-3", "--tolerance", "plant.y=0,1e-4"]) == 1
    assert "plant.y: first at t = 0 s: value 0.001, reference 0, |diff| 0.001 > 0.0001" in capsys.readouterr().out
    assert main(["compare", a, c, "--tolerance", "plant.y=1e-3"]) == 2
    assert "not GLOB=RTOL,ATOL" in capsys.readouterr().err


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
