"""The parts of cosim.tune on their own and on a loop of C FMUs (tests/twin_fmus.py: Step,
Sum, Gain, FirstOrderFilter; no pythonfmu): terms, constraints and parameters as given on the
command line, the measurement of a result, a tuning's table, its best point re-run from
best.ssv, and an interrupted tuning resumed from its table to the uninterrupted one's end."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import SetupError
from cosim.present.metrics import event_metrics, find_events
from cosim.record.results import read
from cosim.tune import DifferentialEvolution, NelderMead, read_evaluations, tune
from cosim.tune.measures import MetricTerm, Measurement, parse_constraint, parse_term
from cosim.tune.space import parse_parameter
from ssdgen import ssd_text, write_system

COSIM = str(Path(sys.executable).with_name("cosim"))


def test_terms_constraints_and_parameters_read_as_written():
    assert parse_term("ITAE:plant.y") == (1.0, MetricTerm("ITAE", "plant.y"))
    assert parse_term("0.5*overshoot:plant.y:setpoint.y@1") == (0.5, MetricTerm("overshoot", "plant.y", "setpoint.y", "1"))
    assert parse_term("itae:plant.y@disturbance")[1] == MetricTerm("ITAE", "plant.y", None, "disturbance")
    c = parse_constraint("overshoot:plant.y<=10%")
    assert (c.term, c.upper, c.lower) == (MetricTerm("overshoot", "plant.y"), 10.0, -math.inf)
    assert parse_constraint("rise_time:plant.y >= 2s").lower == 2.0
    assert c.violation(12.5) == 2.5 and c.violation(3) == 0 and c.violation(math.nan) == math.inf
    p = parse_parameter("controller.Kc=0.1:10:log")
    assert (p.low, p.high, p.scale, p.bounds()) == (0.1, 10.0, "log", (-1.0, 1.0))
    assert p.value(0.0) == 1.0 and p.value(5.0) == 10.0          # clipped into the bounds
    for bad, match in (("ITAE", "is not"), ("IAX:plant.y", "unknown metric 'IAX'"), ("ITAE:plant.y@0", "selects no"),
                       ("-1*ITAE:plant.y", "not a positive number")):
        with pytest.raises(SetupError, match=match):
            parse_term(bad)
    for bad, match in (("overshoot:plant.y<=10s", "not measured in s"), ("ITAE:plant.y", "is not METRIC"),
                       ("2*ITAE:plant.y<=3", "has no weight")):
        with pytest.raises(SetupError, match=match):
            parse_constraint(bad)
    for bad, match in (("c.k=1", "is not NAME=LOW:HIGH"), ("c.k=0:1:log", "LOW > 0"), ("c.k=2:1", "LOW < HIGH"),
                       ("c.k=1:2:cubic", "unknown scale")):
        with pytest.raises(SetupError, match=match):
            parse_parameter(bad)


def _response() -> np.ndarray:
    """A set-point step at 1 s and a disturbance at 6 s, y a first-order lag of the error's cause."""
    t = np.round(np.arange(0, 12.0001, 0.01), 10)
    r = np.where(t >= 1, 1.0, 0.0)
    d = np.where(t >= 6, 0.5, 0.0)
    y = np.where(t >= 1, 1 - np.exp(-(t - 1) / 0.5), 0.0) * 1.1 - np.where(t >= 6, 0.5 * np.exp(-(t - 6)), 0.0)
    out = np.zeros(len(t), dtype=[("time", float), ("r", float), ("y", float), ("d", float)])
    out["time"], out["r"], out["y"], out["d"] = t, r, y, d
    return out


def test_a_term_over_events_sums_the_integrals_and_takes_the_worst_of_the_rest():
    result = _response()
    events = find_events(result["time"], ("r", result["r"]), {"d": result["d"]})
    rows = event_metrics(result["time"], result["y"], result["r"], events)
    terms = (MetricTerm("ITAE", "y", "r"), MetricTerm("ITAE", "y", "r", "2"), MetricTerm("overshoot", "y", "r"),
             MetricTerm("settling_time", "y", "r", "disturbance"), MetricTerm("peak_error", "y", "r"))
    measured = Measurement(terms, ("d",), stop=12.0)(result)
    assert measured["ITAE:y"] == pytest.approx(rows[0].values["ITAE"] + rows[1].values["ITAE"], rel=1e-12)
    assert measured["ITAE:y@2"] == rows[1].values["ITAE"]
    assert measured["overshoot:y"] == rows[0].values["overshoot"]      # the disturbance event has none
    # 10 % off for good: never settles into ±2 % of the step, and says why
    assert measured["settling_time:y@disturbance"] is None and "undefined in event 2" in measured["measure_error"]
    assert measured["peak_error:y"] == max(abs(r.values["peak_error"]) for r in rows)
    short = Measurement(terms, ("d",), stop=20.0)(result)
    assert all(short[t.name] is None for t in terms) and "before the stop time 20 s" in short["measure_error"]
    assert Measurement(terms, ("d",))(None)["measure_error"] == "the run failed"


