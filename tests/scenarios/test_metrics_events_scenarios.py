"""The tests of tests/cosim/test_metrics_events.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import json
import math

import pytest

from cosim.cli import main


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