def effort(result: np.ndarray) -> float:
    """∫u² dt of the loop's controller output (a callable objective term, module level: it pickles)."""
    u, t = result["gain.y"], result["time"]
    return float(np.sum((u[1:] ** 2 + u[:-1] ** 2) * np.diff(t)) / 2)


#: the evaluation at which `interrupting` raises KeyboardInterrupt (None: never)
STOP_AT: list[int | None] = [None]
CALLS = [0]


def interrupting(result: np.ndarray) -> float:
    """`effort`, but a KeyboardInterrupt at call number STOP_AT[0] (a Ctrl-C in the middle of a batch)."""
    CALLS[0] += 1
    if STOP_AT[0] is not None and CALLS[0] == STOP_AT[0]:
        raise KeyboardInterrupt
    return effort(result)


@pytest.fixture(scope="module")
def loop(twin_fmus, tmp_path_factory) -> Path:
    """setpoint (0 -> 1 at 1 s) -> error = r - y -> gain k -> first-order plant (T = 1 s, K = 1)."""
    components = {"setpoint": ("Step.fmu", {"y": "output"}), "error": ("Sum.fmu", {"u1": "input", "u2": "input",
                                                                                  "y": "output"}),
                  "gain": ("Gain.fmu", {"u": "input", "y": "output"}),
                  "plant": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    wiring = [("setpoint", "y", "error", "u1"), ("plant", "y", "error", "u2"), ("error", "y", "gain", "u"),
              ("gain", "y", "plant", "u")]
    text = ssd_text("loop", components, wiring, stop=8.0, step=0.05,
                    parameters={"setpoint": {"t_step": 1.0}, "error": {"k2": -1.0}, "gain": {"k": 2.0}})
    folder = tmp_path_factory.mktemp("loop")
    return write_system(folder / "loop", {f"{n}.fmu": twin_fmus[n] for n in ("Step", "Sum", "Gain", "FirstOrderFilter")},
                        text)


OBJECTIVE = ["ITAE:plant.y:setpoint.y", (0.05, effort)]


def test_a_tuning_finds_the_interior_optimum_and_its_best_ssv_runs_to_the_same_objective(loop, tmp_path):
    result = tune(loop, {"gain.k": (0.1, 50, "log")}, objective=OBJECTIVE, method=DifferentialEvolution(popsize=6),
                  max_evaluations=36, executor="serial", output=tmp_path / "t")
    rows = read_evaluations(tmp_path / "t")
    # 4 generations of 6 points, then Nelder-Mead; a point proposed again is answered by its first evaluation
    assert len(rows) == len(result.evaluations) <= 36 and "polished by Nelder-Mead" in result.message
    assert [r["evaluation"] for r in rows] == list(range(len(rows)))
    assert rows[0]["gain.k"] == 2.0                       # the scenario's own value, exactly, first
    best = min(rows, key=lambda r: r["objective"])
    assert result.best.values == {"gain.k": best["gain.k"]} and result.best.objective == best["objective"]
    assert rows[-1]["best"] == best["objective"] and all(a["best"] >= b["best"] for a, b in zip(rows, rows[1:]))
    assert 0.5 < best["gain.k"] < 40                     # interior: the effort term balances the ITAE
    # best.ssv through cosim run: the same objective from the command line's result
    out = tmp_path / "again.csv"
    done = subprocess.run([COSIM, "run", str(loop), "--param-set", str(result.ssv), "-o", str(out), "--quiet"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    again = read(out)
    itae = Measurement((MetricTerm("ITAE", "plant.y", "setpoint.y"),), ("",)[:0], stop=8.0)(again)["ITAE:plant.y"]
    assert itae + 0.05 * effort(again) == pytest.approx(result.best.objective, rel=1e-12)
    assert (tmp_path / "t" / "tune.html").read_text().count("data:image/png;base64,") >= 2   # convergence + run


def test_nelder_mead_refines_from_the_scenarios_value(loop, tmp_path):
    result = tune(loop, ["gain.k=0.1:50:log"], objective=OBJECTIVE, method=NelderMead(), max_evaluations=25,
                  executor="serial", output=tmp_path, report=False)
    assert result.evaluations[0].values == {"gain.k": 2.0} and result.best.value < result.evaluations[0].value
    assert len(result.evaluations) <= 25 and result.ssv.is_file() and result.report is None


def test_an_interrupted_tuning_resumes_from_its_table_to_the_uninterrupted_end(loop, tmp_path):
    options = dict(objective=["ITAE:plant.y:setpoint.y", (0.05, interrupting)], method=DifferentialEvolution(popsize=5),
                   max_evaluations=30, executor="serial", report=False)
    STOP_AT[0] = None
    whole = tune(loop, {"gain.k": (0.1, 50, "log")}, output=tmp_path / "whole", **options)
    CALLS[0], STOP_AT[0] = 0, 13
    with pytest.raises(KeyboardInterrupt):
        tune(loop, {"gain.k": (0.1, 50, "log")}, output=tmp_path / "cut", **options)
    kept = read_evaluations(tmp_path / "cut")
    assert len(kept) == 12                                   # every evaluation finished before the Ctrl-C
    STOP_AT[0] = None
    resumed = tune(loop, {"gain.k": (0.1, 50, "log")}, output=tmp_path / "cut", **options)
    assert resumed.ran == len(resumed.evaluations) - 12 and len(resumed.evaluations) == len(whole.evaluations)
    columns = ("evaluation", "key", "gain.k", "objective", "best")
    assert [[r[c] for c in columns] for r in read_evaluations(tmp_path / "cut")] == \
        [[r[c] for c in columns] for r in read_evaluations(tmp_path / "whole")]
    assert resumed.best.values == whole.best.values
    # another objective is other rows: refused, not mixed in
    with pytest.raises(SetupError, match="cannot be reused; give --force"):
        tune(loop, {"gain.k": (0.1, 50, "log")}, **{**options, "objective": "ITAE:plant.y:setpoint.y"},
             output=tmp_path / "cut")


def test_the_process_pool_gives_the_serial_tuning(loop, tmp_path):
    options = dict(objective=OBJECTIVE, method=DifferentialEvolution(popsize=5), max_evaluations=15, report=False)
    serial = tune(loop, {"gain.k": (0.1, 50, "log")}, executor="serial", output=tmp_path / "s", **options)
    pooled = tune(loop, {"gain.k": (0.1, 50, "log")}, executor="process", workers=2, output=tmp_path / "p", **options)
    assert [(e.values, e.objective) for e in pooled.evaluations] == [(e.values, e.objective) for e in serial.evaluations]


def test_bad_names_and_signals_are_refused_before_any_run(loop, tmp_path):
    cases = [({"gain.q": (1, 2)}, "ITAE:plant.y:setpoint.y", "has no variable 'q'"),
             ({"gain.k": (1, 2)}, "ITAE:plant.y", "controlled variable of no control loop"),
             ({"gain.k": (1, 2)}, "ITAE:plant.x:setpoint.y", "no recorded signal 'plant.x'"),
             ({"plant.y": (1, 2)}, "ITAE:plant.y:setpoint.y", "causality 'output'")]
    for parameters, objective, match in cases:
        with pytest.raises(SetupError, match=match):
            tune(loop, parameters, objective=objective, executor="serial", output=tmp_path)
    assert not (tmp_path / "tune.csv").exists()


def test_a_dask_cluster_gives_the_serial_tuning(loop, tmp_path):
    pytest.importorskip("distributed")
    options = dict(objective="ITAE:plant.y:setpoint.y", constraints=["overshoot:plant.y:setpoint.y<=1%"],
                   method=DifferentialEvolution(popsize=5), max_evaluations=10, report=False)
    serial = tune(loop, {"gain.k": (0.1, 50, "log")}, executor="serial", output=tmp_path / "s", **options)
    on_dask = tune(loop, {"gain.k": (0.1, 50, "log")}, executor="local:2", output=tmp_path / "d", **options)
    assert [(e.values, e.objective, e.constraints) for e in on_dask.evaluations] == \
        [(e.values, e.objective, e.constraints) for e in serial.evaluations]


def test_ctrl_c_stops_cosim_tune_with_its_evaluations_kept_and_the_same_command_goes_on(loop, tmp_path):
    import os
    import signal
    import time

    out = tmp_path / "out"
    command = [COSIM, "tune", str(loop), "--param", "gain.k=0.1:50:log", "--objective", "ITAE:plant.y:setpoint.y",
               "--popsize", "5", "--polish", "0", "--workers", "2", "-o", str(out)]
    # as a terminal's foreground job: SIGINT at its default disposition (see tests/scenarios/sweep/test_interrupts.py)
    default_sigint = [sys.executable, "-c", "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
                      "os.execv(sys.argv[1], sys.argv[1:])"]
    process = subprocess.Popen(default_sigint + command + ["--max-evaluations", "100000"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, start_new_session=True)
    end = time.monotonic() + 300
    while not ((out / "tune.csv").is_file() and len(read_evaluations(out)) >= 5):
        assert process.poll() is None and time.monotonic() < end, process.communicate()
        time.sleep(0.1)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    kept = read_evaluations(out)
    assert process.returncode == 130 and "Traceback" not in err, err
    assert f"tuning interrupted; {len(kept)} evaluations are in {out / 'tune.csv'}" in err
    assert [r["evaluation"] for r in kept] == list(range(len(kept)))
    # the same tuning again (its first generation): every point answered from the table
    again = subprocess.run(command + ["--max-evaluations", "5"], capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert "cosim: tune: 5 evaluations (0 run now)" in again.stdout
